"""``release``: open a grasper or a stitcher jaw."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import RoleRef

__all__ = ["Release", "ReleaseParams"]


class ReleaseParams(SkillParams):
    """Parameters of ``release``."""

    robot: RoleRef
    """The role of the robot that releases."""
    what: Literal["suture-tail", "suture", "needle", "tissue", "any"] = "any"
    """What is released."""


class Release(Skill):
    """Open the tool so that it lets go of ``what``."""

    name: ClassVar[str] = "release"
    Params: ClassVar[type[SkillParams]] = ReleaseParams
    tools: ClassVar[tuple[str, ...] | None] = None

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime and suturing work."""
        raise SkillNotAvailable(self.name)
