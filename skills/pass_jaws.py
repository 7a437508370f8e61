"""``pass-jaws``: close the stitcher and pass the needle to its other jaw (4.4)."""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import RoleRef
from suture_engine.language.units import Force

__all__ = ["PassJaws", "PassJawsParams"]


class PassJawsParams(SkillParams):
    """Parameters of ``pass-jaws``."""

    robot: RoleRef
    """The role of the stitcher."""
    close_force: Force = Field(default=5.0, gt=0.0, le=30.0)
    """Force closing the jaws on the needle [N]."""


class PassJaws(Skill):
    """Close the stitcher jaws and pass the needle to the other jaw (algorithm 1 step 6)."""

    name: ClassVar[str] = "pass-jaws"
    Params: ClassVar[type[SkillParams]] = PassJawsParams
    tools: ClassVar[tuple[str, ...] | None] = ("stitcher",)

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime and suturing work."""
        raise SkillNotAvailable(self.name)
