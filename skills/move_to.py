"""``move-to``: move a robot's tool tip to a point, in free space."""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Angle, Length, Position, Speed

__all__ = ["MoveTo", "MoveToParams"]


class MoveToParams(SkillParams):
    """Parameters of ``move-to``."""

    robot: RoleRef
    """The role of the robot that moves."""
    target: PointRef | Position
    """Where the tool tip goes: a named tissue point of the scene, or (x, y, z) in
    the world frame [m]."""
    offset: Position = (0.0, 0.0, 0.0)
    """Added to the target, in the world frame [m] (e.g. to stop above the tissue)."""
    roll: Angle | None = None
    """Tool roll q3 at the target [rad] (3.17); ``None`` keeps the current roll."""
    speed: Speed = Field(default=0.01, gt=0.0, le=0.2)
    """Cruise speed of the tool tip [m/s]."""
    tolerance: Length = Field(default=0.5e-3, gt=0.0)
    """Arrival tolerance of the tool-tip position [m]."""


class MoveTo(Skill):
    """Move the tool tip to ``target + offset`` at ``speed`` [m/s]."""

    name: ClassVar[str] = "move-to"
    Params: ClassVar[type[SkillParams]] = MoveToParams

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime work."""
        raise SkillNotAvailable(self.name)
