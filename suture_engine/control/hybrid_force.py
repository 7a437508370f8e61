"""Hybrid force/position control along a constraint line (thesis 7.3, (7.11)-(7.22)).

Securing a knot pulls the suture end along a straight line (the direction
rule (7.1)-(7.3)) at a regulated tension. The task space is split by
selection matrices in a task frame aligned with the pulling direction e
(7.14-7.16): ``S_f = e e^T`` selects the force-controlled direction (the free
motion Jacobian J_f of the thesis) and ``S_m = I - S_f`` the two directions
in which the tip is held on the line (the constraint Jacobian J_c). The joint
torques are (7.11, 7.17)

    tau = tau_m + tau_f + G(q),
    tau_m = J^T S_m (K_x (x_line - x) - D_x xdot)        (motion, task-space PD)
    tau_f = J^T e u_f                                    (7.15, 7.20)

with the explicit PI force law with active damping (7.22)

    u_f = K_p (f_r - f_m) + K_i int (f_r - f_m) dt - K_v xdot_m,

``xdot_m = e . J qdot`` the measured velocity along the line. The thesis
writes the motion part in joint space, ``M u_m + G`` with a PD on the
projected joint error (7.18-7.19); a task-space PD with gravity compensation
holds the same line and is what is implemented here. The roll joint, which
moves no point of the tip, is held by its own PD.

The force command is saturated (one of the three safety layers on tension)
and the integral is not advanced while the output is saturated in the
direction the error pushes (clamping anti-windup). The modified reference of
Fig. 7.29 keeps the force error small while the suture comes into tension, so
that the integral does not wind up: the reference leads the measured force by
a fixed margin (the thesis uses ``-(f + 5) N``) and never exceeds the target.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.errors import InvalidValue
from suture_engine.robot import endobot
from suture_engine.robot.params import EndoBotParams, FrictionParams

__all__ = [
    "ExplicitForceController",
    "ForceGainsError",
    "HybridCommand",
    "HybridForcePositionController",
    "ModifiedForceReference",
    "selection_matrices",
]

FloatArray = NDArray[np.float64]
Vec = Sequence[float] | FloatArray
_TRANSLATING = [0, 1, 3]
"""The joints that move the tool tip (the roll, joint 3, only turns the tool)."""


class ForceGainsError(InvalidValue):
    """A force controller built with impossible gains or limits.

    Attributes:
        name: the offending argument.
        value: its value.
    """


def _check(name: str, value: float, positive: bool = False) -> float:
    v = float(value)
    if not math.isfinite(v) or v < 0.0 or (positive and v == 0.0):
        raise ForceGainsError(name, value, "finite and " + ("> 0" if positive else ">= 0"))
    return v


class ExplicitForceController:
    """Explicit PI force control with active damping and saturation (7.22).

    Args:
        kp: proportional force gain K_p [-].
        ki: integral force gain K_i [1/s].
        kv: active damping gain K_v [N*s/m].
        dt: sample period [s].
        limit: saturation of the force command |u_f| [N] (``math.inf``: none).

    Raises:
        ForceGainsError: a gain is negative or not finite, or dt/limit not > 0.
    """

    def __init__(self, kp: float, ki: float, kv: float, dt: float, limit: float = math.inf) -> None:
        self.kp = _check("kp", kp)
        self.ki = _check("ki", ki)
        self.kv = _check("kv", kv)
        self.dt = _check("dt", dt, positive=True)
        if not limit > 0.0:
            raise ForceGainsError("limit", limit, "> 0")
        self.limit = float(limit)
        self.integral = 0.0
        """Integral of the force error [N*s]."""
        self.saturated = False
        """Whether the last output was clipped."""

    def __repr__(self) -> str:
        return (
            f"ExplicitForceController(kp={self.kp:g}, ki={self.ki:g}, kv={self.kv:g}, "
            f"dt={self.dt:g}, limit={self.limit:g})"
        )

    def reset(self, integral: float = 0.0) -> None:
        """Restart with the given integral of the force error [N*s]."""
        self.integral = float(integral)
        self.saturated = False

    def update(self, reference: float, measured: float, velocity: float) -> float:
        """One sample of (7.22).

        Args:
            reference: reference force f_r [N].
            measured: measured force f_m [N].
            velocity: measured velocity along the force direction xdot_m [m/s].

        Returns:
            The force command u_f [N], within ±limit.
        """
        error = reference - measured
        candidate = self.integral + error * self.dt
        u = self.kp * error + self.ki * candidate - self.kv * velocity
        lim = self.limit
        if u > lim or u < -lim:
            self.saturated = True
            # clamp: integrate only if the error drives the output out of saturation
            if (u > lim) != (error > 0.0):
                self.integral = candidate
            return lim if u > lim else -lim
        self.saturated = False
        self.integral = candidate
        return u


class ModifiedForceReference:
    """The modified ("ramped") force reference of Fig. 7.29.

    ``f_r[k] = min(target, max(f_r[k-1], f_m[k] + lead))``, and with a rate
    limit also ``f_r[k] <= f_r[k-1] + rate * dt``: the reference leads the
    measured force by ``lead`` while the suture comes into tension, never
    decreases and never exceeds the target.

    Args:
        target: final desired tension F_des [N], > 0.
        lead: margin of the reference over the measured force [N] (thesis: 5 N).
        dt: sample period [s].
        rate: largest slope of the reference [N/s] (``math.inf``: none).

    Raises:
        ForceGainsError: on a non-positive target, lead, period or rate.
    """

    def __init__(
        self, target: float, lead: float = 5.0, dt: float = 2e-3, rate: float = math.inf
    ) -> None:
        self.target = _check("target", target, positive=True)
        self.lead = _check("lead", lead, positive=True)
        self.dt = _check("dt", dt, positive=True)
        if not rate > 0.0:
            raise ForceGainsError("rate", rate, "> 0")
        self.rate = float(rate)
        self.value = 0.0
        """The current reference [N]."""

    def __repr__(self) -> str:
        return (
            f"ModifiedForceReference(target={self.target:g} N, lead={self.lead:g} N, "
            f"rate={self.rate:g} N/s)"
        )

    def reset(self, value: float = 0.0) -> None:
        """Restart from the reference ``value`` [N]."""
        self.value = float(value)

    def update(self, measured: float) -> float:
        """The reference [N] for the measured force ``measured`` [N]."""
        r = max(self.value, measured + self.lead)
        r = min(r, self.value + self.rate * self.dt, self.target)
        self.value = r
        return r


def selection_matrices(direction: Vec) -> tuple[FloatArray, FloatArray]:
    """Force and motion selection matrices of a line task frame (7.14-7.16).

    Args:
        direction: pulling direction e [-] (normalised here).

    Returns:
        ``(S_f, S_m)`` with ``S_f = e e^T`` and ``S_m = I - S_f`` (3x3).

    Raises:
        ForceGainsError: on a zero or non-finite direction.
    """
    e = np.asarray(direction, dtype=float)
    n = float(np.linalg.norm(e)) if e.shape == (3,) else 0.0
    if not (n > 1e-12 and math.isfinite(n)):
        raise ForceGainsError("direction", direction, "a finite non-zero 3-vector")
    e = e / n
    sf = np.outer(e, e)
    return sf, np.eye(3) - sf


class HybridCommand(NamedTuple):
    """One output of :class:`HybridForcePositionController`.

    Attributes:
        torque: joint torques [N*m, N*m, N*m, N].
        force: the force command u_f along e [N] (7.22).
        reference: the force reference f_r used [N].
        line_error: distance of the tip from the constraint line [m].
        velocity: measured velocity along e [m/s].
    """

    torque: FloatArray
    force: float
    reference: float
    line_error: float
    velocity: float


class HybridForcePositionController:
    """Tension along a line, position across it (7.11-7.22).

    Args:
        direction: pulling direction e in the base frame [-].
        point: a point of the constraint line in the base frame [m].
        force: the explicit force controller (its dt is the force-loop period).
        params: the robot model used for gravity compensation and kinematics.
        dt: torque-loop period [s]; the force command is updated every
            ``round(force.dt / dt)`` calls and held in between.
        kx: stiffness holding the tip on the line [N/m].
        dx: damping across the line [N*s/m].
        roll: roll angle held [rad].
        kr: roll stiffness [N*m/rad].
        dr: roll damping [N*m*s/rad].
        reference: optional :class:`ModifiedForceReference`; when given, the
            reference passed to :meth:`update` is ignored and this one is used.
        friction: joint friction parameters to compensate (3.43, 5.19); None: no
            compensation. Coulomb friction ``Fc tanh(qdot / smoothing)`` is added.
        viscous: also compensate viscous friction ``Fv qdot``.
        smoothing: velocity scale of the smoothed sign [rad/s or m/s].
        stiction_band: with ``friction``, a force error band [N] outside which the
            static (break-away) friction of the joints at rest is also compensated, in the
            sense each joint must turn for the tip to move along ``+e`` (tension too low)
            or ``-e`` (too high). Without it a joint at rest stays stuck until the force
            command has crossed the whole static-friction window (about +-1.3 N at the
            tip of the EndoBot's first joint at 0.13 m), and the tension is held that far
            from its reference. Inside the band nothing is added: static friction then holds the
            tension reached. None: not compensated at rest.

    Raises:
        ForceGainsError: on a bad direction, negative gains or periods.
    """

    def __init__(
        self,
        direction: Vec,
        point: Vec,
        force: ExplicitForceController,
        params: EndoBotParams | None = None,
        dt: float = 1e-3,
        kx: float = 2000.0,
        dx: float = 40.0,
        roll: float = 0.0,
        kr: float = 0.5,
        dr: float = 0.01,
        reference: ModifiedForceReference | None = None,
        friction: Sequence[FrictionParams] | None = None,
        viscous: bool = False,
        smoothing: float = 0.01,
        stiction_band: float | None = None,
    ) -> None:
        self.s_force, self.s_motion = selection_matrices(direction)
        e = np.asarray(direction, dtype=float)
        self.direction = e / float(np.linalg.norm(e))
        self.point = np.asarray(point, dtype=float).reshape(3)
        self.force = force
        self.params = params
        self.dt = _check("dt", dt, positive=True)
        self.kx = _check("kx", kx)
        self.dx = _check("dx", dx)
        self.kr = _check("kr", kr)
        self.dr = _check("dr", dr)
        self.roll = float(roll)
        self.ramp = reference
        self.decimation = max(1, round(force.dt / self.dt))
        self._tick = 0
        self._uf = 0.0
        self._fr = 0.0
        self._fc = np.array([f.coulomb for f in friction]) if friction is not None else None
        self._fs = np.array([f.static for f in friction]) if friction is not None else None
        self._fv = np.array([f.viscous if viscous else 0.0 for f in friction or ()])
        self.smoothing = _check("smoothing", smoothing, positive=True)
        self.stiction_band = (
            None if stiction_band is None else _check("stiction_band", stiction_band)
        )

    def __repr__(self) -> str:
        e = ", ".join(f"{x:.3g}" for x in self.direction)
        return f"HybridForcePositionController(direction=({e}), force={self.force!r})"

    def reset(self) -> None:
        """Restart the force loop (integral, reference, held command)."""
        self.force.reset()
        if self.ramp is not None:
            self.ramp.reset()
        self._tick = 0
        self._uf = 0.0
        self._fr = 0.0

    def update(self, q: Vec, qd: Vec, measured: float, reference: float) -> HybridCommand:
        """Joint torques for one torque-loop tick.

        Args:
            q: joints (encoders) [rad, rad, rad, m].
            qd: estimated joint velocities [rad/s, rad/s, rad/s, m/s].
            measured: measured tension f_m [N] (e.g. :class:`TensionEstimator`).
            reference: desired tension f_r [N] (ignored with a modified reference).

        Returns:
            The :class:`HybridCommand`.
        """
        qa = np.asarray(q, dtype=float)
        qda = np.asarray(qd, dtype=float)
        jac = endobot.jacobian(qa)
        x = endobot.forward_kinematics(qa).position
        v = jac[:3] @ qda
        e = self.direction
        v_e = float(e @ v)
        if self._tick % self.decimation == 0:
            self._fr = self.ramp.update(measured) if self.ramp is not None else float(reference)
            self._uf = self.force.update(self._fr, measured, v_e)
        self._tick += 1
        across = self.s_motion @ (self.point - x)
        f_task = self.kx * across - self.dx * (self.s_motion @ v) + self._uf * e
        tau = jac[:3].T @ f_task
        tau[2] += self.kr * (self.roll - qa[2]) - self.dr * qda[2]
        tau += endobot.gravity_vector(qa, self.params)
        if self._fc is not None:
            moving = np.tanh(qda / self.smoothing)
            tau += self._fc * moving + self._fv * qda
            error = self._fr - measured
            if self.stiction_band is not None and abs(error) > self.stiction_band:
                # joint rates that move the tip along e (the roll moves no point of it)
                trans = jac[:3][:, _TRANSLATING]
                rates = np.zeros(4)
                rates[_TRANSLATING] = np.linalg.lstsq(trans, e, rcond=None)[0]
                sense = np.tanh(rates * math.copysign(1.0, error) / (0.1 * np.abs(rates).max()))
                tau += self._fs * sense * (1.0 - np.abs(moving))
        return HybridCommand(tau, self._uf, self._fr, float(np.linalg.norm(across)), v_e)
