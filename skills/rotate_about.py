"""``rotate-about``: rotate a tool about an axis through the RCM point (algorithm 1 step 4).

The axis is OP: O the centre of the spherical joint (the robot's RCM), P a
point given in the world frame or named in the scene, or taken relative to
another robot's tool tip.
"""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Angle, AngularSpeed, Position

__all__ = ["RotateAbout", "RotateAboutParams"]


class RotateAboutParams(SkillParams):
    """Parameters of ``rotate-about``."""

    robot: RoleRef
    """The role of the robot that rotates."""
    angle: Angle = Field(ge=-4 * 3.141592653589793, le=4 * 3.141592653589793)
    """Rotation angle about OP [rad]; the mirror image of a knot uses the opposite sign."""
    point: PointRef | Position | None = None
    """P, the second point of the axis: a tissue point or (x, y, z) in the world frame
    [m]; ``None`` uses the contact point left by the previous step."""
    relative_to: RoleRef | None = None
    """When set, ``point`` is an offset [m] from that robot's tool tip."""
    speed: AngularSpeed = Field(default=0.5, gt=0.0, le=5.0)
    """Angular speed [rad/s]."""


class RotateAbout(Skill):
    """Rotate the tool by ``angle`` [rad] about the axis OP through the RCM point O."""

    name: ClassVar[str] = "rotate-about"
    Params: ClassVar[type[SkillParams]] = RotateAboutParams
    tools: ClassVar[tuple[str, ...] | None] = None

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime and suturing work."""
        raise SkillNotAvailable(self.name)
