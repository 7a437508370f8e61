"""The chapter 6 shared-control experiments on the simulated EndoBot (6.3.4, 6.4.3).

A simulated operator holds the tool tip through a hand impedance that is the same in
every direction (6.3.4: "the operator was trying to move the tool in all direction
with same impedance"): the hand point slides along the fixture and circles around it,
and the force on the tip is ``F = K_h (h(t) - p) - B_h pdot`` [N], applied in PyBullet
as an external force at the tool tip, plus a roll torque about the tool axis. The
shared controller (task space, 6.24, or joint space, 6.37) holds the fixture.

Measured per constraint row (evaluation only, from the encoders and the commands):

* the deviation ``e = C(x)`` [m] and the controller's constraint force ``Fc`` [N]
  recovered from the applied torques by (6.53); Table 6.2's stiffness is
  ``max|Fc| / max|e|`` (6.54);
* independently of the controller, the operator's force along the row's unit normal
  [N]: in quasi-static equilibrium it balances the virtual spring, so
  ``max|F_op,n| / max|e|`` and the least-squares slope of F_op,n on e are a second,
  physics-side measure of the same stiffness (it includes friction and inertia).

PyBullet is imported lazily, inside :func:`run_experiment`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.control.fixtures import Circle, EqualityFixture, Line
from suture_engine.control.shared import (
    StiffnessReport,
    TaskSpaceGains,
    constraint_force,
    effective_stiffness,
    joint_space_shared_control,
    task_space_shared_control,
    task_vector,
)
from suture_engine.robot import endobot

__all__ = [
    "ExperimentResult",
    "OperatorModel",
    "run_experiment",
    "thesis_circle",
    "thesis_line",
]

Array = NDArray[np.float64]

# The robot's base frame has z along the tool, into the patient; the thesis plots use
# z up (Figs. 6.2, 6.14: z < 0 below the RCM). Its line a = (1, 1, -2) (Table 6.1) and
# circle centre (0, 0, -0.15) (Fig. 6.14) are, in the base frame of a base turned by
# 180 deg about x (EndoBotSim's default), a = (1, -1, 2) and (0, 0, 0.15).


def thesis_line() -> Line:
    """The constrained line of Table 6.1 through the RCM, in the robot's base frame."""
    return Line(point=np.zeros(3), direction=np.array([1.0, -1.0, 2.0]))


def thesis_circle() -> Circle:
    """The circle of Fig. 6.14 (centre 0.15 m below the RCM, r = 0.05 m), base frame."""
    return Circle(center=np.array([0.0, 0.0, 0.15]), radius=0.05)


@dataclass(frozen=True, eq=False)
class OperatorModel:
    """A simulated operator: the same hand impedance in all directions (6.3.4).

    Attributes:
        stiffness: hand stiffness K_h [N/m].
        damping: hand damping B_h [N*s/m].
        slide: amplitude of the motion along the fixture [m] (line) or [rad] (circle).
        slide_period: period of that motion [s].
        push: radius of the hand's excursion normal to the fixture [m].
        push_period: period of one turn of the push direction [s].
        roll: roll amplitude [rad].
        roll_stiffness: hand roll stiffness [N*m/rad].
        circle_slide: amplitude of the motion along a circle [rad].
    """

    stiffness: float = 300.0
    damping: float = 8.0
    slide: float = 0.03
    slide_period: float = 4.0
    push: float = 0.02
    push_period: float = 1.3
    roll: float = 0.8
    roll_stiffness: float = 0.5
    circle_slide: float = 1.2

    def hand(self, fixture: EqualityFixture, free_start: Array, t: float) -> Array:
        """The hand's target (x, y, z, phi) at time t [s] in the base frame [m, rad].

        It slides along the fixture's first free coordinate, rolls, and circles the
        fixture at ``push`` [m] in the plane of its normals (ramped in over 0.5 s).

        Args:
            fixture: the fixture the operator works along.
            free_start: the free coordinates f(x) (6.34) where the run started.
            t: time since the start [s].
        """
        m = fixture.rows
        free = np.array(free_start, dtype=float)
        amp = self.circle_slide if isinstance(fixture, Circle) else self.slide
        free[0] += amp * np.sin(2 * np.pi * t / self.slide_period)
        free[-1] = self.roll * np.sin(2 * np.pi * t / (1.7 * self.slide_period))
        on = fixture.inverse(np.zeros(m), free)
        normals = fixture.jacobian(on)[:, :3]
        normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        ang = 2 * np.pi * t / self.push_period
        ramp = min(1.0, t / 0.5)
        if m == 2:
            u1 = normals[0]
            u2 = normals[1] - (normals[1] @ u1) * u1
            u2 /= np.linalg.norm(u2)
            offset = self.push * ramp * (np.cos(ang) * u1 + np.sin(ang) * u2)
        else:
            offset = self.push * ramp * np.cos(ang) * normals[0]
        return np.r_[on[:3] + offset, on[3]]

    def wrench(
        self, fixture: EqualityFixture, free_start: Array, t: float, x: Array, pdot: Array
    ) -> tuple[Array, float]:
        """The operator's force on the tool tip [N] and roll torque [N*m], base frame.

        ``F = K_h (h - p) - B_h pdot`` and ``tau_roll = K_roll (phi_h - phi)``.

        Args:
            fixture: the fixture the operator works along.
            free_start: the free coordinates where the run started.
            t: time since the start [s].
            x: the tool's task vector (x, y, z, phi) [m, m, m, rad].
            pdot: the tool tip's velocity [m/s].
        """
        h = self.hand(fixture, free_start, t)
        force = self.stiffness * (h[:3] - x[:3]) - self.damping * np.asarray(pdot)
        return force, self.roll_stiffness * (float(h[3]) - float(x[3]))


class ExperimentResult(NamedTuple):
    """One run's measurements.

    Attributes:
        controller: ``"task"`` (6.24) or ``"joint"`` (6.37).
        fixture: ``"line"`` or ``"circle"``.
        desired_stiffness: Kp of the task-space controller [N/m] (nan for joint space).
        table: Tables 6.2-6.4: peaks of e and Fc (6.53) per row and their ratio (6.54).
        operator_table: the same with the operator's normal force instead of Fc.
        operator_slope: least-squares slope of the operator's normal force on e [N/m].
        free_travel: range of the free coordinate covered [m or rad].
        roll_range: range of the roll covered [rad].
        saturated_ticks: ticks where a motor torque hit its limit (0 when not saturating).
        saturate: whether the motors' limits applied.
        t: time [s]; e: deviations (T, m) [m]; fc: constraint forces (T, m) [N];
        f_op: operator normal forces (T, m) [N]; x: task vectors (T, 4).
    """

    controller: str
    fixture: str
    desired_stiffness: float
    table: StiffnessReport
    operator_table: StiffnessReport
    operator_slope: Array
    free_travel: float
    roll_range: float
    saturated_ticks: int
    saturate: bool
    t: Array
    e: Array
    fc: Array
    f_op: Array
    x: Array


@dataclass(frozen=True, eq=False)
class _JointGains:
    kp: Array = field(default_factory=lambda: np.array([60.0, 60.0, 0.0, 1500.0]))
    kd: Array = field(default_factory=lambda: np.array([1.0, 1.0, 0.0, 40.0]))


def _start_q(fixture: EqualityFixture) -> Array:
    if isinstance(fixture, Circle):
        x0 = fixture.inverse(np.zeros(2), np.array([0.0, 0.0]))
    else:
        x0 = fixture.inverse(np.zeros(fixture.rows), np.r_[0.12, np.zeros(3 - fixture.rows)])
    return endobot.inverse_kinematics(x0[:3], float(x0[3]))


def run_experiment(
    fixture: EqualityFixture,
    *,
    controller: Literal["task", "joint"] = "task",
    duration: float = 8.0,
    stiffness: float = 1000.0,
    damping: float = 30.0,
    operator: OperatorModel | None = None,
    friction: bool = True,
    velocity_pole: float = 200.0,
    saturate: bool = True,
    seed: int = 0,
) -> ExperimentResult:
    """Run one chapter 6 experiment on a PyBullet EndoBot (headless).

    Args:
        fixture: the line or circle to hold.
        controller: ``"task"`` for (6.24), ``"joint"`` for (6.35-6.37).
        duration: simulated time [s].
        stiffness: task-space Kp [N/m] (task controller only).
        damping: task-space Kv [N*s/m] (task controller only).
        operator: the simulated operator (default :class:`OperatorModel`).
        friction: simulate joint friction (model b, Coulomb + viscous).
        velocity_pole: washout filter pole for the velocity estimate [rad/s] (3.79).
        saturate: clip the torques to the motors' limits (Table 3.1); False shows what
            the control law does with unlimited actuators.
        seed: seed of the sensor models (ideal sensors here: no effect).

    Returns:
        The run's measurements.
    """
    import pybullet as p

    from backends.pybullet.robot import EndoBotSim
    from suture_engine.control.filters import WashoutFilter

    op = operator or OperatorModel()
    client = p.connect(p.DIRECT)
    try:
        p.setGravity(0.0, 0.0, -9.81, physicsClientId=client)
        q0 = _start_q(fixture)
        sim = EndoBotSim(client, q0=q0, friction=friction, seed=seed, saturate=saturate)
        _, base_quat = p.getBasePositionAndOrientation(sim.body_id, physicsClientId=client)
        rot = np.array(p.getMatrixFromQuaternion(base_quat)).reshape(3, 3)  # base -> world
        gains = TaskSpaceGains(stiffness=stiffness, damping=damping)
        jg = _JointGains()
        washout = WashoutFilter(velocity_pole, sim.dt)
        washout.reset(q0)
        n = round(duration / sim.dt)
        m = fixture.rows
        t_log, e_log = np.zeros(n), np.zeros((n, m))
        fc_log, fop_log, x_log = np.zeros((n, m)), np.zeros((n, m)), np.zeros((n, 4))
        x_start = task_vector(q0)
        f_start = fixture.free(x_start)
        saturated = 0
        limits = np.array([j.motor.max_torque for j in sim.params.joints])
        meas = sim.measure()
        p_prev = x_start[:3].copy()
        for k in range(n):
            t = k * sim.dt
            q = np.asarray(meas.joints.values, dtype=float)
            qd = washout.update(q).copy()
            x = task_vector(q)
            grav = endobot.gravity_vector(q, sim.model_params)
            if controller == "task":
                out = task_space_shared_control(fixture, q, qd, gains)
                tau_shared = out.tau
            else:
                fr = endobot.friction_torque(qd, sim.params) if friction else None
                tau_shared, _ = joint_space_shared_control(fixture, q, qd, jg.kp, jg.kd)
                if fr is not None:
                    tau_shared = tau_shared + fr
            tau = tau_shared + grav
            applied = tau
            if saturate:
                if np.any(np.abs(tau) >= limits):
                    saturated += 1
                applied = np.clip(tau, -limits, limits)
            # The operator's hand, in the base frame: slide along the fixture, circle round it.
            pos = x[:3]
            pdot = (pos - p_prev) / sim.dt if k else np.zeros(3)
            p_prev = pos
            f_op, roll_torque = op.wrench(fixture, f_start, t, x, pdot)
            tool_world, _ = sim.true_tool_pose()
            p.applyExternalForce(
                sim.body_id,
                sim.tool_link,
                (rot @ f_op).tolist(),
                tool_world.tolist(),
                p.WORLD_FRAME,
                physicsClientId=client,
            )
            axis_world = rot @ endobot.rotation(q)[:, 2]
            p.applyExternalTorque(
                sim.body_id,
                sim.tool_link,
                (roll_torque * axis_world).tolist(),
                p.WORLD_FRAME,
                physicsClientId=client,
            )
            meas = sim.step(applied)
            # Evaluation: deviation, constraint force from the applied torques (6.53),
            # and the operator's force along each row's unit normal.
            jc = fixture.jacobian(x)[:, :3]
            unit = jc / np.linalg.norm(jc, axis=1, keepdims=True)
            t_log[k] = t
            e_log[k] = fixture.value(x)
            fc_log[k] = constraint_force(fixture, q, applied - grav)
            fop_log[k] = unit @ f_op
            x_log[k] = x
        skip = int(0.5 / sim.dt)  # the operator's ramp-in
        table = effective_stiffness(e_log[skip:], fc_log[skip:])
        op_table = effective_stiffness(e_log[skip:], fop_log[skip:])
        slope = np.array(
            [
                float(e_log[skip:, i] @ fop_log[skip:, i] / (e_log[skip:, i] @ e_log[skip:, i]))
                for i in range(m)
            ]
        )
        free_traj = np.array([fixture.free(xx)[0] for xx in x_log[skip:]])
        return ExperimentResult(
            controller=controller,
            fixture=fixture.name,
            desired_stiffness=stiffness if controller == "task" else float("nan"),
            table=table,
            operator_table=op_table,
            operator_slope=slope,
            free_travel=float(np.ptp(free_traj)),
            roll_range=float(np.ptp(x_log[skip:, 3])),
            saturated_ticks=saturated,
            saturate=saturate,
            t=t_log,
            e=e_log,
            fc=fc_log,
            f_op=fop_log,
            x=x_log,
        )
    finally:
        p.disconnect(physicsClientId=client)
