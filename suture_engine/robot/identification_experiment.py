"""Identification experiments on the simulated EndoBot (3.5.3, Figs. 3.17-3.19, Table 3.4).

Each joint is identified alone while a PD with gravity compensation holds the
others at the synchronisation pose, as in the thesis:

1. a constant-velocity loop (Fig. 3.17) sweeps the joint back and forth at
   several speeds; the steady torques give ``Fc`` and ``Fv`` (Table 3.3);
2. an excitation torque (Schroeder-phased by default, 3.57-3.59) drives the
   joint; the differential model (or the energy model with the friction of
   step 1 subtracted) gives ``I`` and ``ml`` (Table 3.4).

The controller sees encoder positions only; velocities for feedback come from
a washout filter (3.78-3.79). The "true" values a report compares against are
what the simulation was built with: the diagonal of ``M`` and the gravity
moment of the robot model at the hold pose, and the friction parameters.

PyBullet is imported lazily, inside the functions that need it.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.control.filters import WashoutFilter
from suture_engine.control.model import endobot_control_model
from suture_engine.control.pd import PDController, critically_damped_gains
from suture_engine.robot import dynamics
from suture_engine.robot.excitation import ExcitationKind, excitation
from suture_engine.robot.identification import (
    GRAVITY,
    FrictionEstimate,
    GravityShape,
    JointEstimate,
    Validation,
    differential_rows,
    estimate_motion,
    fit_differential,
    fit_energy,
    fit_friction,
    validate,
)
from suture_engine.robot.params import E1, EndoBotParams

if TYPE_CHECKING:
    from backends.pybullet.robot import EndoBotSim

__all__ = [
    "JOINT_PLANS",
    "IdentificationReport",
    "JointPlan",
    "JointRecord",
    "JointResult",
    "identify_robot",
    "joint_truth",
    "run_constant_velocity",
    "run_excitation",
    "simulated_endobot",
]

FloatArray = NDArray[np.float64]
DT = 1e-3


@dataclass(frozen=True)
class JointPlan:
    """How one joint is excited (amplitudes keep it inside its limits).

    Attributes:
        shape: the joint's gravity shape in the single-joint model (3.73).
        hold: the pose the other joints hold [rad, rad, rad, m].
        amplitude: excitation torque half-range [N m or N].
        band: excited frequency band [Hz].
        spring: stiffness keeping the excited joint centred [N m/rad or N/m].
        damping: damping of that spring [N m s/rad or N s/m].
        sweep: position range of the constant-velocity sweeps [rad or m].
        speeds: sweep speeds [rad/s or m/s].
        cutoff: low-pass corner used for differentiation with noisy encoders [Hz].
    """

    shape: GravityShape
    hold: tuple[float, float, float, float]
    amplitude: float
    band: tuple[float, float]
    spring: float
    damping: float
    sweep: tuple[float, float]
    speeds: tuple[float, ...]
    cutoff: float


JOINT_PLANS: tuple[JointPlan, JointPlan, JointPlan, JointPlan] = (
    JointPlan(
        GravityShape.SINE, (0, 0, 0, 0.05), 0.5, (0.2, 5.0), 0.0, 0.0, (-0.5, 0.5),
        (0.25, 0.5, 1.0), 15.0,
    ),
    JointPlan(
        GravityShape.SINE, (0, 0, 0, 0.05), 0.5, (0.2, 5.0), 0.0, 0.0, (-0.5, 0.5),
        (0.25, 0.5, 1.0), 15.0,
    ),
    JointPlan(
        GravityShape.NONE, (0, 0, 0, 0.05), 1.0, (1.0, 40.0), 0.3, 0.0, (-1.0, 1.0),
        (0.5, 1.0, 2.0), 40.0,
    ),
    JointPlan(
        GravityShape.CONSTANT, (0, 0, 0, 0.10), 0.6, (0.2, 5.0), 20.0, 0.0, (0.04, 0.16),
        (0.02, 0.04, 0.08), 15.0,
    ),
)  # fmt: skip
"""Default plan per joint (yaw, pitch, roll, insertion)."""


class JointRecord(NamedTuple):
    """One single-joint experiment's data (what the real robot could record).

    Attributes:
        t: time [s].
        q: encoder positions of the excited joint [rad or m].
        tau: torque applied to the excited joint during each period [N m or N].
        u: the excitation part of ``tau``.
    """

    t: FloatArray
    q: FloatArray
    tau: FloatArray
    u: FloatArray


class JointResult(NamedTuple):
    """Estimate and truth for one joint (one row of Table 3.4).

    Attributes:
        joint: joint index 0-3.
        estimate: the identified parameters.
        truth: the simulated robot's values (condition is nan).
        friction: the constant-velocity friction estimate.
        validation: residual of the differential model with the estimate, and its
            correlation with the excitation input (3.77, 3.80).
    """

    joint: int
    estimate: JointEstimate
    truth: JointEstimate
    friction: FrictionEstimate
    validation: Validation


class IdentificationReport(NamedTuple):
    """The result of :func:`identify_robot`.

    Attributes:
        robot: the robot's name.
        signal: the excitation used.
        method: "differential" or "energy".
        encoder_noise: encoder noise standard deviation [rad, m].
        joints: one result per identified joint.
        quantised: whether the encoders were quantised.
    """

    robot: str
    signal: str
    method: str
    encoder_noise: float
    joints: tuple[JointResult, ...]
    quantised: bool = False


@contextmanager
def simulated_endobot(
    params: EndoBotParams | None = None,
    *,
    encoder_noise: float = 0.0,
    quantised: bool = False,
    seed: int = 0,
    q0: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.05),
    saturate: bool = False,
) -> Iterator[EndoBotSim]:
    """One EndoBot alone on a headless PyBullet client, gravity pointing into the patient.

    Args:
        params: the robot's true parameters (None: E1).
        encoder_noise: Gaussian encoder noise [rad and m].
        quantised: quantise encoders at 2000 counts per motor revolution.
        seed: sensor noise seed.
        q0: initial joints [rad, rad, rad, m].
        saturate: clip torques at the drives' +-10 V limit. Off by default: at that
            limit the insertion drive gives 2.46 N, barely above the 2.40 N weight
            of the vertical insertion stage, which leaves no room to excite it.

    Yields:
        The simulated robot; the client is disconnected on exit.
    """
    import pybullet as p

    from backends.pybullet.robot import EndoBotSim
    from backends.pybullet.sensors import encoder_model

    client = p.connect(p.DIRECT)
    try:
        p.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=client)
        enc = encoder_model(
            params,
            counts_per_motor_rev=2000.0 if quantised else 0.0,
            insertion_resolution=1e-6 if quantised else 0.0,
            noise_std=encoder_noise,
        )
        yield EndoBotSim(
            client, params, q0=q0, encoder=enc, seed=seed, include_tool=False, saturate=saturate
        )
    finally:
        p.disconnect(physicsClientId=client)


def joint_truth(params: EndoBotParams, joint: int, hold: Any) -> JointEstimate:
    """The simulated robot's single-joint values at the hold pose.

    ``I = M_jj(q_hold)``; ``ml`` from the model's gravity vector with the joint
    turned to its largest gravity torque (``G_j = ml g s(q_j)``).

    Args:
        params: the parameters the simulation was built with (gravity included).
        joint: joint index 0-3.
        hold: hold pose [rad, rad, rad, m].

    Returns:
        The true values (condition nan).
    """
    th = params.coefficients
    q = np.array(hold, dtype=float)
    inertia = float(dynamics.mass_matrix(q, th)[joint, joint])
    shape = JOINT_PLANS[joint].shape
    if shape is GravityShape.SINE:
        q[joint] = math.pi / 2
        ml = float(dynamics.gravity_vector(q, th, params.gravity)[joint]) / GRAVITY
    elif shape is GravityShape.CONSTANT:
        ml = -float(dynamics.gravity_vector(q, th, params.gravity)[joint]) / GRAVITY
    else:
        ml = float("nan")
    fr = params.joints[joint].friction
    return JointEstimate(inertia, ml, fr.coulomb, fr.viscous, float("nan"))


class _Holder:
    """PD + gravity + Coulomb compensation holding every joint but one (encoders only)."""

    def __init__(self, params: EndoBotParams, joint: int, hold: Any) -> None:
        model = endobot_control_model(params)
        m = np.diag(model.mass_matrix(np.asarray(hold, dtype=float)))
        gains = critically_damped_gains(2 * math.pi * 8.0, m)
        self.pd = PDController(gains, model, friction=False)
        self.filter = WashoutFilter(300.0, DT, n=4)
        self.hold = np.asarray(hold, dtype=float)
        self.joint = joint
        self.zero = np.zeros(4)

    def update(self, q_meas: FloatArray) -> FloatArray:
        v = self.filter.update(q_meas)
        return self.pd.update(q_meas, v, self.hold, self.zero)


def run_excitation(
    sim: EndoBotSim,
    joint: int,
    signal: ExcitationKind | str = ExcitationKind.SCHROEDER,
    duration: float = 10.0,
    *,
    plan: JointPlan | None = None,
    seed: int = 1,
) -> JointRecord:
    """Drive one joint with an excitation torque while the others are held.

    Args:
        sim: the simulated robot.
        joint: joint index 0-3.
        signal: excitation kind.
        duration: length [s].
        plan: excitation plan (default :data:`JOINT_PLANS`).
        seed: PRBS seed.

    Returns:
        The record of the excited joint.
    """
    pl = plan or JOINT_PLANS[joint]
    hold = np.array(pl.hold, dtype=float)
    sim.reset(hold)
    holder = _Holder(sim.model_params, joint, hold)
    sig = excitation(signal, duration, DT, pl.amplitude, f_low=pl.band[0], f_high=pl.band[1],
                     seed=seed)  # fmt: skip
    n = sig.t.size
    q_rec, tau_rec = np.empty(n), np.empty(n)
    g_ff = 0.0
    if pl.shape is GravityShape.CONSTANT:
        g_ff = float(dynamics.gravity_vector(hold, sim.model_params.coefficients,
                                             sim.model_params.gravity)[joint])  # fmt: skip
    q_meas = sim.measure().joints.values
    wo = WashoutFilter(300.0, DT, n=1)
    for k in range(n):
        tau = holder.update(q_meas).copy()
        qj = q_meas[joint]
        vj = wo.update(q_meas[joint : joint + 1])[0]
        tau[joint] = sig.u[k] + g_ff - pl.spring * (qj - hold[joint]) - pl.damping * vj
        q_rec[k] = qj
        q_meas = sim.step(tau).joints.values
        tau_rec[k] = sim.last_command[joint]  # after saturation, if any
    return JointRecord(sig.t, q_rec, tau_rec, sig.u.copy())


def run_constant_velocity(
    sim: EndoBotSim,
    joint: int,
    *,
    plan: JointPlan | None = None,
    settle: float = 0.4,
    cutoff_hz: float | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Constant-velocity sweeps of one joint (Fig. 3.17), steady samples only.

    A stiff PD tracks position ramps (a PI loop on velocity) back and forth at
    each speed of the plan; samples within ``settle`` of a ramp's start are
    dropped.

    Args:
        sim: the simulated robot.
        joint: joint index 0-3.
        plan: sweep plan (default :data:`JOINT_PLANS`).
        settle: time dropped after each ramp start [s].
        cutoff_hz: low-pass corner before differentiating (None for clean encoders) [Hz].

    Returns:
        ``(q, v, tau)`` of the excited joint on the steady samples.
    """
    pl = plan or JOINT_PLANS[joint]
    hold = np.array(pl.hold, dtype=float)
    lo, hi = pl.sweep
    start = hold.copy()
    start[joint] = lo
    sim.reset(start)
    holder = _Holder(sim.model_params, joint, start)
    holder.filter.reset(start)
    model = holder.pd.model
    inertia = float(model.mass_matrix(start)[joint, joint])
    w = 2 * math.pi * 6.0
    kp, kd = w * w * inertia * 4.0, 2.0 * w * inertia * 2.0
    refs: list[tuple[float, float, bool]] = []  # (position, velocity, steady)
    for _ in range(int(0.5 / DT)):
        refs.append((lo, 0.0, False))
    for speed in pl.speeds:
        for direction in (1.0, -1.0):
            a, b = (lo, hi) if direction > 0 else (hi, lo)
            n = round((hi - lo) / speed / DT)
            for k in range(n + 1):
                refs.append((a + direction * speed * k * DT, direction * speed, k * DT > settle))
            for _ in range(int(0.2 / DT)):
                refs.append((b, 0.0, False))
    n = len(refs)
    q_rec, tau_rec, steady = np.empty(n), np.empty(n), np.zeros(n, dtype=bool)
    q_meas = sim.measure().joints.values
    wo = WashoutFilter(300.0, DT, n=1)
    wo.reset(q_meas[joint : joint + 1])
    for k, (qr, vr, st) in enumerate(refs):
        holder.hold[joint] = qr
        tau = holder.update(q_meas).copy()
        vj = wo.update(q_meas[joint : joint + 1])[0]
        qj = q_meas[joint]
        grav = float(model.gravity_vector(q_meas)[joint])
        tau[joint] = kp * (qr - qj) + kd * (vr - vj) + grav
        q_rec[k], steady[k] = qj, st
        q_meas = sim.step(tau).joints.values
        tau_rec[k] = sim.last_command[joint]
    _, v, _ = estimate_motion(q_rec, DT, cutoff_hz)
    keep = steady & np.isfinite(v)
    return q_rec[keep], v[keep], tau_rec[keep]


def identify_robot(
    params: EndoBotParams | None = None,
    *,
    signal: ExcitationKind | str = ExcitationKind.SCHROEDER,
    duration: float = 10.0,
    encoder_noise: float = 0.0,
    quantised: bool = False,
    seed: int = 0,
    method: str = "differential",
    joints: tuple[int, ...] = (0, 1, 2, 3),
) -> IdentificationReport:
    """Identify every joint of a simulated EndoBot (3.5.3) and compare with the truth.

    Args:
        params: the simulated robot's true parameters (None: E1).
        signal: excitation kind.
        duration: excitation length per joint [s].
        encoder_noise: encoder noise standard deviation [rad and m].
        quantised: quantise the encoders (2000 counts per motor revolution).
        seed: sensor noise and PRBS seed.
        method: "differential" (3.60-3.64) or "energy" (3.65-3.75, friction first).
        joints: which joints to identify.

    Returns:
        The report. As in Tables 3.3-3.4, ``Fc`` and ``Fv`` are those of the
        constant-velocity loop; ``I`` and ``ml`` come from the excitation record
        (the differential fit estimates friction alongside, but only uses it to
        separate the columns).
    """
    p = params or E1
    kind = ExcitationKind(signal)
    results = []
    noisy = encoder_noise > 0.0 or quantised
    with simulated_endobot(p, encoder_noise=encoder_noise, quantised=quantised, seed=seed) as sim:
        for j in joints:
            pl = JOINT_PLANS[j]
            cutoff = pl.cutoff if noisy else None
            qs, vs, ts = run_constant_velocity(sim, j, cutoff_hz=cutoff)
            friction = fit_friction(qs, vs, ts, pl.shape)
            rec = run_excitation(sim, j, kind, duration, seed=seed + 1)
            if method == "energy":
                est = fit_energy(rec.q, rec.tau, DT, pl.shape, cutoff_hz=cutoff,
                                 friction=friction, window=50)  # fmt: skip
            else:
                est = fit_differential(rec.q, rec.tau, DT, pl.shape, cutoff_hz=cutoff)
            # As in Tables 3.3-3.4: friction comes from the velocity loop, I and ml
            # from the excitation record.
            est = est._replace(coulomb=friction.coulomb, viscous=friction.viscous)
            trim = 0.5
            rows, tau_f = differential_rows(rec.q, rec.tau, DT, pl.shape, cutoff_hz=cutoff,
                                            trim=trim)  # fmt: skip
            k = max(2, int(trim / DT))
            u = rec.u[k : rec.u.size - k]
            theta = [est.inertia, 0.0 if math.isnan(est.gravity_moment) else est.gravity_moment,
                     est.coulomb, est.viscous]  # fmt: skip
            check = validate(rows, theta, tau_f, u)
            truth = joint_truth(sim.model_params, j, pl.hold)
            results.append(JointResult(j, est, truth, friction, check))
    return IdentificationReport(
        p.name, kind.value, method, encoder_noise, tuple(results), quantised
    )
