"""Mapping pydantic's validation errors to located :class:`Problem` records."""

from __future__ import annotations

import difflib
from typing import Any

from pydantic import BaseModel, ValidationError

from suture_engine.language.source import PathKey, SourceMap
from suture_engine.validation.problem import Problem

__all__ = ["InvalidValue", "problems_from_validation"]


class InvalidValue:
    """Stands in for a value already reported as a problem (a bad expression), so
    that validation does not report it a second time."""

    def __repr__(self) -> str:
        return "<invalid>"


_CODES = {
    "extra_forbidden": "unknown-key",
    "missing": "missing-field",
    "unit_mismatch": "unit-mismatch",
    "greater_than": "out-of-bounds",
    "greater_than_equal": "out-of-bounds",
    "less_than": "out-of-bounds",
    "less_than_equal": "out-of-bounds",
    "literal_error": "bad-value",
    "enum": "bad-value",
}


def _fields(model: type[BaseModel] | None, loc: tuple[Any, ...]) -> list[str]:
    """Field names (and aliases) of the model at ``loc``, for suggestions."""
    current: Any = model
    for part in loc:
        if not (isinstance(current, type) and issubclass(current, BaseModel)):
            return []
        field = current.model_fields.get(str(part))
        if field is None:
            for f in current.model_fields.values():
                if f.alias == part:
                    field = f
        if field is None:
            return []
        current = _model_in(field.annotation)
    if isinstance(current, type) and issubclass(current, BaseModel):
        return [f.alias or n for n, f in current.model_fields.items()]
    return []


def _model_in(annotation: Any) -> Any:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in getattr(annotation, "__args__", ()) or ():
        found = _model_in(arg)
        if found is not None:
            return found
    return None


def problems_from_validation(
    exc: ValidationError,
    source: SourceMap,
    prefix: PathKey,
    model: type[BaseModel] | None = None,
) -> list[Problem]:
    """Turn a pydantic error into one located problem per error.

    Args:
        exc: the validation error.
        source: the source map of the validated document.
        prefix: the path of the validated node inside the document.
        model: the validated model, used to suggest the closest key for a misspelt one.
    """
    problems: list[Problem] = []
    for err in exc.errors(include_url=False):
        if isinstance(err.get("input"), InvalidValue):
            continue
        raw_loc = tuple(err.get("loc", ()))
        # drop pydantic's union-branch markers (type names such as "str", "tuple[...]")
        loc = tuple(p for p in raw_loc if not (isinstance(p, str) and ("[" in p or p in _BRANCHES)))
        kind = err.get("type", "")
        code = _CODES.get(kind, "schema")
        message = str(err.get("msg", "invalid value"))
        if message.startswith("Value error, "):
            message = message[len("Value error, ") :]
        if kind == "extra_forbidden" and loc:
            key = str(loc[-1])
            close = difflib.get_close_matches(key, _fields(model, loc[:-1]), n=1, cutoff=0.6)
            message = f"unknown key {key!r}" + (f"; did you mean {close[0]!r}?" if close else "")
        elif kind == "missing" and loc:
            message = f"missing required key {str(loc[-1])!r}"
        elif "input" in err and kind not in ("missing", "unit_mismatch"):
            found = (
                str(err["input"])
                if type(err["input"]).__name__ == "Quantity"
                else repr(err["input"])
            )
            if len(found) > 60:
                found = found[:57] + "..."
            message = f"{message}, found {found}"
        at_key = kind == "extra_forbidden"
        problems.append(source.problem(code, message, (*prefix, *loc), at_key=at_key))
    return _dedupe(problems)


_BRANCHES = {
    "str",
    "int",
    "float",
    "bool",
    "dict",
    "list",
    "tuple",
    "none",
    "literal",
    "function-before",
    "function-after",
    "function-plain",
    "is-instance",
}


def _dedupe(problems: list[Problem]) -> list[Problem]:
    seen: set[tuple[str, str]] = set()
    out: list[Problem] = []
    for p in problems:
        # a union yields one error per branch at the same place; keep the first of each code
        key = (p.path, p.code)
        if key in seen:
            continue
        seen.add(key)
        out.append(p)
    return out
