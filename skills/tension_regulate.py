"""``tension-regulate``: secure a knot by applying a regulated tension (chapter 7).

Hybrid force/position control (7.11-7.20): explicit PI force control with
active damping (7.22) along the securing direction of the throw (7.1-7.3,
opposite for the two throws of a square knot), with the tension estimated
from the base force/torque sensor (7.6-7.10) and an optional ramped
("modified") force reference (Fig. 7.29). The dry-run checks the tension
against the scene's limit and the gains against the Routh bounds (7.29, 7.33,
and 7.41, 7.43 when the scene declares a measurement delay).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import RoleRef
from suture_engine.language.units import Damping, Duration, Force, Unit

if TYPE_CHECKING:
    from suture_engine.validation.problem import Problem

__all__ = ["TensionRegulate", "TensionRegulateParams"]


class TensionRegulateParams(SkillParams):
    """Parameters of ``tension-regulate``."""

    robot: RoleRef
    """The role of the robot that pulls (its base carries the force sensor)."""
    tension: Force = Field(gt=0.0)
    """Desired tension F_des [N]; at most the scene's tension limit."""
    throw: Literal[1, 2] = 1
    """Which throw of a square knot is secured; the second pulls the opposite way (7.1-7.3)."""
    kp: float = Field(default=0.2, ge=0.0, le=1e3)
    """Proportional force gain Kp [-] (7.22)."""
    ki: Annotated[float, Unit("1/s")] = Field(default=0.3, gt=0.0, le=1e4)
    """Integral force gain Ki [1/s] (7.22)."""
    kv: Damping = Field(default=2000.0, ge=0.0, le=1e5)
    """Active damping gain Kv [N*s/m] (7.30)."""
    ramp: bool = True
    """Use the modified (ramped) force reference of Fig. 7.29."""
    hold_time: Duration = Field(default=2.0, gt=0.0, le=60.0)
    """How long the tension is held once reached [s]."""


class TensionRegulate(Skill):
    """Pull to ``tension`` [N] under explicit PI force control with active damping (7.22)."""

    name: ClassVar[str] = "tension-regulate"
    Params: ClassVar[type[SkillParams]] = TensionRegulateParams

    @classmethod
    def check(cls, params: SkillParams, scene: Any) -> list[Problem]:
        """Ki within the Routh stability bound of the scene's force plant (7.29, 7.33),
        with the scene's measurement delay when it declares one (7.41, 7.43)."""
        from suture_engine.control.force import integral_gain_bound
        from suture_engine.validation.problem import Problem

        assert isinstance(params, TensionRegulateParams)
        if scene is None:
            return []
        plant = scene.physics.force_plant
        delay = scene.physics.measurement_delay
        bound = integral_gain_bound(
            plant.mass, plant.damping, plant.stiffness, params.kp, params.kv, delay
        )
        if params.ki < bound:
            return []
        eq = "(7.41, 7.43)" if delay > 0 else "(7.29, 7.33)"
        why = f" with a {delay * 1e3:g} ms measurement delay" if delay > 0 else ""
        return [
            Problem(
                "unstable-gains",
                f"Ki = {params.ki:g} 1/s is not below the Routh stability bound {bound:.4g} 1/s"
                f"{why} {eq} for m = {plant.mass:g} kg, b = {plant.damping:g} N*s/m, "
                f"k = {plant.stiffness:g} N/m, Kp = {params.kp:g}, Kv = {params.kv:g} N*s/m",
                path="ki",
            )
        ]

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime and suturing work."""
        raise SkillNotAvailable(self.name)
