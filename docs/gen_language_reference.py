"""Generate ``docs/language.md``, the procedure-language reference, from ``suture schema``.

The structure (documents, fields, types, defaults, bounds, which skill takes which
parameters) comes from the JSON Schema the engine prints; the one-line meaning of
each skill parameter comes from the attribute docstring under the field in the
skill's parameter model (the schema does not carry them).

Usage:
    python docs/gen_language_reference.py            # writes docs/language.md
    python docs/gen_language_reference.py --check    # exit 1 if docs/language.md is stale
"""

from __future__ import annotations

import argparse
import ast
import inspect
import io
import itertools
import json
import sys
import textwrap
from pathlib import Path
from typing import Any

OUT = Path(__file__).resolve().parent / "language.md"
EXPR = "\\$\\{.*\\}"


def schema() -> dict[str, Any]:
    """The schema exactly as ``suture schema`` prints it."""
    from suture_engine.validation.report import schema_command

    buf = io.StringIO()
    schema_command(out=buf)
    result: dict[str, Any] = json.loads(buf.getvalue())
    return result


def _strip_expr(node: dict[str, Any]) -> tuple[dict[str, Any], bool]:
    """``(the real field schema, whether a ${...} expression is accepted)``."""
    options = node.get("anyOf")
    if isinstance(options, list) and len(options) == 2 and options[1].get("pattern") == EXPR:
        return options[0], True
    return node, False


def _is_quantity(node: dict[str, Any]) -> bool:
    options = node.get("anyOf") or []
    return (
        len(options) == 2
        and options[0].get("type") == "number"
        and options[1].get("type") == "string"
        and "pattern" in options[1]
    )


def type_text(node: dict[str, Any]) -> str:
    """A short human spelling of a field's type."""
    if "$ref" in node:
        name = node["$ref"].rsplit("/", 1)[-1]
        return f"[{name}](#{name.lower()})"
    if _is_quantity(node):
        return "quantity (number in SI, or text such as `20 mm`)"
    if "enum" in node:
        return " \\| ".join(f"`{v}`" for v in node["enum"])
    if "anyOf" in node:
        parts = [type_text(o) for o in node["anyOf"]]
        return " or ".join(p for p in parts if p != "null") + (
            " (optional)" if "null" in parts else ""
        )
    kind = node.get("type")
    if kind == "array":
        items = node.get("items")
        return f"list of {type_text(items)}" if isinstance(items, dict) else "list"
    if kind == "object":
        extra = node.get("additionalProperties")
        if isinstance(extra, dict):
            return f"map of name to {type_text(_strip_expr(extra)[0])}"
        return "mapping"
    return str(kind) if kind else "any"


def _bounds(node: dict[str, Any]) -> str:
    out = []
    for key, sym in (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<")):
        for n in [node, *(node.get("anyOf") or [])]:
            if isinstance(n, dict) and key in n:
                out.append(f"{sym} {n[key]}")
    for key, sym in (("minimum", ">="), ("exclusiveMinimum", ">"), ("maximum", "<=")):
        if key in node:
            out.append(f"{sym} {node[key]}")
    return ", ".join(dict.fromkeys(out))


def field_docs(model: type) -> dict[str, str]:
    """Attribute docstrings (the string literal under each field) of a class and its bases."""
    docs: dict[str, str] = {}
    for cls in reversed(model.__mro__):
        try:
            source = textwrap.dedent(inspect.getsource(cls))
        except (OSError, TypeError):
            continue
        body = ast.parse(source).body
        if not body or not isinstance(body[0], ast.ClassDef):
            continue
        stmts = body[0].body
        for prev, nxt in itertools.pairwise(stmts):
            if (
                isinstance(prev, ast.AnnAssign)
                and isinstance(prev.target, ast.Name)
                and isinstance(nxt, ast.Expr)
                and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)
            ):
                docs[prev.target.id] = " ".join(nxt.value.value.split())
    return docs


def skill_events(skill: str) -> tuple[str, ...]:
    """The skill's named failure events (``Skill.events``); none if it does not import."""
    from skills.registry import get_skill

    try:
        return tuple(get_skill(skill).events)
    except Exception:  # a skill that does not import: structure only
        return ()


def skill_models(s: dict[str, Any]) -> dict[str, tuple[str, dict[str, str]]]:
    """``{def name: (skill name, field docs)}`` from the schema's skill dispatch."""
    from skills.registry import get_skill

    out: dict[str, tuple[str, dict[str, str]]] = {}
    for rule in s["$defs"].get("StateDocument", {}).get("allOf", []):
        skill = rule["if"]["properties"]["skill"]["const"]
        ref = rule["then"]["properties"]["with"]["$ref"].rsplit("/", 1)[-1]
        try:
            docs = field_docs(get_skill(skill).Params)
        except Exception:  # a skill that does not import: structure only
            docs = {}
        out[ref] = (skill, docs)
    return out


def document_docs(names: list[str]) -> dict[str, dict[str, str]]:
    """Field docs of the language's own documents (``suture_engine.language.model``)."""
    from suture_engine.language import model

    out = {}
    for name in names:
        cls = getattr(model, name, None)
        if isinstance(cls, type):
            out[name] = field_docs(cls)
    return out


def _md(text: str) -> str:
    return " ".join(text.replace("``", "`").split()).replace("|", "\\|")


def render(s: dict[str, Any]) -> str:
    """The Markdown reference."""
    defs: dict[str, Any] = s["$defs"]
    skills = skill_models(s)
    root = s["$ref"].rsplit("/", 1)[-1]
    lines = [
        "# Procedure language reference",
        "",
        "<!-- Generated by docs/gen_language_reference.py from `suture schema`; do not edit. -->",
        "",
        "A procedure is a YAML file; this page lists every document and field the",
        "engine accepts. Quantities take a number in SI units or a text with a unit",
        "(`20 mm`, `200 ms`, `2 N`, `5 deg`). Fields marked *expr* also take a",
        "`${...}` expression over the procedure's parameters. Editors can validate",
        "files with the schema itself: `suture schema > procedure.schema.json`.",
        "",
        "## Contents",
        "",
    ]
    order = [root, *sorted(n for n in defs if n != root and n not in skills), *sorted(skills)]
    own = document_docs([n for n in order if n not in skills])
    for name in order:
        label = f"`{skills[name][0]}` skill parameters" if name in skills else name
        lines.append(f"- [{label}](#{name.lower()})")
    for name in order:
        d = defs[name]
        lines += ["", f'<a id="{name.lower()}"></a>', ""]
        if name in skills:
            lines.append(f"## {name}: parameters of the `{skills[name][0]}` skill")
        else:
            lines.append(f"## {name}")
        lines.append("")
        if d.get("description"):
            lines += [_md(d["description"]), ""]
        if name in skills:
            events = skill_events(skills[name][0])
            if events:
                names = ", ".join(f"`{e}`" for e in events)
                lines += [f"Named failure events (route with `on: {{EVENT: STATE}}`): {names}.", ""]
        props: dict[str, Any] = d.get("properties", {})
        if not props:
            continue
        docs = skills[name][1] if name in skills else own.get(name, {})
        required = set(d.get("required", []))
        lines += [
            "| field | type | required | default | bounds | expr | meaning |",
            "|---|---|---|---|---|---|---|",
        ]
        for field, node in props.items():
            real, expr = _strip_expr(node)
            default = real.get("default", "")
            default_text = f"`{json.dumps(default)}`" if "default" in real else ""
            lines.append(
                f"| `{field}` | {type_text(real)} | {'yes' if field in required else ''} | "
                f"{default_text} | {_bounds(real)} | {'yes' if expr else ''} | "
                f"{_md(docs.get(field, real.get('description', '')))} |"
            )
        if d.get("additionalProperties") is False:
            lines += ["", "Other fields are errors."]
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description="Generate docs/language.md from the schema.")
    parser.add_argument("--check", action="store_true", help="exit 1 if the file is stale")
    args = parser.parse_args()
    text = render(schema())
    if args.check:
        current = OUT.read_text(encoding="utf-8") if OUT.is_file() else ""
        if current != text:
            print(f"{OUT} is stale: run python docs/gen_language_reference.py", file=sys.stderr)
            return 1
        return 0
    OUT.write_text(text, encoding="utf-8")
    print(OUT)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
