"""Circle-tracking experiments on the simulated EndoBot (5.2.2, Figs. 5.3-5.4, Tables 5.1-5.2).

The tool tip follows a horizontal circle at a fixed depth below the RCM; the
joint references come from the inverse kinematics of the circle, and a joint
controller tracks them from encoder positions only:

* ``"pd"``: PD with gravity and (optionally) Coulomb friction compensation
  (5.10, 5.19), critically damped 7 Hz gains from the workspace centre
  (5.15-5.18), velocity from a washout filter (5.50);
* ``"lqg"``: feedback linearisation with LQR + integral action and a Kalman
  velocity observer (5.21, 5.44, 5.53-5.62), friction compensation optional.

Errors are measured on the simulator's ground truth (evaluation only): the
joint errors of yaw and pitch [deg] and the Cartesian error of the tool tip
[mm], as in Table 5.1. The first period is discarded (start-up transient).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.control.filters import WashoutFilter
from suture_engine.control.kalman import LQGController
from suture_engine.control.lqr import LqrWeights
from suture_engine.control.model import FrictionSign, endobot_control_model
from suture_engine.control.pd import PDController, gains_at_workspace_centre
from suture_engine.errors import SutureError
from suture_engine.robot import endobot
from suture_engine.robot.params import E1, EndoBotParams

__all__ = [
    "TABLE_5_2_FREQUENCIES",
    "TABLE_5_2_RADII",
    "CircleTrajectory",
    "TrackingResult",
    "circle_trajectory",
    "run_circle_tracking",
]

FloatArray = NDArray[np.float64]
DT = 1e-3

TABLE_5_2_FREQUENCIES = (0.1, 0.25, 0.5)
"""Circle frequencies of Table 5.2 [Hz]."""
TABLE_5_2_RADII = (0.0025, 0.005, 0.010)
"""Circle radii of Table 5.2 [m]."""


class TrackingError(SutureError):
    """A tracking experiment was asked for with impossible settings.

    Attributes:
        name: the parameter.
        value: its value.
    """

    code = "tracking"

    def __init__(self, name: str, value: object, reason: str) -> None:
        super().__init__(f"{name}={value!r}: {reason}")
        self.name = name
        self.value = value


class CircleTrajectory(NamedTuple):
    """A circle of the tool tip and its joint-space reference.

    Attributes:
        t: time [s].
        position: desired tip positions [m], ``(m, 3)``.
        q: joint references [rad, rad, rad, m], ``(m, 4)``.
        qd: joint velocity references, ``(m, 4)``.
        qdd: joint acceleration references, ``(m, 4)``.
    """

    t: FloatArray
    position: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray


class TrackingResult(NamedTuple):
    """Table 5.1 figures of one run (errors after the first period).

    Attributes:
        max_joint_error_deg: max |error| of yaw and pitch [deg].
        mean_joint_error_deg: mean |error| of yaw and pitch [deg].
        mean_cartesian_error_mm: mean tip distance to the reference [mm].
        max_cartesian_error_mm: max tip distance to the reference [mm].
        t: time [s].
        tip: true tip positions [m], ``(m, 3)``.
        tip_ref: desired tip positions [m].
        tau: applied torques, ``(m, 4)``.
    """

    max_joint_error_deg: tuple[float, float]
    mean_joint_error_deg: tuple[float, float]
    mean_cartesian_error_mm: float
    max_cartesian_error_mm: float
    t: FloatArray
    tip: FloatArray
    tip_ref: FloatArray
    tau: FloatArray


def circle_trajectory(
    radius: float, frequency: float, duration: float, *, depth: float = 0.10, dt: float = DT
) -> CircleTrajectory:
    """Joint references for a horizontal tip circle centred below the RCM.

    The circle is ``(r cos wt, r sin wt, depth)`` in the base frame (z along the
    tool at ``q = 0``); joints come from the inverse kinematics, velocities and
    accelerations from the analytical Jacobian and central differences.

    Args:
        radius: circle radius [m].
        frequency: revolutions per second [Hz].
        duration: length [s].
        depth: distance of the circle's plane below the RCM [m].
        dt: sampling time [s].

    Returns:
        The trajectory.
    """
    if not radius > 0.0:
        raise TrackingError("radius", radius, "must be positive")
    if not frequency > 0.0:
        raise TrackingError("frequency", frequency, "must be positive")
    t = np.arange(round(duration / dt) + 2, dtype=np.float64) * float(dt)
    w = 2.0 * math.pi * frequency
    pos = np.column_stack([radius * np.cos(w * t), radius * np.sin(w * t), np.full_like(t, depth)])
    vel = np.column_stack([-radius * w * np.sin(w * t), radius * w * np.cos(w * t), 0.0 * t])
    q = np.array([endobot.inverse_kinematics(p, 0.0) for p in pos])
    qd = np.array([np.linalg.solve(endobot.jacobian(qi), np.append(v, 0.0)) for qi, v in
                   zip(q, vel, strict=True)])  # fmt: skip
    qdd = np.gradient(qd, dt, axis=0)
    return CircleTrajectory(t, pos, q, qd, qdd)


def run_circle_tracking(
    radius: float = 0.010,
    frequency: float = 0.25,
    *,
    controller: str = "pd",
    friction_compensation: bool = True,
    periods: float = 2.0,
    params: EndoBotParams | None = None,
    model_params: EndoBotParams | None = None,
    friction_model: str = "b",
    encoder_noise: float = 0.0,
    quantised: bool = True,
    seed: int = 0,
    natural_frequency_hz: float = 7.0,
    washout_pole: float = 150.0,
    lqr_weights: LqrWeights | None = None,
) -> TrackingResult:
    """Track one circle on the simulated robot and measure the Table 5.1 errors.

    Args:
        radius: circle radius [m].
        frequency: circle frequency [Hz].
        controller: "pd" or "lqg".
        friction_compensation: add the Coulomb compensation (5.19).
        periods: number of circles; the first is not scored.
        params: the simulated robot's parameters (None: E1).
        model_params: the parameters the controller compensates with (None: the
            robot's own, an exact model).
        friction_model: the simulated friction model, "a"-"d".
        encoder_noise: encoder noise standard deviation [rad and m].
        quantised: quantise encoders at 2000 counts per motor revolution.
        seed: sensor seed.
        natural_frequency_hz: PD closed-loop natural frequency [Hz] (5.17).
        washout_pole: washout filter pole for the PD's velocity [rad/s].
        lqr_weights: LQR weights for "lqg".

    Returns:
        The errors and the recorded tip path.
    """
    import pybullet as p

    from backends.pybullet.robot import EndoBotSim
    from backends.pybullet.sensors import encoder_model

    if controller not in ("pd", "lqg"):
        raise TrackingError("controller", controller, "choose pd or lqg")
    if periods <= 1.0:
        raise TrackingError("periods", periods, "need more than one (the first is not scored)")
    prm = params or E1
    traj = circle_trajectory(radius, frequency, periods / frequency)
    mprm = model_params or prm
    model = endobot_control_model(mprm, friction_scale=1.0 if friction_compensation else 0.0)
    n = traj.t.size - 1
    client = p.connect(p.DIRECT)
    try:
        p.setGravity(0.0, 0.0, -9.81, physicsClientId=client)
        enc = encoder_model(
            prm,
            counts_per_motor_rev=2000.0 if quantised else 0.0,
            insertion_resolution=1e-6 if quantised else 0.0,
            noise_std=encoder_noise,
        )
        sim = EndoBotSim(
            client,
            prm,
            q0=traj.q[0],
            friction_model=friction_model,
            encoder=enc,
            seed=seed,
            include_tool=False,
        )
        sim.reset(traj.q[0], traj.qd[0])
        q_meas = sim.measure().joints.values
        if controller == "pd":
            gains = gains_at_workspace_centre(natural_frequency_hz, mprm)
            pd = PDController(
                gains, model, friction=friction_compensation, friction_sign=FrictionSign.DESIRED
            )
            wo = WashoutFilter(washout_pole, DT, n=4)
            wo.reset(q_meas)
        else:
            lqg = LQGController(
                model,
                DT,
                weights=lqr_weights or LqrWeights(),
                process_noise=1e3,
                measurement_noise=1e-10,
            )
            lqg.reset(q_meas)
        q_true = np.empty((n, 4))
        taus = np.empty((n, 4))
        for k in range(n):
            if controller == "pd":
                v = wo.update(q_meas)
                tau = pd.update(q_meas, v, traj.q[k], traj.qd[k])
            else:
                tau = lqg.update(q_meas, traj.q[k], traj.qd[k], traj.qdd[k])
            taus[k] = tau
            q_meas = sim.step(tau).joints.values
            q_true[k] = sim.true_state().q
    finally:
        p.disconnect(physicsClientId=client)
    # q_true[k] is the state after period k, to be compared with the reference at k+1.
    ref = traj.q[1 : n + 1]
    tip = np.array([endobot.forward_kinematics(qi).position for qi in q_true])
    tip_ref = traj.position[1 : n + 1]
    scored = traj.t[1 : n + 1] >= 1.0 / frequency
    e_joint = np.degrees(np.abs(q_true[scored, :2] - ref[scored, :2]))
    e_cart = 1e3 * np.linalg.norm(tip[scored] - tip_ref[scored], axis=1)
    return TrackingResult(
        max_joint_error_deg=(float(e_joint[:, 0].max()), float(e_joint[:, 1].max())),
        mean_joint_error_deg=(float(e_joint[:, 0].mean()), float(e_joint[:, 1].mean())),
        mean_cartesian_error_mm=float(e_cart.mean()),
        max_cartesian_error_mm=float(e_cart.max()),
        t=traj.t[1 : n + 1],
        tip=tip,
        tip_ref=tip_ref,
        tau=taus,
    )
