"""The skill catalogue: skills registered by name.

Built-in skills are listed here and imported on first use, so that looking up
one skill does not import them all. Third-party skills register through the
entry-point group ``suture_engine.skills`` (``name = "package.module:Class"``)
or at run time with :func:`register_skill`.
"""

from __future__ import annotations

import difflib
import importlib
from typing import TYPE_CHECKING

from suture_engine.errors import SutureError

if TYPE_CHECKING:
    from skills.base import Skill

__all__ = [
    "BUILTIN_SKILLS",
    "ENTRY_POINT_GROUP",
    "UnknownSkill",
    "available_skills",
    "get_skill",
    "register_skill",
]

ENTRY_POINT_GROUP = "suture_engine.skills"

BUILTIN_SKILLS: dict[str, str] = {
    "move-constrained": "skills.move_constrained:MoveConstrained",
    "pass-needle": "skills.pass_needle:PassNeedle",
    "place-knot": "skills.place_knot:PlaceKnot",
    "tension-regulate": "skills.tension_regulate:TensionRegulate",
    "grasp": "skills.grasp:Grasp",
    "release": "skills.release:Release",
    "hook": "skills.hook:Hook",
    "bend": "skills.bend:Bend",
    "pass-jaws": "skills.pass_jaws:PassJaws",
    "rotate-about": "skills.rotate_about:RotateAbout",
    "wrap": "skills.wrap:Wrap",
    "hold": "skills.hold:Hold",
    "move-to": "skills.move_to:MoveTo",
    "register": "skills.register:Register",
    "cut-suture": "skills.reload:CutSuture",
    "load-suture": "skills.reload:LoadSuture",
    "remove-posts": "skills.remove_posts:RemovePosts",
    "wait-for-operator": "skills.wait_for_operator:WaitForOperator",
}
"""Name -> ``module:Class`` of the skills shipped with the engine."""

_registered: dict[str, type[Skill]] = {}
_entry_points: dict[str, str] | None = None


class UnknownSkill(SutureError):
    """A skill name that is not registered.

    Attributes:
        name: the name asked for.
        available: every registered name, sorted.
        suggestions: the closest registered names (difflib), best first.
    """

    code = "unknown-skill"

    def __init__(self, name: str, available: list[str]) -> None:
        self.name = name
        self.available = sorted(available)
        self.suggestions = difflib.get_close_matches(name, self.available, n=3, cutoff=0.5)
        hint = (
            f"; did you mean {' or '.join(repr(s) for s in self.suggestions)}?"
            if self.suggestions
            else f"; available: {', '.join(self.available)}"
        )
        super().__init__(f"unknown skill {name!r}{hint}")


def register_skill(cls: type[Skill]) -> type[Skill]:
    """Register a skill class under its ``name`` (usable as a decorator)."""
    _registered[cls.name] = cls
    return cls


def _third_party() -> dict[str, str]:
    global _entry_points
    if _entry_points is None:
        from importlib.metadata import entry_points

        _entry_points = {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}
    return _entry_points


def available_skills() -> list[str]:
    """Every registered skill name, sorted (built-in, entry points, run time)."""
    return sorted(set(BUILTIN_SKILLS) | set(_third_party()) | set(_registered))


def _import(target: str) -> type[Skill]:
    module_name, _, attr = target.partition(":")
    module = importlib.import_module(module_name)
    cls: type[Skill] = getattr(module, attr)
    return cls


def get_skill(name: str) -> type[Skill]:
    """The skill class registered under ``name``.

    Raises:
        UnknownSkill: no skill has that name; the error suggests the closest names.
    """
    if name in _registered:
        return _registered[name]
    target = BUILTIN_SKILLS.get(name)
    if target is None:
        target = _third_party().get(name)
    if target is None:
        raise UnknownSkill(name, available_skills())
    cls = _import(target)
    _registered[name] = cls
    return cls
