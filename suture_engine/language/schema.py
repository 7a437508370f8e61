"""The JSON Schema of the procedure language, for editors (``suture schema``).

The schema is the document model's, with each state's ``with`` tied to the
parameter model of the skill it names (an ``if``/``then`` per registered
skill), so that an editor completes and checks skill parameters too.
Quantities accept a number (SI) or a string such as ``"20 mm"``; any value may
also be a ``${...}`` expression, which the schema cannot check.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:
    from pydantic import BaseModel

__all__ = ["SCHEMA_ID", "procedure_schema"]

SCHEMA_ID = "https://suture-engine.invalid/schema/procedure.json"
"""The ``$id`` of the schema."""


def procedure_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a procedure file."""
    from pydantic.json_schema import models_json_schema

    from skills.registry import available_skills, get_skill
    from suture_engine.language.model import ProcedureDocument

    skills = {}
    for name in available_skills():
        try:
            skills[name] = get_skill(name)
        except Exception:  # a broken third-party skill must not break the schema
            continue
    models: list[tuple[type[BaseModel], Literal["validation"]]] = [
        (ProcedureDocument, "validation")
    ]
    models += [(cls.Params, "validation") for cls in skills.values()]
    refs, schema = models_json_schema(models, ref_template="#/$defs/{model}")
    defs = schema.setdefault("$defs", {})
    state = defs.get("StateDocument")
    if state is not None:
        state["allOf"] = [
            {
                "if": {"properties": {"skill": {"const": name}}, "required": ["skill"]},
                "then": {"properties": {"with": refs[(cls.Params, "validation")]}},
            }
            for name, cls in skills.items()
        ]
        state["properties"]["skill"] = {"enum": sorted(skills), "type": "string"}
    for model in defs.values():
        _allow_expressions(model)
    root = refs[(ProcedureDocument, "validation")]
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": SCHEMA_ID,
        "title": "suture-engine procedure",
        **root,
        "$defs": defs,
    }


EXPRESSION = {"type": "string", "pattern": r"\$\{.*\}"}
"""A string holding a ``${...}`` expression (or an interpolation)."""


def _allow_expressions(schema: Any) -> None:
    """Let every property, array item and tuple item also be a ``${...}`` string."""
    if not isinstance(schema, dict):
        return
    for key in ("properties",):
        props = schema.get(key)
        if isinstance(props, dict):
            for name, sub in list(props.items()):
                _allow_expressions(sub)
                props[name] = {"anyOf": [sub, EXPRESSION]}
    for key in ("items", "additionalProperties"):
        sub = schema.get(key)
        if isinstance(sub, dict):
            _allow_expressions(sub)
            schema[key] = {"anyOf": [sub, EXPRESSION]}
    for key in ("prefixItems", "anyOf", "oneOf", "allOf"):
        subs = schema.get(key)
        if isinstance(subs, list):
            for i, sub in enumerate(subs):
                _allow_expressions(sub)
                if key == "prefixItems":
                    subs[i] = {"anyOf": [sub, EXPRESSION]}
