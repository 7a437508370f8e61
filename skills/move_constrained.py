"""``move-constrained``: tool motion under a virtual fixture (chapter 6, 7.3.2).

The fixture geometry is given in the robot's base frame, whose origin is the
remote centre of motion (the spherical joint at the incision): a line
(6.28-6.32), a circle in a plane z = z0 (6.43-6.46), a plane, or a cone.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Angle, Duration, Force, Length, Position, Speed

if TYPE_CHECKING:
    from suture_engine.validation.problem import Problem

__all__ = ["MoveConstrained", "MoveConstrainedParams"]


class MoveConstrainedParams(SkillParams):
    """Parameters of ``move-constrained``."""

    robot: RoleRef
    """The role of the robot that moves."""
    fixture: Literal["line", "circle", "plane", "cone"]
    """The virtual fixture the tool tip must stay on (line, circle) or in (plane, cone)."""
    point: Position = (0.0, 0.0, 0.0)
    """A point of the line, the circle's centre (x0, y0, z0), a point of the plane,
    or the cone's apex, in the robot's base frame [m]."""
    direction: tuple[float, float, float] = (0.0, 0.0, 1.0)
    """The line's direction (a1, a2, a3) (6.28), or the normal of the circle's
    plane / of the plane, or the cone's axis [-]; need not be a unit vector."""
    radius: Length | None = Field(default=None, gt=0.0)
    """The circle's radius r [m] (6.43)."""
    half_angle: Angle | None = Field(default=None, gt=0.0, lt=math.pi / 2)
    """The cone's half angle [rad]."""
    mode: Literal["autonomous", "shared"] = "autonomous"
    """``autonomous`` tracks ``target``; ``shared`` lets the operator move the tool
    along the fixture (task-space shared control, 6.24)."""
    target: PointRef | Position | None = None
    """Where to go along the fixture (autonomous mode): a tissue point or (x, y, z)
    in the world frame [m]."""
    speed: Speed = Field(default=0.01, gt=0.0, le=0.2)
    """Cruise speed of the tool tip [m/s]."""
    duration: Duration | None = Field(default=None, gt=0.0)
    """How long the shared-control phase lasts [s]; ``None`` until an event."""
    max_tension: Force | None = Field(default=None, gt=0.0)
    """Suture tension bound held by the extension-rate limit (4.10-4.11) [N]."""


class MoveConstrained(Skill):
    """Move the tool tip while it stays on a virtual fixture (6.31-6.32, 6.43-6.46)."""

    name: ClassVar[str] = "move-constrained"
    Params: ClassVar[type[SkillParams]] = MoveConstrainedParams

    @classmethod
    def check(cls, params: SkillParams, scene: Any) -> list[Problem]:
        """The fixture is fully specified: a non-zero direction, a radius for a
        circle, a half angle for a cone, and a target in autonomous mode."""
        from suture_engine.validation.problem import Problem

        assert isinstance(params, MoveConstrainedParams)
        problems: list[Problem] = []
        if math.hypot(*params.direction) < 1e-12:
            problems.append(
                Problem("out-of-bounds", "fixture direction must be non-zero", path="direction")
            )
        if params.fixture == "circle" and params.radius is None:
            problems.append(
                Problem("missing-field", "a circle fixture needs a radius", path="radius")
            )
        if params.fixture == "cone" and params.half_angle is None:
            problems.append(
                Problem("missing-field", "a cone fixture needs a half_angle", path="half_angle")
            )
        if params.mode == "autonomous" and params.target is None:
            problems.append(
                Problem("missing-field", "autonomous mode needs a target", path="target")
            )
        return problems

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime work."""
        raise SkillNotAvailable(self.name)
