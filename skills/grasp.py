"""``grasp``: close a grasper on the suture tail, the suture, or the needle (4.4)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Force, Position

__all__ = ["Grasp", "GraspParams"]


class GraspParams(SkillParams):
    """Parameters of ``grasp``."""

    robot: RoleRef
    """The role of the grasping robot."""
    what: Literal["suture-tail", "suture", "needle", "tissue"] = "suture-tail"
    """What to grasp. The suture tail is found from the stitch just made
    (algorithm 1 step 2): the skill never measures the suture itself."""
    target: PointRef | Position | None = None
    """Where to grasp: a tissue point or (x, y, z) in the world frame [m];
    ``None`` grasps where the tool is."""
    offset: Position = (0.0, 0.0, 0.0)
    """Added to the target, world frame [m]."""
    force: Force = Field(default=2.0, gt=0.0, le=20.0)
    """Grip force [N]."""


class Grasp(Skill):
    """Move the grasper tip to the target, then close it on ``what``."""

    name: ClassVar[str] = "grasp"
    Params: ClassVar[type[SkillParams]] = GraspParams
    tools: ClassVar[tuple[str, ...] | None] = ("grasper", "hook-grasper", "bent-tip-grasper")

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime and suturing work."""
        raise SkillNotAvailable(self.name)
