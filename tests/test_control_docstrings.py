"""Meta-test: every public callable of the control and identification modules documents
each of its parameters (Google style, ``Args:``), as python-control's docstring test does."""

from __future__ import annotations

import importlib
import inspect

import pytest

MODULES = [
    "suture_engine.control.filters",
    "suture_engine.control.gravity",
    "suture_engine.control.kalman",
    "suture_engine.control.lqr",
    "suture_engine.control.model",
    "suture_engine.control.pd",
    "suture_engine.control.tracking",
    "suture_engine.robot.excitation",
    "suture_engine.robot.identification",
    "suture_engine.robot.identification_experiment",
    "suture_engine.robot.identification_report",
]


def _callables():  # type: ignore[no-untyped-def]
    for name in MODULES:
        mod = importlib.import_module(name)
        assert hasattr(mod, "__all__"), name
        for public in mod.__all__:
            obj = getattr(mod, public)
            if inspect.isclass(obj):
                if issubclass(obj, BaseException) or hasattr(obj, "_fields"):
                    continue
                init = obj.__dict__.get("__init__")
                if init is not None:
                    yield f"{name}.{public}", init, obj.__doc__ or ""
                for meth_name, meth in vars(obj).items():
                    if inspect.isfunction(meth) and not meth_name.startswith("_"):
                        yield f"{name}.{public}.{meth_name}", meth, meth.__doc__ or ""
            elif inspect.isfunction(obj):
                yield f"{name}.{public}", obj, obj.__doc__ or ""


@pytest.mark.parametrize(("qualname", "func", "doc"), list(_callables()))
def test_every_parameter_is_documented(qualname: str, func: object, doc: str) -> None:
    assert doc.strip(), f"{qualname} has no docstring"
    sig = inspect.signature(func)  # type: ignore[arg-type]
    params = [
        p
        for p in sig.parameters.values()
        if p.name not in ("self", "cls") and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
    ]
    if len(params) <= 1 and "Args:" not in doc:
        return  # a one-argument call whose docstring names its meaning and unit inline
    missing = [p.name for p in params if f"{p.name}:" not in doc]
    assert not missing, f"{qualname}: undocumented {missing}"
