"""The procedure language: YAML with source positions, models, units, expressions.

Public entry points (imported lazily, so that ``import suture_engine.language``
stays cheap):

- :func:`load` / :func:`load_procedure`: a file -> :class:`Procedure`;
- :class:`Procedure`, :class:`LoadedState`: what the runtime compiles;
- :class:`Scene`: the scene model (Tables 7.1, 7.2, the tension limit);
- :func:`procedure_schema`: the JSON Schema behind ``suture schema``.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = [
    "LoadResult",
    "LoadedState",
    "Procedure",
    "Scene",
    "load",
    "load_procedure",
    "procedure_schema",
]

_WHERE = {
    "LoadResult": "suture_engine.language.loader",
    "load": "suture_engine.language.loader",
    "load_procedure": "suture_engine.language.loader",
    "LoadedState": "suture_engine.language.procedure",
    "Procedure": "suture_engine.language.procedure",
    "Scene": "suture_engine.language.scene",
    "procedure_schema": "suture_engine.language.schema",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
