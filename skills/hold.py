"""``hold``: keep a robot at its current pose (the Lock mode's law, thesis 4.44)."""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import RoleRef
from suture_engine.language.units import Duration

__all__ = ["Hold", "HoldParams"]


class HoldParams(SkillParams):
    """Parameters of ``hold``."""

    robot: RoleRef
    """The role of the robot that holds its pose (``stitcher``, ``grasper``)."""
    duration: Duration | None = Field(default=None, ge=0.0)
    """How long to hold [s]; ``None`` holds until the state's next event."""


class Hold(Skill):
    """Hold the current joint positions (4.44) for ``duration`` [s] or until an event."""

    name: ClassVar[str] = "hold"
    Params: ClassVar[type[SkillParams]] = HoldParams

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime work."""
        raise SkillNotAvailable(self.name)
