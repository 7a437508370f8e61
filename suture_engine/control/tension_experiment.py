"""The tension-control experiments of thesis 7.5 (Fig. 7.20, Tables 7.3-7.5), simulated.

Set-up (7.5.1): the suture's free tail is fixed to a fixture, the other end is
held by the tool tip of an EndoBot whose base carries the force/torque sensor.
The tip starts at rest with the suture slack; the hybrid controller
(:class:`~suture_engine.control.hybrid_force.HybridForcePositionController`)
then commands a step of tension (thesis: -15 N in its sign convention, 15 N of
tension here) along the pulling direction, and the tip is held on that line.

The suture is the thesis' environment model (Fig. 7.11): a unilateral
spring-damper from the tool tip to the fixed anchor, ``T = max(0, k s + b sdot)``
while taut (stretch ``s > 0``), zero while slack, applied to the simulated
robot as an external force at the tool tip. The thesis does not identify the
suture's stiffness. The default ``k = 10 kN/m`` is 5 cm of 2-0 braided silk
(EA ~ 500 N: ~15 % elongation near its ~25 N straight-pull strength, and
E ~ 5-10 GPa over d = 0.32 mm) to a rigid fixture; ``b = 2 N*s/m`` is light
material damping; the tip starts 10 mm short of taut. Softer sutures are a
parameter away (:class:`SutureSpring`); with them, or without slack, the
contact is gentle and the integral-only loop shows no force spike in this
simulation (the benchmark prints that sensitivity).

The torque loop runs at 1 kHz with gravity and Coulomb friction compensation
(5.19, smoothed sign); the force loop at 500 Hz as in 7.5.1.

What the controller sees is what the real robot measures: encoder positions
(joint velocity by a washout filter, 5.50) and the base wrench, turned into a
tension by :class:`~suture_engine.suture.tension.TensionEstimator`. The
simulated spring's tension is recorded beside it as ground truth.

Metrics as in 7.5.2: ``e_RMS = sqrt(mean((f_m - F_des)^2))`` over the run and
``e_inf = max |f_m|`` (the thesis' "maximum force error" is the largest
measured force), from the measured tension at the force-loop rate.

PyBullet is imported lazily, inside :func:`run_tension_experiment`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.control.filters import WashoutFilter
from suture_engine.control.hybrid_force import (
    ExplicitForceController,
    HybridForcePositionController,
    ModifiedForceReference,
)
from suture_engine.robot import endobot
from suture_engine.suture.tension import TensionEstimator

__all__ = [
    "THESIS_TABLE",
    "SutureSpring",
    "TensionCase",
    "TensionRun",
    "run_tension_experiment",
    "thesis_cases",
    "windup_force",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SutureSpring:
    """The suture as a unilateral spring-damper to a fixed anchor (Fig. 7.11).

    Attributes:
        stiffness: k [N/m].
        damping: b [N*s/m], active only while taut.
        slack: initial slack between the tip and the taut length [m].
        length: taut (rest) length from the tip to the anchor [m].
    """

    stiffness: float = 10000.0
    damping: float = 2.0
    slack: float = 0.01
    length: float = 0.05


@dataclass(frozen=True)
class TensionCase:
    """One row of Tables 7.3-7.5.

    Attributes:
        label: the row's name.
        kp: K_p [-].
        ki: K_i [1/s].
        kv: K_v [N*s/m].
        ramp: use the modified force reference of Fig. 7.29.
        lead: margin of the modified reference over the measured force [N].
    """

    label: str
    kp: float
    ki: float
    kv: float
    ramp: bool = False
    lead: float = 5.0


def thesis_cases() -> list[TensionCase]:
    """The six gain sets of Tables 7.3-7.5, in the thesis' order."""
    return [
        TensionCase("Ki=0.5, Kv=0", 0.0, 0.5, 0.0),
        TensionCase("Ki=0.5, Kv=1000", 0.0, 0.5, 1000.0),
        TensionCase("Ki=0.5, Kv=2000", 0.0, 0.5, 2000.0),
        TensionCase("Kp=0.3, Ki=0.5, Kv=2000", 0.3, 0.5, 2000.0),
        TensionCase("Kp=0.5, Ki=0.5, Kv=2000", 0.5, 0.5, 2000.0),
        TensionCase("Kp=0.2, Ki=0.3, Kv=2000, ramped", 0.2, 0.3, 2000.0, ramp=True),
    ]


THESIS_TABLE: dict[str, tuple[float, float]] = {
    "Ki=0.5, Kv=0": (5.92, 71.91),
    "Ki=0.5, Kv=1000": (4.76, 31.45),
    "Ki=0.5, Kv=2000": (4.70, 27.21),
    "Kp=0.3, Ki=0.5, Kv=2000": (3.68, 31.24),
    "Kp=0.5, Ki=0.5, Kv=2000": (4.84, 33.19),
    "Kp=0.2, Ki=0.3, Kv=2000, ramped": (1.93, 15.83),
}
"""The thesis' (e_RMS [N], e_inf [N]) per row, Tables 7.3-7.5 (step to -15 N)."""


def windup_force(ki: float, kv: float, error: float, slack: float) -> float:
    """Force command the integrator holds when a slack suture comes taut [N].

    Not from the thesis; the mechanism behind this simulation's peaks once Kv is large.
    While the suture is slack the force error is constant (``error`` = F_des for a step,
    the lead for the modified reference), so (7.22) with K_p = 0 gives
    ``u = Ki error t - Kv xdot``. With the tip's inertia negligible against the damping
    (time constant m / Kv, about a millisecond here) the tip creeps at
    ``xdot = Ki error t / Kv``, covers the slack s at ``t_c = sqrt(2 Kv s / (Ki error))``,
    and the integral has then reached ``Ki error t_c = sqrt(2 Ki error Kv s)``. Once the
    taut suture stops the tip, the damping term vanishes and the tension rises to that
    integral: more damping lets the integral wind up longer, so above
    ``Kv = F_des^2 / (2 Ki error s)`` the peak grows like sqrt(Kv).

    Args:
        ki: integral gain K_i [1/s].
        kv: active damping gain K_v [N*s/m].
        error: force error while slack [N].
        slack: slack to take up [m].
    """
    return math.sqrt(2.0 * ki * error * kv * slack)


class TensionRun(NamedTuple):
    """One simulated run.

    Attributes:
        case: the gain set.
        time: sample times of the force loop [s].
        measured: estimated tension f_m [N].
        true_tension: the simulated suture's tension (ground truth) [N].
        reference: force reference f_r [N].
        force_command: u_f [N].
        line_error: distance of the tip from the constraint line [m].
        rms_error: e_RMS against the desired tension F_des [N].
        rms_reference: e_RMS against the reference actually used, f_r [N] (the
            same as ``rms_error`` for a step; smaller for the modified reference).
        max_force: e_inf = max |f_m| [N].
        max_true: max of the true tension [N].
        final_error: mean |f_m - F_des| over the last second [N].
    """

    case: TensionCase
    time: FloatArray
    measured: FloatArray
    true_tension: FloatArray
    reference: FloatArray
    force_command: FloatArray
    line_error: FloatArray
    rms_error: float
    rms_reference: float
    max_force: float
    max_true: float
    final_error: float


def run_tension_experiment(
    case: TensionCase,
    duration: float = 30.0,
    target: float = 15.0,
    spring: SutureSpring | None = None,
    q0: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.1),
    direction: tuple[float, float, float] = (0.8, -0.6, 0.0),
    force_period: float = 2e-3,
    washout_pole: float = 200.0,
    estimator_cutoff: float = 100.0,
    force_noise: float = 0.0,
    force_limit: float = math.inf,
    friction_compensation: str = "coulomb",
    seed: int = 0,
) -> TensionRun:
    """Run one step of tension on the simulated EndoBot (7.5).

    Args:
        case: the gains.
        duration: simulated time after the step [s].
        target: desired tension F_des [N].
        spring: the suture model; None: :class:`SutureSpring` defaults.
        q0: starting joints [rad, rad, rad, m], suture slack.
        direction: pulling direction e in the base frame [-].
        force_period: force-loop period [s] (thesis: 2 ms); torques at 1 kHz.
        washout_pole: pole of the joint-velocity washout filter [rad/s].
        estimator_cutoff: low-pass cut-off of the tension estimate [Hz].
        force_noise: standard deviation of the base sensor's force noise [N]
            (moments get 1/10 of it in N*m).
        force_limit: saturation of the force command [N].
        friction_compensation: "none", "coulomb" (5.19) or "full" (Coulomb and viscous).
        seed: the sensor noise's seed.

    Returns:
        The :class:`TensionRun`.
    """
    import pybullet as p

    from backends.pybullet.robot import EndoBotSim
    from backends.pybullet.sensors import ft_sensor_model

    sp = spring or SutureSpring()
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)
        ft = ft_sensor_model(force_noise, 0.1 * force_noise) if force_noise > 0 else None
        sim = EndoBotSim(cid, q0=q0, ft_sensor=ft, seed=seed)
        prm = sim.model_params
        dt = sim.dt
        e = np.asarray(direction, dtype=float)
        e = e / float(np.linalg.norm(e))
        x0 = endobot.forward_kinematics(q0).position
        anchor_base = x0 - e * (sp.length - sp.slack)
        rot = sim._base_rot  # world <- base (the mount's fixed pose, known)
        base_pos = np.asarray(p.getBasePositionAndOrientation(sim.body_id, cid)[0])
        anchor = base_pos + rot @ anchor_base

        estimator = TensionEstimator(e, prm, dt=dt, cutoff=estimator_cutoff)
        meas = sim.step(endobot.gravity_vector(q0, prm))
        estimator.tare(meas.base_wrench.values, meas.joints.values)
        washout = WashoutFilter(washout_pole, dt)
        washout.reset(meas.joints.values)
        force = ExplicitForceController(case.kp, case.ki, case.kv, force_period, force_limit)
        ramp = ModifiedForceReference(target, case.lead, force_period) if case.ramp else None
        comp = None if friction_compensation == "none" else [j.friction for j in prm.joints]
        ctrl = HybridForcePositionController(
            e,
            x0,
            force,
            prm,
            dt=dt,
            roll=q0[2],
            reference=ramp,
            friction=comp,
            viscous=friction_compensation == "full",
        )
        n = round(duration / dt)
        keep = ctrl.decimation
        rows = []
        for k in range(n):
            q = meas.joints.values
            qd = washout.update(q)
            est = estimator.update(meas.base_wrench.values, q)
            cmd = ctrl.update(q, qd, est.tension, target)
            st = p.getLinkState(
                sim.body_id, sim.tool_link, computeLinkVelocity=True, physicsClientId=cid
            )
            tip, vel = np.asarray(st[0]), np.asarray(st[6])
            span = anchor - tip
            dist = float(np.linalg.norm(span))
            u = span / dist
            stretch = dist - sp.length
            tension = 0.0
            if stretch > 0.0:
                tension = max(0.0, sp.stiffness * stretch - sp.damping * float(u @ vel))
                p.applyExternalForce(
                    sim.body_id,
                    sim.tool_link,
                    (tension * u).tolist(),
                    tip.tolist(),
                    p.WORLD_FRAME,
                    physicsClientId=cid,
                )
            if k % keep == 0:
                rows.append(
                    (k * dt, est.tension, tension, cmd.reference, cmd.force, cmd.line_error)
                )
            meas = sim.step(cmd.torque)
    finally:
        p.disconnect(cid)
    data = np.array(rows)
    t, fm, ft_true = data[:, 0], data[:, 1], data[:, 2]
    last = t >= t[-1] - 1.0
    return TensionRun(
        case=case,
        time=t,
        measured=fm,
        true_tension=ft_true,
        reference=data[:, 3],
        force_command=data[:, 4],
        line_error=data[:, 5],
        rms_error=float(np.sqrt(np.mean((fm - target) ** 2))),
        rms_reference=float(np.sqrt(np.mean((fm - data[:, 3]) ** 2))),
        max_force=float(np.max(np.abs(fm))),
        max_true=float(np.max(ft_true)),
        final_error=float(np.mean(np.abs(fm[last] - target))),
    )
