"""``pass-needle``: make a stitch and pull the suture through (4.1-4.4).

The needle enters at ``entry`` and leaves at ``exit``; the suture is then
pulled out to the desired length l_d with the tension kept under f_max by the
extension-rate bound (4.10-4.11). The suture length is tracked from the needle
position only (4.1, 4.3-4.4), by
:class:`suture_engine.suture.length.SutureLengthEstimator`.

Phases, each a minimum-jerk path through the inverse kinematics (3.14-3.17):

1. ``approach``: straight to the entry point p_a, the needle held in its jaw;
2. ``bite``: along the circular arc from p_a to p_b through the tissue, in the
   plane of the entry-exit line and the tissue normal, ``bite_depth`` below
   the surface at its middle;
3. ``pass`` (stitcher only): the other jaw closes on the needle, then the first
   opens (the shuttle needle changes jaws);
4. ``pull``: along the tissue normal away from p_b with peak tip speed
   ``min(speed, l'_max)``, l'_max = (f_max - F_s)/F_v (4.11), until the
   estimated length L (exit point to needle) reaches l_d (4.7-4.9).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Force, Length, Speed

if TYPE_CHECKING:
    from suture_engine.validation.problem import Problem

__all__ = ["PassNeedle", "PassNeedleParams", "bite_arc"]


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
    """l_d, the suture length from the exit point to the needle after pulling (4.7-4.9) [m]."""
    max_tension: Force | None = Field(default=None, gt=0.0)
    """f_max, the tension bound while pulling [N]; at most the scene's limit."""
    speed: Speed = Field(default=0.01, gt=0.0, le=0.2)
    """Pulling speed bound [m/s]."""


def bite_arc(entry: Any, exit: Any, normal: Any, depth: float) -> tuple[Any, float]:
    """The needle's circular path through the tissue from ``entry`` to ``exit``.

    The arc lies in the plane of the chord and the normal, ``depth`` below the
    chord's middle. With chord c and sagitta h: radius R = (c^2/4 + h^2)/(2h),
    half-angle alpha = 2 atan(2h/c), length 2 R alpha.

    Args:
        entry: p_a [m].
        exit: p_b [m].
        normal: tissue normal (out of the tissue).
        depth: h [m], > 0.

    Returns:
        (``s -> point`` for s in [0, 1], arc length [m]).
    """
    import math

    import numpy as np

    pa = np.asarray(entry, dtype=float)
    pb = np.asarray(exit, dtype=float)
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    chord = pb - pa
    c = float(np.linalg.norm(chord))
    if c < 1e-9 or depth <= 0.0:
        raise ValueError("the bite needs distinct entry and exit points and a positive depth")
    u = chord / c
    radius = (c * c / 4.0 + depth * depth) / (2.0 * depth)
    alpha = 2.0 * math.atan2(2.0 * depth, c)
    centre = 0.5 * (pa + pb) + (radius - depth) * n

    def point(s: float) -> Any:
        phi = -alpha + 2.0 * alpha * s
        return centre + radius * (math.sin(phi) * u - math.cos(phi) * n)

    return point, 2.0 * radius * alpha


class PassNeedle(Skill):
    """Stitch from ``entry`` to ``exit`` and pull the suture out to ``pull_length``.

    Fails when a path leaves the joint limits, when ``max_tension`` is not above
    the static drag F_s (4.11), when the tip misses a phase's goal by more than
    :attr:`TOLERANCE` [m] :attr:`SETTLE_S` [s] after its path, when a stitcher jaw
    does not respond within :attr:`JAW_S` [s], or when the estimated length has
    not reached l_d at the end of the pull.
    """

    name: ClassVar[str] = "pass-needle"
    Params: ClassVar[type[SkillParams]] = PassNeedleParams
    tools: ClassVar[tuple[str, ...] | None] = (
        "stitcher",
        "grasper",
        "hook-grasper",
        "bent-tip-grasper",
    )

    STATIC_DRAG: ClassVar[float] = 0.2
    """F_s, static suture-tissue drag [N] (4.5); assumed, the thesis gives no value."""
    VISCOUS_DRAG: ClassVar[float] = 50.0
    """F_v, viscous suture-tissue drag [N*s/m] (4.5); assumed."""
    DEFAULT_MAX_TENSION: ClassVar[float] = 3.0
    """f_max when neither the step nor the scene gives one [N]."""
    TOLERANCE: ClassVar[float] = 3e-3
    """Tip position tolerance at the end of the approach and the bite [m]: both end on
    the tissue surface, which pushes back on the tool."""
    LENGTH_TOLERANCE: ClassVar[float] = 0.5e-3
    """How close to l_d the estimated length must come [m]."""
    SETTLE_S: ClassVar[float] = 1.0
    """Time after a path to reach its goal [s]."""
    JAW_S: ClassVar[float] = 0.5
    """Time for a stitcher jaw to respond [s]."""

    @classmethod
    def check(cls, params: SkillParams, scene: Any) -> list[Problem]:
        """f_max above the static drag F_s (4.11) and at most the scene's tension limit.

        Args:
            params: validated parameters (SI units).
            scene: the procedure's scene, or None.

        Returns:
            The problems found, located at ``max_tension``.
        """
        from suture_engine.validation.problem import Problem

        assert isinstance(params, PassNeedleParams)
        f_max = params.max_tension
        if f_max is None:
            return []
        problems = []
        if f_max <= cls.STATIC_DRAG:
            problems.append(
                Problem(
                    "tension-bound-too-low",
                    f"max_tension {f_max:g} N is not above the static suture drag "
                    f"F_s = {cls.STATIC_DRAG:g} N: no pulling speed keeps the tension under it "
                    "(4.11)",
                    path="max_tension",
                )
            )
        limit = getattr(scene, "tension_limit", None) if scene is not None else None
        if limit is not None and f_max > float(limit) + 1e-12:
            problems.append(
                Problem(
                    "tension-above-limit",
                    f"max_tension {f_max:g} N is above the scene's tension limit "
                    f"{float(limit):.4g} N",
                    path="max_tension",
                )
            )
        return problems

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._base: Any = None
        self._failure = ""
        self._phase = "approach"
        self._t_phase = 0.0
        self._paths: dict[str, Any] = {}
        self._goals: dict[str, Any] = {}
        self._holder = 1
        self._stitcher = False
        self._roll = 0.0
        self._q_hold: Any = None
        self.estimator: Any = None
        self.rate_bound = 0.0
        self.arc_length = 0.0
        self._pa: Any = None
        self._pb: Any = None
        self._n: Any = None

    # ----------------------------------------------------------------- planning
    def _points(self, ctx: Any) -> None:
        import numpy as np

        p = self.params
        assert isinstance(p, PassNeedleParams)
        points = ctx.scene.tissue.points if ctx.scene is not None else {}
        for name in (p.entry, p.exit):
            if name not in points:
                raise KeyError(f"no tissue point named {name!r}; known: {sorted(points)}")
        self._pa = np.array(points[p.entry], dtype=float)
        self._pb = np.array(points[p.exit], dtype=float)
        normal = np.asarray(ctx.start.scene.tissue_normal, dtype=float)
        if ctx.scene is not None:
            normal = np.asarray(ctx.scene.tissue.normal, dtype=float)
        self._n = normal / np.linalg.norm(normal)

    def _line(self, a: Any, b: Any, speed: float) -> Any:
        import numpy as np

        from skills.tool_path import ToolPath, duration_for, ik_world

        roll = self._roll
        return ToolPath(
            lambda s: ik_world(a + s * (b - a), roll, self._base),
            duration_for(float(np.linalg.norm(b - a)), speed),
        )

    def start(self, ctx: Any) -> None:
        """Plan the approach, the bite and the pull; set up the length estimator.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        import numpy as np

        from skills.tool_path import ToolPath, duration_for, ik_world, joint_box, tip_world
        from suture_engine.suture.length import SutureLengthEstimator, max_extension_rate

        p = self.params
        assert isinstance(p, PassNeedleParams)
        self._robot = ctx.robot(p.robot)
        self._base = ctx.base_poses.get(self._robot)
        robot = ctx.start.robots[self._robot]
        self._roll = float(robot.q[2])
        self._stitcher = robot.tool.kind == "stitcher"
        self._holder = 2 if (robot.tool.jaw2_closed and not robot.tool.jaw_closed) else 1
        self._phase = "approach"
        self._t_phase = ctx.t0
        self._failure = ""
        self._points(ctx)
        f_max = p.max_tension
        if f_max is None:
            limit = getattr(ctx.scene, "tension_limit", None) if ctx.scene is not None else None
            f_max = float(limit) if limit is not None else self.DEFAULT_MAX_TENSION
        try:
            self.rate_bound = max_extension_rate(f_max, self.STATIC_DRAG, self.VISCOUS_DRAG)
        except Exception as exc:  # TensionBoundTooLow: reported as the skill's failure
            self._failure = str(exc)
            self.rate_bound = 0.0
        tip = tip_world(robot.q, self._base)
        arc, self.arc_length = bite_arc(self._pa, self._pb, self._n, p.bite_depth)
        pull_end = self._pb + p.pull_length * self._n
        pull_speed = min(p.speed, self.rate_bound) if self.rate_bound > 0 else p.speed
        roll = self._roll
        self._paths = {
            "approach": self._line(tip, self._pa, p.speed),
            "bite": ToolPath(
                lambda s: ik_world(arc(s), roll, self._base),
                duration_for(self.arc_length, p.speed),
            ),
            "pull": self._line(self._pb, pull_end, pull_speed),
        }
        self._goals = {"approach": self._pa, "bite": self._pb, "pull": pull_end}
        self.estimator = SutureLengthEstimator(self._pb, 0.0)
        box = joint_box(ctx, self._robot)
        for name, path in self._paths.items():
            why = path.first_violation(box)
            if why and not self._failure:
                self._failure = f"{name}: {why}"
        self._q_hold = np.array(robot.q)

    # ----------------------------------------------------------------- ticking
    def _jaws(self, holder_closed: bool, receiver_closed: bool | None) -> Any:
        from suture_engine.runtime.observation import ToolCommand

        if not self._stitcher:
            return ToolCommand(jaw_closed=holder_closed)
        receiver = None if receiver_closed is None else receiver_closed
        if self._holder == 1:
            return ToolCommand(jaw_closed=holder_closed, jaw2_closed=receiver)
        return ToolCommand(jaw2_closed=holder_closed, jaw_closed=receiver)

    def _next(self, phase: str, t: float) -> None:
        self._phase = phase
        self._t_phase = t

    def step(self, ctx: Any, obs: Any) -> Any:
        """Run the current phase; success once the estimated length reaches l_d.

        Args:
            ctx: the skill context.
            obs: this tick's observation.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        import numpy as np

        from skills.tool_path import hold_command, tip_world
        from suture_engine.runtime.observation import (
            Command,
            RobotCommand,
            SkillStatus,
            StepResult,
        )

        p = self.params
        assert isinstance(p, PassNeedleParams)
        robot = obs.robots[self._robot]
        if self._failure:
            return StepResult(
                hold_command(self._robot, robot.q), SkillStatus.FAILURE, self._failure
            )
        t = obs.t - self._t_phase
        tip = tip_world(robot.q, self._base)
        if self._phase == "pass":
            tool = robot.tool
            receiver_closed = tool.jaw2_closed if self._holder == 1 else tool.jaw_closed
            holder_closed = tool.jaw_closed if self._holder == 1 else tool.jaw2_closed
            if not receiver_closed:
                cmd = hold_command(self._robot, self._q_hold, self._jaws(True, True))
                if t >= self.JAW_S:
                    return StepResult(cmd, SkillStatus.FAILURE, "the receiving jaw did not close")
                return StepResult(cmd)
            cmd = hold_command(self._robot, self._q_hold, self._jaws(False, True))
            if not holder_closed:
                self._holder = 2 if self._holder == 1 else 1
                self._next("pull", obs.t)
                self.estimator.update(obs.t, tip)
            elif t >= self.JAW_S:
                return StepResult(cmd, SkillStatus.FAILURE, "the giving jaw did not open")
            return StepResult(cmd)
        path = self._paths[self._phase]
        q, qd, done = path.sample(t)
        tool = self._jaws(True, None if self._phase != "pull" else False)
        cmd = Command({self._robot: RobotCommand.position(q, qd, tool)})
        if self._phase == "pull":
            sample = self.estimator.update(obs.t, tip)
            if sample.length >= p.pull_length - self.LENGTH_TOLERANCE:
                return StepResult(cmd, SkillStatus.SUCCESS)
            if done and t >= path.duration + self.SETTLE_S:
                return StepResult(
                    cmd,
                    SkillStatus.FAILURE,
                    f"suture length {sample.length * 1e3:.1f} mm, "
                    f"wanted {p.pull_length * 1e3:.1f} mm",
                )
            return StepResult(cmd)
        if not done:
            return StepResult(cmd)
        err = float(np.linalg.norm(tip - self._goals[self._phase]))
        if err <= self.TOLERANCE:
            if self._phase == "approach":
                self._next("bite", obs.t)
            elif self._stitcher:
                self._q_hold = np.array(q)
                self._next("pass", obs.t)
            else:
                self._next("pull", obs.t)
                self.estimator.update(obs.t, tip)
        elif t >= path.duration + self.SETTLE_S:
            return StepResult(
                cmd, SkillStatus.FAILURE, f"{self._phase}: tip {err * 1e3:.2f} mm from its goal"
            )
        return StepResult(cmd)

    def metrics(self) -> dict[str, float]:
        """Stitch figures: estimated suture length [m], peak extension rate and its bound [m/s]."""
        if self.estimator is None:
            return {}
        return {
            "stitch_length_estimate_m": float(self.estimator.length),
            "stitch_peak_extension_rate_m_s": float(self.estimator.peak_rate),
            "stitch_extension_rate_bound_m_s": float(self.rate_bound),
            "stitch_bite_arc_m": float(self.arc_length),
        }
