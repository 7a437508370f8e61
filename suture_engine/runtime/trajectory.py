"""Smooth point-to-point trajectories and frame helpers for the motion skills.

The minimum-jerk (quintic) profile from rest to rest,
``s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5`` with ``tau = t / T``, has zero
velocity and acceleration at both ends; its peak rate is ``1.875 / T`` at
``tau = 1/2``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "MinJerk",
    "MinJerkSample",
    "min_jerk_duration",
    "rpy_matrix",
    "tool_tip_world",
    "world_to_base",
]

FloatArray = NDArray[np.float64]

PEAK_RATE = 1.875
"""Peak of ds/dtau of the minimum-jerk profile."""


class MinJerkSample(NamedTuple):
    """One sample of a trajectory.

    Attributes:
        q: position [rad or m].
        qd: velocity [rad/s or m/s].
        done: True once t >= T.
    """

    q: FloatArray
    qd: FloatArray
    done: bool


class MinJerk:
    """Rest-to-rest quintic from ``q0`` to ``q1`` in ``duration`` [s].

    Args:
        q0: start [rad or m].
        q1: goal [rad or m].
        duration: T [s], > 0.
    """

    def __init__(
        self, q0: Sequence[float] | FloatArray, q1: Sequence[float] | FloatArray, duration: float
    ) -> None:
        if not duration > 0.0:
            raise ValueError("duration must be positive")
        self.q0 = np.array(q0, dtype=np.float64)
        self.q1 = np.array(q1, dtype=np.float64)
        self.delta = self.q1 - self.q0
        self.duration = float(duration)

    def __call__(self, t: float) -> MinJerkSample:
        """The sample at time ``t`` [s] after the start (clamped to [0, T])."""
        tau = min(max(t / self.duration, 0.0), 1.0)
        s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
        ds = 30.0 * tau * tau * (1.0 - tau) ** 2 / self.duration
        return MinJerkSample(self.q0 + s * self.delta, ds * self.delta, t >= self.duration)


def min_jerk_duration(distance: float, peak_speed: float, minimum: float = 0.05) -> float:
    """Duration [s] whose minimum-jerk peak speed over ``distance`` [m] is ``peak_speed`` [m/s]."""
    if peak_speed <= 0.0:
        raise ValueError("peak_speed must be positive")
    return max(PEAK_RATE * abs(distance) / peak_speed, minimum)


def rpy_matrix(rpy: Sequence[float]) -> tuple[float, ...]:
    """Row-major R = Rz(yaw) Ry(pitch) Rx(roll) of roll-pitch-yaw angles [rad]."""
    r, p, y = (float(a) for a in rpy)
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return (
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    )


def _pose(base: Any) -> tuple[FloatArray, FloatArray]:
    if base is None:
        return np.zeros(3), np.eye(3)
    return np.asarray(base[0], dtype=np.float64), np.asarray(base[1], dtype=np.float64).reshape(
        3, 3
    )


def tool_tip_world(q: Sequence[float] | FloatArray, base: Any = None) -> FloatArray:
    """Tool-tip position in the world frame [m]: ``p_base + R_base p(q)`` (3.12).

    Args:
        q: joints [rad, rad, rad, m].
        base: (base position [m], row-major 3x3 rotation) or None (identity).
    """
    from suture_engine.robot.kinematics import forward_kinematics

    pos, rot = _pose(base)
    return pos + rot @ np.asarray(forward_kinematics(q).position)


def world_to_base(point: Sequence[float] | FloatArray, base: Any = None) -> FloatArray:
    """A world point [m] in the robot's base frame: ``R_base^T (p - p_base)``."""
    pos, rot = _pose(base)
    return rot.T @ (np.asarray(point, dtype=np.float64) - pos)
