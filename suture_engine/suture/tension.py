"""Suture tension from the base force/torque sensor (thesis 7.2.2, (7.5)-(7.10)).

The sensor between the mount and the robot's static frame reads the wrench the
mount exerts on the robot, ``F_s = (f, m)`` (force [N], moment about the remote
centre of motion O [N*m], base-frame coordinates). It is the sum (7.6)

    F_s = F_m + F_g + F_b

of a motion-induced wrench ``F_m`` (neglected: tension is regulated at low
speed), the configuration-dependent gravity wrench ``F_g(q)`` and the wrench
``F_b`` due to the environment. In static equilibrium the mount carries the
weight and the external load, so ``F_g(q) = -(sum_i m_i g, sum_i c_i(q) x m_i g)``
with ``c_i(q)`` the centres of mass of the moving links (and of the static
frame above the sensor, whose constant part a tare can absorb instead), and
gravity compensation is (7.7) ``F_b = F_s - F_g``.

The load the environment exerts on the robot, about O, is ``-F_b``. The
adjoint transform (7.8)-(7.9) moves a wrench from O to the tool tip ``p(q)``
(moment ``m_tip = m_O - p x f``) and rotates it into the tool frame with
``R(q)^T``. A suture holds the tip with a pure force ``f = T u`` along the
unit vector ``u`` from the tip towards the anchor, so the tension is
``T = f . u = -f . e`` with ``e = -u`` the direction the robot pulls in, and the
moment left at the tip measures how far the load is from a pure tip force.

Only the robot's model (link masses and centres of mass, kinematics) and the
measurements (encoders, base wrench) are used: no simulator ground truth.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.errors import InvalidValue
from suture_engine.robot.params import E1, EndoBotParams

__all__ = [
    "TensionEstimate",
    "TensionEstimator",
    "TensionEstimatorError",
    "gravity_wrench",
    "mounted_estimator",
    "tip_wrench",
    "wrench_transform",
]

FloatArray = NDArray[np.float64]
Vec = Sequence[float] | FloatArray


class TensionEstimatorError(InvalidValue):
    """A tension estimator configured or fed with impossible values.

    Attributes:
        name: the offending argument.
        value: its value.
    """


def _cross(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


def _frames(q: Vec) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """The z axes of the yaw, pitch and roll/insertion link frames (3.11)."""
    q1, q2 = float(q[0]), float(q[1])
    c1, s1 = math.cos(q1), math.sin(q1)
    c2, s2 = math.cos(q2), math.sin(q2)
    z1 = (0.0, -s1, c1)  # Rx(q1) e_z
    z2 = (s2, -s1 * c2, c1 * c2)  # Rx(q1) Ry(q2) e_z; Rz(q3) leaves it unchanged
    return z1, z2, z2


def gravity_wrench(
    q: Vec,
    params: EndoBotParams | None = None,
    static_mass: float = 0.0,
    static_com: Vec = (0.0, 0.0, 0.0),
) -> FloatArray:
    """Sensor reading ``F_g(q)`` due to gravity alone, robot at rest (7.6).

    Args:
        q: joints [rad, rad, rad, m].
        params: the robot's model (link masses, centres of mass, gravity in the
            base frame); None: E1.
        static_mass: mass of the static frame between sensor and yaw joint [kg].
        static_com: its centre of mass in the base frame [m].

    Returns:
        ``(f [N], m [N*m])`` about O in base coordinates, shape (6,).
    """
    prm = params or E1
    g = prm.gravity
    b1, b2, b3, b4 = prm.bodies
    z1, z2, z3 = _frames(q)
    q4 = float(q[3])
    cs = static_com
    mass = static_mass + b1.mass + b2.mass + b3.mass + b4.mass
    # first mass moment sum_i m_i c_i [kg*m]
    h = [
        static_mass * float(cs[k])
        + b1.mass * b1.com_z * z1[k]
        + b2.mass * b2.com_z * z2[k]
        + b3.mass * b3.com_z * z3[k]
        + b4.mass * (q4 + b4.com_z) * z3[k]
        for k in range(3)
    ]
    moment = _cross(h, g)
    return -np.array((mass * g[0], mass * g[1], mass * g[2], *moment))


def wrench_transform(wrench: Vec, rotation: FloatArray, position: Vec) -> FloatArray:
    """Adjoint transform of a wrench to another frame (7.8)-(7.9).

    Args:
        wrench: ``(f [N], m [N*m])`` about the origin O, in O's coordinates.
        rotation: orientation R of the new frame E in O's coordinates.
        position: origin p of E in O's coordinates [m].

    Returns:
        The same wrench ``(R^T f, R^T (m - p x f))`` about E's origin, in E's
        coordinates (the thesis orders wrenches (moment, force), (7.5); the
        map is the same).
    """
    w = np.asarray(wrench, dtype=float)
    f = w[:3]
    m = w[3:] - np.cross(np.asarray(position, dtype=float), f)
    rt = np.asarray(rotation, dtype=float).T
    return np.concatenate((rt @ f, rt @ m))


def tip_wrench(
    sensor: Vec,
    q: Vec,
    params: EndoBotParams | None = None,
    offset: Vec | None = None,
) -> FloatArray:
    """The environment's wrench on the tool, at the tool tip, base coordinates (7.7, 7.9).

    Args:
        sensor: base sensor reading ``(f [N], m [N*m])`` about O.
        q: joints [rad, rad, rad, m] (encoders).
        params: the robot's model; None: E1.
        offset: constant wrench added to ``F_g`` (a tare; static frame, sensor bias).

    Returns:
        ``(f [N], m_tip [N*m])``: force on the tool and moment about its tip.
    """
    fg = gravity_wrench(q, params)
    if offset is not None:
        fg = fg + np.asarray(offset, dtype=float)
    load = fg - np.asarray(sensor, dtype=float)  # -F_b (7.7)
    q1, q2, q4 = float(q[0]), float(q[1]), float(q[3])
    c2q4 = math.cos(q2) * q4
    tip = (math.sin(q2) * q4, -math.sin(q1) * c2q4, math.cos(q1) * c2q4)  # (3.12)
    return wrench_transform(load, np.eye(3), tip)


class TensionEstimate(NamedTuple):
    """One output of :class:`TensionEstimator`.

    Attributes:
        tension: suture tension T along the pulling direction [N] (filtered).
        force: filtered force of the environment on the tool tip, base frame [N].
        moment: filtered moment about the tip, base frame [N*m] (~0 for a suture).
    """

    tension: float
    force: FloatArray
    moment: FloatArray


class TensionEstimator:
    """Stateful, low-pass filtered tension estimate from the base sensor (7.6)-(7.10).

    Each :meth:`update` compensates gravity with the model and the encoders,
    neglects the motion wrench, moves the load to the tool tip and filters it
    with a first-order low-pass (one IIR step, cheap at 1 kHz).

    Args:
        direction: pulling direction e in the base frame (normalised here) [-].
        params: the robot's model; None: E1.
        dt: sample period [s].
        cutoff: low-pass cut-off frequency [Hz]; ``math.inf`` disables filtering.
        offset: constant wrench added to the gravity model [N, N*m] (see :meth:`tare`).

    Raises:
        TensionEstimatorError: on a zero direction or a non-positive period or cut-off.
    """

    def __init__(
        self,
        direction: Vec,
        params: EndoBotParams | None = None,
        dt: float = 1e-3,
        cutoff: float = 30.0,
        offset: Vec | None = None,
    ) -> None:
        if not (dt > 0.0 and math.isfinite(dt)):
            raise TensionEstimatorError("dt", dt, "finite and > 0")
        if not cutoff > 0.0:
            raise TensionEstimatorError("cutoff", cutoff, "> 0")
        self.params = params or E1
        self.dt = dt
        self.cutoff = cutoff
        self.direction = self._unit(direction)
        tau = 0.0 if math.isinf(cutoff) else 1.0 / (2.0 * math.pi * cutoff)
        self._alpha = dt / (tau + dt)
        self.offset = np.zeros(6) if offset is None else np.asarray(offset, dtype=float).copy()
        self._state: FloatArray | None = None

    @staticmethod
    def _unit(v: Vec) -> FloatArray:
        d = np.asarray(v, dtype=float)
        n = float(np.linalg.norm(d)) if d.shape == (3,) else 0.0
        if not (n > 1e-12 and math.isfinite(n)):
            raise TensionEstimatorError("direction", v, "a finite non-zero 3-vector")
        return d / n

    def __repr__(self) -> str:
        e = ", ".join(f"{x:.3g}" for x in self.direction)
        return f"TensionEstimator(direction=({e}), cutoff={self.cutoff:g} Hz, dt={self.dt:g} s)"

    def set_direction(self, direction: Vec) -> None:
        """Change the pulling direction e (e.g. the next throw, (7.3))."""
        self.direction = self._unit(direction)

    def tare(self, sensor: Vec, q: Vec) -> FloatArray:
        """Zero the estimate on a reading taken at rest with the suture slack.

        The difference between the reading and the gravity model becomes the
        offset: it absorbs the static frame's weight and the sensor's bias.

        Args:
            sensor: base sensor reading [N, N*m].
            q: joints at that reading [rad, rad, rad, m].

        Returns:
            The new offset [N, N*m].
        """
        self.offset = np.asarray(sensor, dtype=float) - gravity_wrench(q, self.params)
        self._state = None
        return self.offset.copy()

    def reset(self) -> None:
        """Forget the filter state (the next update starts from its own value)."""
        self._state = None

    def update(self, sensor: Vec, q: Vec) -> TensionEstimate:
        """One estimate from one base reading and the encoders.

        Args:
            sensor: base sensor reading ``(f [N], m [N*m])`` about O.
            q: joints [rad, rad, rad, m].

        Returns:
            The filtered :class:`TensionEstimate`.
        """
        w = tip_wrench(sensor, q, self.params, self.offset)
        if self._state is None:
            self._state = w
        else:
            self._state = self._state + self._alpha * (w - self._state)
        s = self._state
        force = s[:3]
        tension = -float(force @ self.direction)
        return TensionEstimate(tension, force.copy(), s[3:].copy())


def mounted_estimator(
    base_rotation: Vec | None,
    direction_world: Vec,
    start_wrench: Vec,
    q0: Vec,
    dt: float,
    cutoff: float,
) -> tuple[TensionEstimator, EndoBotParams]:
    """A tension estimator for a robot mounted with ``base_rotation``, tared at rest.

    Gravity is expressed in the base frame (the model's parameters, E1, are for a base
    with z up), the pulling direction is turned into the base frame, and the estimator is
    tared on ``start_wrench`` at the joints ``q0`` (the strand slack, 7.5.2).

    Args:
        base_rotation: row-major 3x3 rotation of the base in the world (None: identity).
        direction_world: pulling direction e in the world frame [-].
        start_wrench: the base sensor's reading at rest [N, N*m].
        q0: the joints of that reading [rad, rad, rad, m].
        dt: sample period [s].
        cutoff: low-pass cut-off frequency [Hz].

    Returns:
        The estimator and the robot's parameters with gravity in its base frame.
    """
    import dataclasses

    rot = np.eye(3) if base_rotation is None else np.asarray(base_rotation, float).reshape(3, 3)
    g = rot.T @ np.array([0.0, 0.0, -9.81])
    prm = dataclasses.replace(E1, gravity=(float(g[0]), float(g[1]), float(g[2])))
    est = TensionEstimator(rot.T @ np.asarray(direction_world, float), prm, dt=dt, cutoff=cutoff)
    est.tare(np.asarray(start_wrench, float), np.asarray(q0, float))
    return est, prm
