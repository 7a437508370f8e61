"""``place-knot``: slide the knot down to the tissue along its normal (4.5).

Both strand ends are pulled so that the knot slides (4.30-4.31) along the
suture-end trajectories (4.36-4.40) with the minimum-tension choice
beta = beta_min.
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Angle, Force, Speed

__all__ = ["PlaceKnot", "PlaceKnotParams"]


class PlaceKnotParams(SkillParams):
    """Parameters of ``place-knot``."""

    post: RoleRef
    """The role holding the post strand."""
    loop: RoleRef
    """The role holding the loop strand."""
    site: PointRef
    """Where the knot is seated on the tissue, named in the scene."""
    max_tension: Force | None = Field(default=None, gt=0.0)
    """Tension bound while sliding [N]; at most the scene's limit."""
    friction: float = Field(default=0.2, ge=0.0, le=2.0)
    """Suture-suture friction coefficient mu of the sliding condition (4.30) [-]."""
    beta: Literal["min"] | Angle = "min"
    """Pulling angle beta [rad], or ``min`` for the minimum-tension choice."""
    speed: Speed = Field(default=0.005, gt=0.0, le=0.1)
    """Knot sliding speed [m/s]."""


class PlaceKnot(Skill):
    """Slide the knot to ``site`` under ``max_tension`` [N]."""

    name: ClassVar[str] = "place-knot"
    Params: ClassVar[type[SkillParams]] = PlaceKnotParams
    tools: ClassVar[tuple[str, ...] | None] = None

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime and suturing work."""
        raise SkillNotAvailable(self.name)
