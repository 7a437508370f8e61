"""``wrap``: loop the suture around the other tool (algorithms 2 and 3).

Algorithm 2 moves the stitcher over the extended hook so that the suture hangs
over it; algorithm 3 moves the needle holder around the bent grasper tip. The
mirror image of a knot wraps in the opposite direction.
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import RoleRef
from suture_engine.language.units import Length, Speed

__all__ = ["Wrap", "WrapParams"]


class WrapParams(SkillParams):
    """Parameters of ``wrap``."""

    robot: RoleRef
    """The role of the robot that carries the suture around."""
    around: RoleRef
    """The role of the robot whose tool the loop goes around."""
    direction: Literal["front-to-back", "back-to-front"] = "front-to-back"
    """Direction of the loop; a mirrored knot uses ``back-to-front``."""
    turns: int = Field(default=1, ge=1, le=3)
    """Number of loops (2 for the first throw of a surgeon's knot)."""
    radius: Length = Field(default=8e-3, gt=0.0, le=0.05)
    """Radius of the loop around the other tool [m]."""
    speed: Speed = Field(default=0.01, gt=0.0, le=0.2)
    """Tool-tip speed [m/s]."""


class Wrap(Skill):
    """Carry the suture around the other tool ``turns`` times in ``direction``."""

    name: ClassVar[str] = "wrap"
    Params: ClassVar[type[SkillParams]] = WrapParams
    tools: ClassVar[tuple[str, ...] | None] = (
        "stitcher",
        "grasper",
        "hook-grasper",
        "bent-tip-grasper",
    )

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime and suturing work."""
        raise SkillNotAvailable(self.name)
