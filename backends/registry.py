"""Backends by name; third parties register through the entry-point group
``suture_engine.backends`` (value: a zero-argument factory or a class).
"""

from __future__ import annotations

import difflib
import importlib
from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any

from suture_engine.errors import SutureError

__all__ = ["ENTRY_POINT_GROUP", "UnknownBackend", "available", "create", "is_known", "register"]

ENTRY_POINT_GROUP = "suture_engine.backends"

_BUILTIN: dict[str, str] = {
    "pybullet": "backends.pybullet.backend:PyBulletBackend",
    "pybullet-surgical": "backends.pybullet.backend:SurgicalPyBulletBackend",
    "replay": "backends.replay:ReplayBackend",
    "ideal": "suture_engine.runtime.testing:IdealBackend",
}
_REGISTERED: dict[str, Callable[..., Any]] = {}


class UnknownBackend(SutureError):
    """No backend of that name.

    Attributes:
        name: the name asked for.
        available: the registered names.
        suggestions: the closest registered names.
    """

    code = "unknown-backend"

    def __init__(self, name: str, available: list[str]) -> None:
        self.name = name
        self.available = available
        self.suggestions = difflib.get_close_matches(name, available, n=3)
        hint = f" (did you mean {', '.join(self.suggestions)}?)" if self.suggestions else ""
        super().__init__(f"unknown backend {name!r}{hint}; available: {', '.join(available)}")


def register(name: str, factory: Callable[..., Any]) -> None:
    """Register a backend factory under ``name`` (replaces an earlier one)."""
    _REGISTERED[name] = factory


_SCANNED: dict[str, Any] | None = None
"""The entry points of :data:`ENTRY_POINT_GROUP`, scanned once per process (a scan reads
every installed package's metadata: tens of milliseconds)."""


def _entry_points() -> dict[str, Any]:
    global _SCANNED
    if _SCANNED is None:
        _SCANNED = {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}
    return _SCANNED


def available() -> list[str]:
    """Sorted names of built-in, registered and entry-point backends."""
    return sorted(set(_BUILTIN) | set(_REGISTERED) | set(_entry_points()))


def is_known(name: str) -> bool:
    """Whether ``name`` names a backend. Entry points are scanned (tens of milliseconds)
    only for a name that is neither built in nor registered."""
    return name in _BUILTIN or name in _REGISTERED or name in _entry_points()


def _load(target: str) -> Callable[..., Any]:
    module, _, attr = target.partition(":")
    obj: Callable[..., Any] = getattr(importlib.import_module(module), attr)
    return obj


def create(name: str, **kwargs: Any) -> Any:
    """Instantiate the backend ``name`` with keyword options (e.g. ``gui=True``).

    Raises:
        UnknownBackend: no backend of that name.
    """
    if name in _REGISTERED:
        return _REGISTERED[name](**kwargs)
    if name in _BUILTIN:
        return _load(_BUILTIN[name])(**kwargs)
    eps = _entry_points()
    if name in eps:
        return eps[name].load()(**kwargs)
    raise UnknownBackend(name, available())
