"""``move-constrained``: tool motion under a virtual fixture (chapter 6, 7.3.2).

The fixture geometry is given in the robot's base frame, whose origin is the
remote centre of motion (the spherical joint at the incision): a line
(6.28-6.32), a circle in a plane z = z0 (6.43-6.46), a plane, or a cone.
"""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING, Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Angle, Duration, Force, Length, Position, Speed

if TYPE_CHECKING:
    from suture_engine.validation.problem import Problem

__all__ = ["MoveConstrained", "MoveConstrainedParams"]


@functools.cache
def _step_imports() -> tuple[Any, ...]:
    """The names step() uses, imported once (lazily: validation never imports numpy)."""
    import numpy as np

    from suture_engine.control.shared import (
        TaskSpaceGains,
        TaskSpaceOutput,
        constraint_force,
        joint_space_shared_control,
        task_space_shared_control,
        task_vector,
    )
    from suture_engine.robot import endobot
    from suture_engine.runtime.observation import (
        Command,
        RobotCommand,
        SkillStatus,
        StepResult,
    )

    return (
        np,
        TaskSpaceGains,
        TaskSpaceOutput,
        constraint_force,
        joint_space_shared_control,
        task_space_shared_control,
        task_vector,
        endobot,
        Command,
        RobotCommand,
        SkillStatus,
        StepResult,
    )


@functools.cache
def _autonomous_imports() -> tuple[Any, ...]:
    """The names autonomous step() uses, imported once (lazily, as _step_imports)."""
    import numpy as np

    from suture_engine.robot import kinematics
    from suture_engine.runtime.observation import (
        Command,
        RobotCommand,
        SkillStatus,
        StepResult,
    )

    return np, kinematics, Command, RobotCommand, SkillStatus, StepResult


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
    shared_space: Literal["task", "joint"] | None = None
    """Shared-mode law: ``task`` (6.24) or ``joint`` (the diffeomorphism d = [c; f],
    6.33-6.37; line, circle and plane); ``None`` takes the class default
    ``SHARED_SPACE``."""


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

    STIFFNESS: ClassVar[float] = 1000.0
    """Virtual spring of shared mode, Kp [N/m] (Table 6.2's desired stiffness)."""
    DAMPING: ClassVar[float] = 30.0
    """Virtual damper of shared mode, Kv [N*s/m]."""
    TOLERANCE: ClassVar[float] = 0.5e-3
    """Arrival tolerance of the tool tip in autonomous mode [m]."""
    SETTLE_S: ClassVar[float] = 1.0
    """Time allowed after the reference's end to reach the tolerance [s], extended by
    the time the extension-rate bound (4.11) was active."""
    SHARED_SPACE: ClassVar[str] = "task"
    """Shared-mode law: ``"task"`` (6.24, Kp = STIFFNESS, Kv = DAMPING) or ``"joint"``
    (6.35-6.37 with JOINT_KP, JOINT_KD; line, circle and plane only)."""
    JOINT_KP: ClassVar[tuple[float, float, float, float]] = (60.0, 60.0, 0.0, 1500.0)
    """Joint stiffness of joint-space shared control [N*m/rad, N*m/rad, N*m/rad, N/m]."""
    JOINT_KD: ClassVar[tuple[float, float, float, float]] = (1.0, 1.0, 0.0, 40.0)
    """Joint damping of joint-space shared control [N*m*s/rad, ..., N*s/m]."""
    CAPTURE_S: ClassVar[float] = 0.5
    """Shared mode: the first seconds of the state, while the fixture pulls the tool onto
    it, are left out of the metrics [s]."""
    MIN_DEVIATION: ClassVar[float] = 1e-5
    """Smallest peak deviation [m] from which a stiffness is reported; below it the
    ratio max|Fc| / max|e| measures model noise, not the virtual spring."""
    MAX_QP_FAILURES: ClassVar[int] = 10
    """Consecutive unsolved ticks (command held) after which the skill fails."""
    SUTURE_STATIC_FRICTION: ClassVar[float] = 0.3
    """Default suture-tissue static friction F_s [N] for (4.11) when the procedure's
    params give no ``suture_static_friction``. An assumption: the thesis gives no value."""
    SUTURE_VISCOUS_COEFFICIENT: ClassVar[float] = 100.0
    """Default suture-tissue viscous coefficient F_v [N*s/m] for (4.11) when the
    params give no ``suture_viscous_coefficient``. An assumption: the thesis gives none."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._fixture: Any = None
        self._qp: Any = None
        self._base: Any = None
        self._gravity_params: Any = None
        self._t0 = 0.0
        self._q_ref: Any = None
        self._f0: Any = None
        self._f_goal: Any = None
        self._x_goal: Any = None
        self._duration = 0.0
        self._throttled = 0.0
        self._exit_base: Any = None
        self._ldot_max: float | None = None
        self._peak_e: Any = None
        self._c_zero: Any = None
        self._df: Any = None
        self._peak_f: Any = None
        self._jac: Any = None
        self._next_ref: tuple[float, Any] | None = None
        self._f0_list: list[float] = []
        self._df_list: list[float] = []
        self._c_zero_list: list[float] = []
        self._np: Any = None
        self._ref_kernel: Any = None
        self._ref_args: tuple[Any, ...] = ()
        self._track_kernel: Any = None
        self._track_args: tuple[Any, ...] = ()
        self._final_ref: tuple[Any, Any] | None = None
        self.last_qp: Any = None
        """The last tick's :class:`~suture_engine.control.constrained_qp.QPResult` (traces)."""

    def _build_fixture(self) -> Any:
        import numpy as np

        from suture_engine.control.fixtures import Circle, Cone, Line, Plane

        p = self.params
        assert isinstance(p, MoveConstrainedParams)
        point = np.array(p.point, dtype=float)
        direction = np.array(p.direction, dtype=float)
        if p.fixture == "line":
            return Line(point=point, direction=direction)
        if p.fixture == "circle":
            return Circle(center=point, radius=float(p.radius or 0.0), normal=direction)
        if p.fixture == "plane":
            return Plane(point=point, normal=direction)
        return Cone(apex=point, axis=direction, half_angle=float(p.half_angle or 0.0))

    def start(self, ctx: Any) -> None:
        """Build the fixture and, in autonomous mode, the persistent QP and the reference.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.

        Raises:
            FixtureError: the fixture geometry is degenerate.
            KeyError: an unknown tissue point or role.
        """
        import dataclasses

        import numpy as np

        from suture_engine.control.constrained_qp import (
            ConstrainedQP,
            JointLimits,
            extension_rate_bound,
        )
        from suture_engine.control.shared import task_vector
        from suture_engine.robot.params import E1
        from suture_engine.runtime.trajectory import world_to_base

        p = self.params
        assert isinstance(p, MoveConstrainedParams)
        self._robot = ctx.robot(p.robot)
        self._base = ctx.base_poses.get(self._robot)
        self._fixture = self._build_fixture()
        self._t0 = ctx.t0
        self._next_ref = None
        self._final_ref = None
        self._ref_kernel = None
        self._track_kernel = None
        q0 = np.array(ctx.start.robots[self._robot].q, dtype=float)
        # Gravity in the base frame, R_base^T g_world; without a pose, E1's own mounting.
        self._gravity_params = E1
        if self._base is not None:
            rot = np.asarray(self._base[1], dtype=float).reshape(3, 3)
            g_base = rot.T @ np.array([0.0, 0.0, -9.81])
            gravity = (float(g_base[0]), float(g_base[1]), float(g_base[2]))
            self._gravity_params = dataclasses.replace(E1, gravity=gravity)
        self._peak_e = np.zeros(self._fixture.rows)
        self._peak_f = np.zeros(self._fixture.rows)
        self._c_zero = np.zeros(self._fixture.rows)
        if p.mode == "shared":
            return
        has_rate = p.max_tension is not None
        limits = JointLimits.from_params(horizon=float(ctx.dt))
        self._qp = ConstrainedQP([self._fixture], limits=limits, extension_rate=has_rate)
        if has_rate:
            fs = float(ctx.params.get("suture_static_friction", self.SUTURE_STATIC_FRICTION))
            fv = float(
                ctx.params.get("suture_viscous_coefficient", self.SUTURE_VISCOUS_COEFFICIENT)
            )
            self._ldot_max = extension_rate_bound(float(p.max_tension or 0.0), fs, fv)
            exit_world = ctx.start.scene.exit_point
            self._exit_base = world_to_base(exit_world, self._base)
        self._q_ref = q0.copy()
        self._jac = np.zeros((4, 4))  # the QP's Jacobian, refilled in place every tick
        x0 = task_vector(q0)
        target = self._target_world(ctx)
        goal = np.r_[world_to_base(np.asarray(target), self._base), x0[3]]
        fx = self._fixture
        if fx.kind == "eq":
            self._x_goal = fx.project(goal)
            self._f0 = fx.free(x0)
            f_goal = fx.free(self._x_goal)
            if p.fixture == "circle":  # the shorter way round (6.49)
                f_goal[0] = self._f0[0] + (f_goal[0] - self._f0[0] + np.pi) % (2 * np.pi) - np.pi
            self._f_goal = f_goal
            self._df = f_goal - self._f0
            self._f0_list = self._f0.tolist()
            self._df_list = self._df.tolist()
            self._c_zero_list = self._c_zero.tolist()
            self._np = np
            affine = fx.affine_inverse()
            if affine is not None:
                from suture_engine.control._move_kernels import JIT

                self._ref_kernel = JIT[0]
                self._ref_args = (self._f0, self._df, self._c_zero, affine[0], affine[1])
        else:
            self._x_goal = goal
        rows = fx.affine()
        if rows is not None:  # a line or a plane: C(x) = Jc[:, :3] (p - p0)
            from suture_engine.control._move_kernels import JIT

            self._track_kernel = JIT[1]
            self._track_args = (rows[0], rows[1], self._peak_e)
        self._duration = max(0.1, 1.5 * float(np.linalg.norm(self._x_goal[:3] - x0[:3])) / p.speed)

    def _target_world(self, ctx: Any) -> tuple[float, float, float]:
        p = self.params
        assert isinstance(p, MoveConstrainedParams)
        if p.target is None:
            raise KeyError("autonomous move-constrained needs a target")
        if isinstance(p.target, str):
            points = ctx.scene.tissue.points if ctx.scene is not None else {}
            if p.target not in points:
                raise KeyError(f"no tissue point named {p.target!r}; known: {sorted(points)}")
            pt = points[p.target]
            return (float(pt[0]), float(pt[1]), float(pt[2]))
        return (float(p.target[0]), float(p.target[1]), float(p.target[2]))

    def _at(self, tt: float) -> Any:
        """Task reference at time tt [s] since start (smoothstep in f)."""
        s = min(max(tt / self._duration, 0.0), 1.0)
        sigma = s * s * (3.0 - 2.0 * s)
        if self._fixture.kind == "eq":
            # f = f0 + sigma (f_goal - f0) on Python floats (numpy's element-wise
            # operations, the same numbers), stacked under c = 0 in one array.
            f = [a + sigma * b for a, b in zip(self._f0_list, self._df_list, strict=True)]
            return self._fixture.inverse_stacked(self._np.array(self._c_zero_list + f))
        return self._x_goal

    def _reference(self, t: float) -> tuple[Any, Any]:
        """Task reference and its velocity at time t [s] since start (smoothstep in f).

        The velocity is the forward difference over h = 1 ms. On a line or a plane (an
        affine inverse map) one compiled call gives both (:mod:`suture_engine.control.
        _move_kernels`, to 1e-12 of :meth:`_at`'s numpy). Otherwise ``_at(t + h)`` is
        kept: at 1 kHz it is the next tick's ``_at(t)`` (reused only when the times are
        equal to the bit). Once both times are past the duration the smoothstep is
        clamped, so the reference is constant and its velocity exactly zero: computed once.
        """
        h = 1e-3
        final = self._final_ref
        if final is not None:
            return final
        kernel = self._ref_kernel
        if kernel is not None:  # a line or a plane: both points and v in one compiled call
            np = self._np
            x, v = np.empty(4), np.empty(4)
            kernel(t, h, self._duration, *self._ref_args, x, v)
            if t >= self._duration:
                self._final_ref = (x, v)
            return x, v
        nxt = self._next_ref
        x = nxt[1] if nxt is not None and nxt[0] == t else self._at(t)
        th = t + h
        x_next = self._at(th)
        self._next_ref = (th, x_next)
        v = (x_next - x) / h
        if t >= self._duration:  # both clamped: x_next == x, v == 0 for every later t
            self._final_ref = (x, v)
        return x, v

    def step(self, ctx: Any, obs: Any) -> Any:
        """One tick: the QP's joint velocities (autonomous) or the shared-control torques.

        Autonomous: the persistent QP (:class:`~suture_engine.control.constrained_qp.
        ConstrainedQP`) is evaluated at the skill's joint reference, which integrates its
        solutions, and the reference is sent as a position set point with the velocity
        feed-forward. Shared: task-space shared control (6.24) with Kp = ``STIFFNESS``
        and Kv = ``DAMPING``, or with ``SHARED_SPACE = "joint"`` joint-space shared
        control (6.35-6.37), plus gravity compensation, as joint torques.

        Args:
            ctx: the skill context.
            obs: this tick's :class:`suture_engine.runtime.observation.Observation`.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        p = self.params
        assert isinstance(p, MoveConstrainedParams)
        ro = obs.robots[self._robot]
        t = obs.t - self._t0
        if p.mode == "shared":
            return self._shared_step(p, ro, t)
        np, kin, Command, RobotCommand, SkillStatus, StepResult = _autonomous_imports()
        q_ref = self._q_ref
        x_ref, jac = kin.task_vector_and_jacobian(q_ref, self._jac)
        x_target, v_target = self._reference(t)
        res = self._qp.solve(
            q_ref,
            x_ref,
            jac,
            v_target=v_target,
            x_target=x_target,
            exit_point=self._exit_base,
            extension_rate_max=self._ldot_max,
        )
        self.last_qp = res
        if "extension_rate" in res.active:
            self._throttled += ctx.dt  # the tension bound slows the motion on purpose
        failing = self._qp.consecutive_failures >= self.MAX_QP_FAILURES
        track = self._track_kernel
        if track is not None:
            # a line or a plane: q_ref's Euler step (numpy's, to the bit), the command's
            # copy and the deviation's peak in one compiled call
            x_meas = kin.task_vector(ro.q)
            q_cmd = np.empty(4)
            track(q_ref, res.qdot, ctx.dt, q_cmd, x_meas, *self._track_args, not failing)
        else:
            q_ref += res.qdot * ctx.dt
            q_cmd = q_ref.copy()
        # Fresh arrays, handed over: q_cmd here, res.qdot a copy the QP made.
        command = Command({self._robot: RobotCommand.trusted_position(q_cmd, res.qdot)})
        if failing:
            return StepResult(
                command,
                SkillStatus.FAILURE,
                f"QP not solved for {self._qp.consecutive_failures} ticks ({res.status})",
            )
        if track is None:
            x_meas = kin.task_vector(ro.q)
            e = self._fixture.value(x_meas)
            np.maximum(self._peak_e, np.abs(e), out=self._peak_e)
        if t < self._duration:
            return StepResult.running(command)
        error = float(np.linalg.norm(x_meas[:3] - self._x_goal[:3]))
        if error <= self.TOLERANCE:
            return StepResult(command, SkillStatus.SUCCESS)
        if t >= self._duration + self.SETTLE_S + self._throttled:
            return StepResult(
                command,
                SkillStatus.FAILURE,
                f"tool tip {error * 1e3:.2f} mm from the target after {t:.2f} s",
            )
        return StepResult(command)

    def _shared_step(self, p: MoveConstrainedParams, ro: Any, t: float) -> Any:
        """Shared mode's tick (see :meth:`step`): task- or joint-space shared control plus
        gravity compensation, as joint torques; ``t`` [s] since the step's start."""
        (
            np,
            TaskSpaceGains,
            TaskSpaceOutput,
            constraint_force,
            joint_space_shared_control,
            task_space_shared_control,
            task_vector,
            endobot,
            Command,
            RobotCommand,
            SkillStatus,
            StepResult,
        ) = _step_imports()
        grav = endobot.gravity_vector(ro.q, self._gravity_params)
        if self._space() == "joint" and self._fixture.kind == "eq":
            tau, _ = joint_space_shared_control(
                self._fixture,
                ro.q,
                ro.qd,
                np.asarray(self.JOINT_KP, dtype=float),
                np.asarray(self.JOINT_KD, dtype=float),
            )
            x_meas = task_vector(np.asarray(ro.q, dtype=float))
            out = TaskSpaceOutput(
                tau + grav,
                constraint_force(self._fixture, ro.q, tau),  # (6.53)
                self._fixture.value(x_meas),
            )
        else:
            out = task_space_shared_control(
                self._fixture,
                ro.q,
                ro.qd,
                TaskSpaceGains(self.STIFFNESS, self.DAMPING),
                gravity=grav,
            )
        if t >= self.CAPTURE_S:
            np.maximum(self._peak_e, np.abs(out.deviation), out=self._peak_e)
            np.maximum(self._peak_f, np.abs(out.constraint_force), out=self._peak_f)
        command = Command({self._robot: RobotCommand.torque(out.tau)})
        done = p.duration is not None and t >= p.duration
        return StepResult(command, SkillStatus.SUCCESS if done else SkillStatus.RUNNING)

    def metrics(self) -> dict[str, float]:
        """Chapter 6 figures of this run so far (Tables 6.2-6.4, (6.54)).

        Returns:
            ``max_deviation_m`` and, in shared mode, ``max_force_N``,
            ``constraint_stiffness_N_per_m`` (the smallest row's max|Fc| / max|e| over
            rows that deviated at least ``MIN_DEVIATION``; nan if none did; Fc is the
            commanded constraint force (6.20), or (6.53) in joint space), in task
            space ``desired_stiffness_N_per_m``, and per constraint row i (Tables
            6.2-6.4) ``row<i>_max_deviation_m``, ``row<i>_max_force_N`` and
            ``row<i>_stiffness_N_per_m`` (nan below ``MIN_DEVIATION``).
        """
        import numpy as np

        if self._peak_e is None:
            return {}
        out = {"max_deviation_m": float(np.max(self._peak_e))}
        p = self.params
        assert isinstance(p, MoveConstrainedParams)
        if p.mode == "shared":
            valid = self._peak_e >= self.MIN_DEVIATION
            with np.errstate(divide="ignore", invalid="ignore"):
                k = np.where(valid, self._peak_f / np.where(valid, self._peak_e, 1.0), np.nan)
            out["max_force_N"] = float(np.max(self._peak_f))
            out["constraint_stiffness_N_per_m"] = (
                float(np.nanmin(k)) if np.any(np.isfinite(k)) else float("nan")
            )
            if self._space() == "task" or self._fixture.kind != "eq":
                out["desired_stiffness_N_per_m"] = self.STIFFNESS
            # Tables 6.2-6.4, one row per constraint row: max|e|, max|Fc|, Ke (6.54).
            for i in range(len(self._peak_e)):
                out[f"row{i + 1}_max_deviation_m"] = float(self._peak_e[i])
                out[f"row{i + 1}_max_force_N"] = float(self._peak_f[i])
                out[f"row{i + 1}_stiffness_N_per_m"] = float(k[i])
        return out

    def _space(self) -> str:
        p = self.params
        assert isinstance(p, MoveConstrainedParams)
        return p.shared_space or self.SHARED_SPACE
