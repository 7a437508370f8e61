"""Meta-test: every public callable of the trace modules documents each of its parameters
(Google style, ``Args:``), the way python-control's docstring test does."""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Iterator
from typing import Any

import pytest

MODULES = [
    "suture_engine.trace.channels",
    "suture_engine.trace.cli_trace",
    "suture_engine.trace.codec",
    "suture_engine.trace.errors",
    "suture_engine.trace.golden",
    "suture_engine.trace.pytest_plugin",
    "suture_engine.trace.reader",
    "suture_engine.trace.synthetic",
    "suture_engine.trace.writer",
]


def _callables() -> Iterator[tuple[str, Any, str]]:
    for name in MODULES:
        mod = importlib.import_module(name)
        assert hasattr(mod, "__all__"), name
        for public in mod.__all__:
            obj = getattr(mod, public)
            if inspect.isclass(obj):
                if issubclass(obj, BaseException) or hasattr(obj, "_fields"):
                    continue
                init = obj.__dict__.get("__init__")
                if init is not None and "__dataclass_fields__" not in obj.__dict__:
                    yield f"{name}.{public}", init, obj.__doc__ or ""
                for meth_name, meth in vars(obj).items():
                    if inspect.isfunction(meth) and not meth_name.startswith("_"):
                        yield f"{name}.{public}.{meth_name}", meth, meth.__doc__ or ""
            elif inspect.isfunction(obj):
                yield f"{name}.{public}", obj, obj.__doc__ or ""


@pytest.mark.parametrize(("qualname", "func", "doc"), list(_callables()))
def test_every_parameter_is_documented(qualname: str, func: Any, doc: str) -> None:
    assert doc.strip(), f"{qualname} has no docstring"
    params = [
        p
        for p in inspect.signature(func).parameters.values()
        if p.name not in ("self", "cls") and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
    ]
    if len(params) <= 1 and "Args:" not in doc:
        return  # a one-argument call whose docstring says what the argument is
    missing = [p.name for p in params if f"{p.name}:" not in doc]
    assert not missing, f"{qualname}: undocumented {missing}"
