"""Helpers shared by the suturing skills: tool-tip paths through IK, joint limits, holding.

A :class:`ToolPath` maps a path parameter ``s`` in [0, 1] to joints through the
closed-form inverse kinematics (3.14-3.17) of a world-frame tool-tip point, and
times ``s`` with the rest-to-rest minimum-jerk profile of
:mod:`suture_engine.runtime.trajectory`. Velocities are ``dq/ds * ds/dt`` with
``dq/ds`` the slope of the tabulated path.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "JointBox",
    "ToolPath",
    "duration_for",
    "hold_command",
    "ik_world",
    "joint_box",
    "tip_tolerance",
    "tip_world",
    "unwrap_roll",
]

FloatArray = NDArray[np.float64]

PEAK_RATE = 1.875
"""Peak of ds/dtau of the minimum-jerk profile (see :mod:`suture_engine.runtime.trajectory`)."""


class JointBox(NamedTuple):
    """Joint limits of one robot.

    Attributes:
        lower: lower limits [rad, rad, rad, m].
        upper: upper limits [rad, rad, rad, m].
    """

    lower: FloatArray
    upper: FloatArray

    def violation(self, q: FloatArray, tol: float = 1e-9) -> str:
        """Which joint leaves the box (empty when inside)."""
        names = ("yaw", "pitch", "roll", "insertion")
        for i, name in enumerate(names):
            if q[i] < self.lower[i] - tol or q[i] > self.upper[i] + tol:
                return f"{name} {q[i]:.4g} outside [{self.lower[i]:.4g}, {self.upper[i]:.4g}]"
        return ""


def joint_box(ctx: Any, robot: str) -> JointBox | None:
    """The scene's joint limits of ``robot`` (None without a scene model)."""
    scene = getattr(ctx, "scene", None)
    robots = getattr(scene, "robots", None)
    if not robots or robot not in robots:
        return None
    jl = robots[robot].joint_limits
    return JointBox(
        np.array([jl.yaw[0], jl.pitch[0], jl.roll[0], jl.insertion[0]], dtype=np.float64),
        np.array([jl.yaw[1], jl.pitch[1], jl.roll[1], jl.insertion[1]], dtype=np.float64),
    )


def tip_world(q: Any, base: Any) -> FloatArray:
    """Tool-tip position in the world frame [m] (3.12)."""
    from suture_engine.runtime.trajectory import tool_tip_world

    return tool_tip_world(q, base)


def ik_world(point: Any, roll: float, base: Any) -> FloatArray:
    """Joints [rad, rad, rad, m] that put the tool tip at a world point (3.14-3.17)."""
    from suture_engine.robot.kinematics import inverse_kinematics
    from suture_engine.runtime.trajectory import world_to_base

    return inverse_kinematics(world_to_base(point, base), roll)


def unwrap_roll(roll: float, reference: float) -> float:
    """``roll`` [rad] shifted by a multiple of 2 pi to lie within pi of ``reference``."""
    return reference + math.remainder(roll - reference, 2.0 * math.pi)


def hold_command(robot: str, q: Any, tool: Any = None) -> Any:
    """A :class:`Command` holding ``robot`` at joints ``q`` with an optional tool command."""
    from suture_engine.runtime.observation import Command, RobotCommand

    return Command({robot: RobotCommand.position(q, tool=tool)})


class ToolPath:
    """Joints along a path ``q(s)``, s in [0, 1], timed by a minimum-jerk profile.

    ``q(s)`` is tabulated once, one sample per :attr:`SAMPLE_S` [s] of motion
    (between :attr:`MIN_SAMPLES` and :attr:`MAX_SAMPLES`), and interpolated
    linearly in ``s`` each tick, so a tick costs no inverse kinematics.

    Args:
        joints_at: ``s -> q`` [rad, rad, rad, m].
        duration: T [s], > 0.
    """

    SAMPLE_S = 0.004
    """Motion time per table sample [s]."""
    MIN_SAMPLES = 50
    """Fewest table intervals."""
    MAX_SAMPLES = 4000
    """Most table intervals."""

    def __init__(self, joints_at: Callable[[float], FloatArray], duration: float) -> None:
        if not duration > 0.0:
            raise ValueError("duration must be positive")
        self.joints_at = joints_at
        self.duration = float(duration)
        n = int(min(max(math.ceil(duration / self.SAMPLE_S), self.MIN_SAMPLES), self.MAX_SAMPLES))
        self._n = n
        self.table = np.array([joints_at(k / n) for k in range(n + 1)], dtype=np.float64)
        self._slopes = np.diff(self.table, axis=0) * n

    def progress(self, t: float) -> tuple[float, float]:
        """Path parameter s [-] and its rate ds/dt [1/s] at ``t`` [s] after the start."""
        tau = min(max(t / self.duration, 0.0), 1.0)
        s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
        ds = 30.0 * tau * tau * (1.0 - tau) ** 2 / self.duration
        return s, ds

    def sample(self, t: float) -> tuple[FloatArray, FloatArray, bool]:
        """Joints [rad, m], joint velocities [rad/s, m/s] and whether the path is over."""
        s, ds = self.progress(t)
        x = s * self._n
        i = min(int(x), self._n - 1)
        slope = self._slopes[i]
        q = self.table[i] + (x - i) / self._n * slope
        return q, slope * ds, t >= self.duration

    def first_violation(self, box: JointBox | None) -> str:
        """The first joint-limit violation along the path (empty when none)."""
        if box is None:
            return ""
        for k, q in enumerate(self.table):
            why = box.violation(q)
            if why:
                return f"at s = {k / self._n:.2f}: {why}"
        return ""


def duration_for(length: float, speed: float, minimum: float = 0.1) -> float:
    """Minimum-jerk duration [s] whose peak rate over ``length`` is ``speed``."""
    return max(PEAK_RATE * abs(length) / speed, minimum)


def tip_tolerance(params: Any, default: float) -> float:
    """The arrival tolerance of a tool-tip path [m]: ``params.tolerance`` when set.

    Args:
        params: a skill's parameters with an optional ``tolerance`` [m].
        default: the skill's own tolerance [m], used when ``tolerance`` is None.
    """
    tolerance = getattr(params, "tolerance", None)
    return default if tolerance is None else float(tolerance)
