"""``pass-needle``: make a stitch and pull the suture through (4.1-4.4).

The needle enters at ``entry`` and leaves at ``exit``; the suture is then
pulled out to the desired length l_d with the tension kept under f_max by the
extension-rate bound (4.10-4.11). The suture length is tracked from the needle
position only (4.1, 4.3-4.4).
"""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Force, Length, Speed

__all__ = ["PassNeedle", "PassNeedleParams"]


class PassNeedleParams(SkillParams):
    """Parameters of ``pass-needle``."""

    robot: RoleRef
    """The role of the robot holding the needle (the stitcher, or a needle holder)."""
    entry: PointRef
    """Entry point of the bite (p_a), named in the scene."""
    exit: PointRef
    """Exit point of the bite (p_b), named in the scene."""
    bite_depth: Length = Field(default=3e-3, gt=0.0, le=0.02)
    """Depth of the bite below the surface [m]."""
    pull_length: Length = Field(gt=0.0, le=1.0)
    """Suture length l_d left out of the entry point, i.e. the tail [m]."""
    max_tension: Force | None = Field(default=None, gt=0.0)
    """f_max, the tension bound while pulling [N]; at most the scene's limit."""
    speed: Speed = Field(default=0.01, gt=0.0, le=0.2)
    """Pulling speed bound [m/s]."""


class PassNeedle(Skill):
    """Stitch from ``entry`` to ``exit`` and pull the suture out to ``pull_length``."""

    name: ClassVar[str] = "pass-needle"
    Params: ClassVar[type[SkillParams]] = PassNeedleParams
    tools: ClassVar[tuple[str, ...] | None] = (
        "stitcher",
        "grasper",
        "hook-grasper",
        "bent-tip-grasper",
    )

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime and suturing work."""
        raise SkillNotAvailable(self.name)
