"""Meta-test: the public API of the language, validation and skill modules is documented."""

from __future__ import annotations

import importlib
import inspect

import pytest

MODULES = [
    "suture_engine.language.units",
    "suture_engine.language.refs",
    "suture_engine.language.source",
    "suture_engine.language.expressions",
    "suture_engine.language.model",
    "suture_engine.language.scene",
    "suture_engine.language.procedure",
    "suture_engine.language.loader",
    "suture_engine.language.schema",
    "suture_engine.validation.problem",
    "suture_engine.validation.checks",
    "suture_engine.validation.reach",
    "suture_engine.validation.graph",
    "suture_engine.validation.report",
    "suture_engine.control.force",
    "skills.base",
    "skills.registry",
]


@pytest.mark.parametrize("name", MODULES)
def test_public_names_are_exported_and_documented(name: str) -> None:
    module = importlib.import_module(name)
    assert inspect.getdoc(module), f"{name} has no module docstring"
    exported = getattr(module, "__all__", None)
    assert exported is not None, f"{name} has no __all__"
    for attr in exported:
        obj = getattr(module, attr)
        if inspect.isfunction(obj) or inspect.isclass(obj):
            assert inspect.getdoc(obj), f"{name}.{attr} is undocumented"
        if inspect.isfunction(obj):
            doc = inspect.getdoc(obj) or ""
            params = [p for p in inspect.signature(obj).parameters if p not in ("self", "cls")]
            if len(params) > 1 and "Args:" in doc:
                for p in params:
                    assert p in doc, f"{name}.{attr}: parameter {p!r} is undocumented"
