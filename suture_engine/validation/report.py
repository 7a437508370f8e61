"""The work behind ``suture validate``, ``suture schema`` and ``suture graph``.

Each function returns the exit code (0 ok, 1 invalid, 2 usage or I/O error)
and writes its output to the given streams; the CLI module only parses
arguments. Nothing here prints a traceback for bad input.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

if TYPE_CHECKING:
    from suture_engine.language.procedure import Procedure
    from suture_engine.validation.problem import Problem

__all__ = ["graph_command", "parse_sets", "schema_command", "validate_command"]

IO_CODES = frozenset({"io-error"})
"""Problem codes that mean the input could not be read (exit code 2)."""


def parse_sets(sets: Sequence[str]) -> dict[str, Any]:
    """``["algorithm=3", "tail=20 mm"]`` -> ``{"algorithm": 3, "tail": "20 mm"}``.

    Values are read as YAML scalars (numbers, booleans, strings).

    Raises:
        ValueError: an item is not ``name=value``.
    """
    import yaml

    out: dict[str, Any] = {}
    for item in sets:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"--set expects name=value, found {item!r}")
        try:
            parsed = yaml.safe_load(value) if value.strip() else value
        except yaml.YAMLError:
            parsed = value
        if not isinstance(parsed, (str, int, float, bool)):
            parsed = value
        out[name.strip()] = parsed
    return out


def validate_command(
    files: Sequence[Path],
    *,
    fmt: str = "text",
    allow_outside: bool = False,
    sets: Sequence[str] = (),
    out: TextIO | None = None,
    err: TextIO | None = None,
) -> int:
    """Validate procedure files and report every problem.

    Args:
        files: procedure files.
        fmt: ``text`` (one ``file:line:col: code: message (at path)`` line per problem)
            or ``json`` (a list of objects with file, line, column, path, code, message).
        allow_outside: allow includes outside each procedure's folder tree.
        sets: ``name=value`` overrides of the procedures' parameters.
        out: where results go (default stdout).
        err: where usage errors go (default stderr).

    Returns:
        0 when every file is valid, 1 when any is invalid, 2 for usage or I/O errors
        (a ``--set`` that is not ``name=value`` or names no parameter of a file).
    """
    from suture_engine.validation.checks import validate_file

    out = out or sys.stdout
    err = err or sys.stderr
    if fmt not in ("text", "json"):
        err.write(f"error: --format must be text or json, found {fmt!r}\n")
        return 2
    try:
        params = parse_sets(sets) if sets else None
    except ValueError as exc:
        err.write(f"error: {exc}\n")
        return 2
    problems: list[Problem] = []
    io_error = False
    for file in files:
        found = validate_file(file, allow_outside=allow_outside, params=params)
        io_error = io_error or any(p.code in IO_CODES for p in found)
        problems.extend(found)
        if fmt == "text":
            for p in found:
                out.write(p.format() + "\n")
            if not found:
                out.write(f"{file}: valid\n")
    if fmt == "json":
        json.dump([p.as_dict() for p in problems], out, indent=2)
        out.write("\n")
    elif problems:
        err.write(f"{len(problems)} problem{'s' if len(problems) != 1 else ''} found\n")
    # A --set naming no parameter is a usage error, as in `suture run` (a refused value is
    # invalid input: exit 1); the loader reports it located, as "(override) ...".
    bad_set = any(
        p.code == "unknown-param" and p.message.startswith("(override)") for p in problems
    )
    if io_error or bad_set:
        return 2
    return 1 if problems else 0


def schema_command(out: TextIO | None = None) -> int:
    """Print the JSON Schema of the procedure language."""
    from suture_engine.language.schema import procedure_schema

    out = out or sys.stdout
    json.dump(procedure_schema(), out, indent=2)
    out.write("\n")
    return 0


def graph_command(
    file: Path,
    *,
    fmt: str = "mermaid",
    allow_outside: bool = False,
    engine: str = "text",
    out: TextIO | None = None,
    err: TextIO | None = None,
) -> int:
    """Draw a procedure's state machine as Mermaid ``stateDiagram-v2`` or Graphviz ``dot``.

    The procedure must load (the semantic checks are ``suture validate``'s job).

    Args:
        file: the procedure file.
        fmt: ``mermaid`` or ``dot``.
        allow_outside: allow includes outside the procedure's folder tree.
        engine: ``text`` (the engine's own writer) or ``transitions`` (``transitions``'
            ``GraphMachine`` with its Mermaid engine; mermaid only).
        out: where the drawing goes (default stdout).
        err: where problems go (default stderr).
    """
    from suture_engine.language.loader import load
    from suture_engine.validation.graph import to_dot, to_mermaid, to_mermaid_transitions

    out = out or sys.stdout
    err = err or sys.stderr
    if fmt not in ("mermaid", "dot"):
        err.write(f"error: --format must be mermaid or dot, found {fmt!r}\n")
        return 2
    if engine not in ("text", "transitions") or (engine == "transitions" and fmt != "mermaid"):
        err.write("error: --engine is text, or transitions with --format mermaid\n")
        return 2
    result = load(file, allow_outside=allow_outside)
    if result.problems or result.procedure is None:
        for p in result.problems:
            err.write(p.format() + "\n")
        return 2 if any(p.code in IO_CODES for p in result.problems) else 1
    proc: Procedure = result.procedure
    if engine == "transitions":
        out.write(to_mermaid_transitions(proc))
    else:
        out.write(to_mermaid(proc) if fmt == "mermaid" else to_dot(proc))
    return 0
