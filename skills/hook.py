"""``hook``: extend or retract the flexible hook over the grasper hinge (4.4.2)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import RoleRef
from suture_engine.language.units import Length

__all__ = ["Hook", "HookParams"]


class HookParams(SkillParams):
    """Parameters of ``hook``."""

    robot: RoleRef
    """The role of the robot carrying the hook grasper."""
    action: Literal["extend", "retract"]
    """Extend the hook (to snare the suture) or retract it (algorithm 2 steps 2, 4)."""
    travel: Length = Field(default=5e-3, gt=0.0, le=0.02)
    """Stroke of the reciprocating actuator [m]."""


class Hook(Skill):
    """Extend or retract the flexible hook (algorithm 2)."""

    name: ClassVar[str] = "hook"
    Params: ClassVar[type[SkillParams]] = HookParams
    tools: ClassVar[tuple[str, ...] | None] = ("hook-grasper",)

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime and suturing work."""
        raise SkillNotAvailable(self.name)
