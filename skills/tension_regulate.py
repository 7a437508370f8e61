"""``tension-regulate``: secure a knot by applying a regulated tension (chapter 7).

Hybrid force/position control (7.11-7.20): explicit PI force control with
active damping (7.22) along the securing direction of the throw (7.1-7.3,
opposite for the two throws of a square knot), with the tension estimated
from the base force/torque sensor (7.6-7.10) and an optional ramped
("modified") force reference (Fig. 7.29). The dry-run checks the tension
against the scene's limit and the gains against the Routh bounds (7.29, 7.33,
and 7.41, 7.43 when the scene declares a measurement delay).

Running: the pulling direction comes from the declared entry and exit points
(:func:`suture_engine.suture.knot.securing_directions`): the stitcher holds
the loop end, any other tool the post end. By default the state is assumed to
start with the strand slack, as the experiments of 7.5.2 do: the base sensor is
tared on the step's first tick, which absorbs the static frame's weight and the
sensor's bias. After a placement the strand is already taut, and a tare there
would zero the tension already in it; ``tare: run`` tares on the run's first
tick instead (the robots at rest, the thread slack), and the gravity model
carries the estimate across the change of pose since.
The tip is held on the line through its starting position; the force loop runs
at half the control rate (500 Hz at 1 kHz, as 7.5.1). The force command is
saturated at the scene's tension limit (or twice the desired tension without a
scene). The skill succeeds once the estimated tension has stayed within ``tolerance``
(5 % by default) of the desired value for ``hold_time``; it fails if the estimate exceeds the
tension limit or the tension is not reached within ``timeout``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillNotAvailable, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Damping, Duration, Force, Length, Unit

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
    site: PointRef | None = None
    """The knot site named in the scene (``knot_<k>``): its stitch's ``entry_<k>`` and
    ``exit_<k>`` give the securing direction. Default: the declared ``entry`` and ``exit``."""
    kp: float = Field(default=0.2, ge=0.0, le=1e3)
    """Proportional force gain Kp [-] (7.22)."""
    ki: Annotated[float, Unit("1/s")] = Field(default=0.3, gt=0.0, le=1e4)
    """Integral force gain Ki [1/s] (7.22)."""
    kv: Damping = Field(default=2000.0, ge=0.0, le=1e5)
    """Active damping gain Kv [N*s/m] (7.30)."""
    ramp: bool = True
    """Use the modified (ramped) force reference of Fig. 7.29."""
    ramp_lead: Force = Field(default=5.0, gt=0.0)
    """How far the ramped reference leads the measured tension [N] (Fig. 7.29: 5 N). It
    bounds the force error, and so the integral's wind-up, while the strand is slack; a
    lead above the desired tension leaves the reference at that tension from the start."""
    tolerance: float = Field(default=0.05, gt=0.0, le=0.5)
    """Relative band around the desired tension that counts as reached [-]. The joints'
    static friction limits how finely the tip force can be set: on the bench, with
    ``stiction``, the regulation stopped 0.07-0.15 N above 1.5 N on three of four seeds."""
    hold_time: Duration = Field(default=2.0, gt=0.0, le=60.0)
    """How long the tension is held once reached [s]."""
    timeout: Duration = Field(default=30.0, gt=0.0, le=600.0)
    """Longest time to reach and hold the tension [s]."""
    stiction: bool = False
    """Compensate the static friction of the joints at rest while the estimate is outside
    the ``tolerance`` band, in the sense that moves the tip to correct it (see
    :class:`suture_engine.control.hybrid_force.HybridForcePositionController`). Without
    it the joints' static friction can hold the tension about 1 N from the desired one
    until the integral has crossed it."""
    tare: Literal["step", "run"] = "step"
    """Where the base sensor is tared: on the step's first tick (``step``: the strand is
    slack there) or on the run's first tick (``run``: the strand may already be taut when
    the step starts, e.g. after ``place-knot``)."""
    max_travel: Length | None = Field(default=None, gt=0.0)
    """Longest pull [m]: the skill fails once the tip has moved this far along the pulling
    direction from where it started (a strand that keeps giving is slipping through the
    knot or the grip, not being secured). None: no bound."""


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

    CUTOFF_HZ: ClassVar[float] = 100.0
    """Low-pass cut-off of the tension estimate [Hz]."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._ctrl: Any = None
        self._est: Any = None
        self._t0 = 0.0
        self._inside_since: float | None = None
        self._limit = math.inf
        self._peak = 0.0
        self._last = 0.0
        self._error = ""
        self._tip0: Any = None
        self._travel = 0.0

    def start(self, ctx: Any) -> None:
        """Set up the direction rule, the tension estimator and the hybrid controller.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        import numpy as np

        from skills.place_knot import wound_points
        from suture_engine.control.hybrid_force import (
            ExplicitForceController,
            HybridForcePositionController,
            ModifiedForceReference,
        )
        from suture_engine.robot import endobot
        from suture_engine.suture.knot import securing_directions
        from suture_engine.suture.tension import mounted_estimator

        p = self.params
        assert isinstance(p, TensionRegulateParams)
        self._robot = ctx.robot(p.robot)
        self._t0 = ctx.t0
        self._inside_since = None
        self._peak = 0.0
        start = ctx.start.robots[self._robot]
        q0 = np.asarray(start.q, dtype=float)
        geo = ctx.start.scene
        self._error = ""
        entry, exit = geo.entry_point, geo.exit_point
        try:
            if p.site is not None:
                _, entry, exit = wound_points(ctx, p.site)
            rule = securing_directions(entry, exit, p.throw, normal=geo.tissue_normal)
        except (KeyError, ValueError) as exc:  # no entry or exit point: no direction
            self._error = f"no securing direction (7.1-7.3): {exc}"
            self._ctrl = None
            return
        tool = ""
        if ctx.scene is not None and self._robot in ctx.scene.robots:
            tool = str(ctx.scene.robots[self._robot].tool)
        loop_end = tool == "stitcher" if tool else "stitcher" in p.robot
        e_world = rule.loop_end if loop_end else rule.post_end
        base = ctx.base_poses.get(self._robot)
        rest = start
        if p.tare == "run":
            if ctx.rest is None or self._robot not in ctx.rest.robots:
                self._error = "tare: run needs the run's first observation, and there is none"
                self._ctrl = None
                return
            rest = ctx.rest.robots[self._robot]
        self._est, prm = mounted_estimator(
            None if base is None else base[1],
            e_world,
            rest.base_wrench,
            rest.q,
            ctx.dt,
            self.CUTOFF_HZ,
        )
        e_base = self._est.direction
        self._limit = float(ctx.scene.tension_limit) if ctx.scene is not None else 2.0 * p.tension
        force_dt = 2.0 * ctx.dt if ctx.dt < 1.5e-3 else ctx.dt
        force = ExplicitForceController(p.kp, p.ki, p.kv, force_dt, limit=self._limit)
        ramp = ModifiedForceReference(p.tension, p.ramp_lead, dt=force_dt) if p.ramp else None
        self._tip0 = endobot.forward_kinematics(q0).position
        self._travel = 0.0
        self._ctrl = HybridForcePositionController(
            e_base,
            self._tip0,
            force,
            prm,
            dt=ctx.dt,
            roll=float(q0[2]),
            reference=ramp,
            friction=[j.friction for j in prm.joints],
            stiction_band=p.tolerance * p.tension if p.stiction else None,
        )

    def step(self, ctx: Any, obs: Any) -> Any:
        """Regulate the tension (7.22) along the securing direction (7.1-7.3).

        Args:
            ctx: the skill context.
            obs: this tick's :class:`suture_engine.runtime.observation.Observation`.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        from suture_engine.runtime.observation import (
            Command,
            RobotCommand,
            SkillStatus,
            StepResult,
        )

        p = self.params
        assert isinstance(p, TensionRegulateParams)
        if ctx is None or obs is None:
            raise SkillNotAvailable(self.name, "step needs the runtime's context and observation")
        if self._ctrl is None and not self._error:
            self.start(ctx)
        if self._ctrl is None:
            hold = Command({self._robot: RobotCommand.position(obs.robots[self._robot].q)})
            return StepResult(hold, SkillStatus.FAILURE, self._error)
        ro = obs.robots[self._robot]
        est = self._est.update(ro.base_wrench, ro.q)
        tension = est.tension
        self._last = tension
        self._peak = max(self._peak, tension)
        out = self._ctrl.update(ro.q, ro.qd, tension, p.tension)
        command = Command({self._robot: RobotCommand.torque(out.torque)})
        t = obs.t - self._t0
        if tension > self._limit:
            return StepResult(
                command,
                SkillStatus.FAILURE,
                f"estimated tension {tension:.2f} N above the limit {self._limit:.2f} N",
            )
        if p.max_travel is not None:
            from suture_engine.robot import endobot

            tip = endobot.forward_kinematics(ro.q).position
            self._travel = float((tip - self._tip0) @ self._est.direction)
            if self._travel > p.max_travel:
                return StepResult(
                    command,
                    SkillStatus.FAILURE,
                    f"pulled {self._travel * 1e3:.1f} mm, past max_travel "
                    f"{p.max_travel * 1e3:.1f} mm, at {tension:.2f} N",
                )
        if abs(tension - p.tension) <= p.tolerance * p.tension:
            if self._inside_since is None:
                self._inside_since = t
            if t - self._inside_since >= p.hold_time - 0.5 * ctx.dt:
                return StepResult(command, SkillStatus.SUCCESS)
        else:
            self._inside_since = None
        if t >= p.timeout:
            return StepResult(
                command,
                SkillStatus.FAILURE,
                f"tension {tension:.2f} N not held at {p.tension:.2f} N within {p.timeout:g} s",
            )
        return StepResult(command)

    def metrics(self) -> dict[str, float]:
        """Estimated peak and last tension of this run so far [N]."""
        return {"peak_tension_N": self._peak, "final_tension_N": self._last}
