"""Reachability of a tool-tip target by an EndoBot, without numpy.

Closed-form inverse kinematics of the EndoBot (thesis 3.13-3.17): joints
yaw q1 about x, pitch q2 about y, roll q3 about z, insertion q4 along z, with
the remote centre of motion at the base frame's origin. The forward map is
``r = (s2 q4, -s1 c2 q4, c1 c2 q4)`` (3.13), so ``q4 = |r|`` (3.14),
``q2 = atan2(x, sqrt(y^2 + z^2))`` (3.15 on the c2 >= 0 branch) and
``q1 = atan2(-y, z)`` (3.16). The Jacobian's determinant is ``c2 q4^2`` up to
sign (3.22), singular at ``q2 = +-90 deg`` or ``q4 = 0`` (3.23).

This module uses only :mod:`math` so that ``suture validate`` need not import
numpy; the tests compare it with ``suture_engine.robot.kinematics``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

__all__ = ["DEFAULT_SINGULARITY_MARGIN", "Reach", "base_to_world", "check_reach", "ik"]

DEFAULT_SINGULARITY_MARGIN = math.radians(5.0)
"""Least distance of q2 from +-90 deg accepted when a state gives none [rad]."""

JOINTS = ("yaw", "pitch", "roll", "insertion")


class Reach(NamedTuple):
    """The outcome of a reachability check.

    Attributes:
        q: joints (q1 [rad], q2 [rad], q3 [rad], q4 [m]) of the target.
        problem: ``""`` when reachable, else ``"unreachable"`` or ``"singularity"``.
        reason: a human explanation of the problem.
    """

    q: tuple[float, float, float, float]
    problem: str
    reason: str


def _rpy_matrix(rpy: Sequence[float]) -> list[list[float]]:
    """R = Rz(yaw) Ry(pitch) Rx(roll), fixed axes x, y, z."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]


def world_to_base(
    point: Sequence[float], base_position: Sequence[float], base_rpy: Sequence[float]
) -> tuple[float, float, float]:
    """A world point [m] expressed in the robot's base frame [m]: R^T (p - o)."""
    rot = _rpy_matrix(base_rpy)
    d = [point[i] - base_position[i] for i in range(3)]
    x, y, z = (sum(rot[j][i] * d[j] for j in range(3)) for i in range(3))
    return (x, y, z)


def base_to_world(
    point: Sequence[float], base_position: Sequence[float], base_rpy: Sequence[float]
) -> tuple[float, float, float]:
    """A base-frame point [m] expressed in the world frame [m]: R p + o."""
    rot = _rpy_matrix(base_rpy)
    x, y, z = (sum(rot[i][j] * point[j] for j in range(3)) + base_position[i] for i in range(3))
    return (x, y, z)


def ik(position: Sequence[float], roll: float = 0.0) -> tuple[float, float, float, float]:
    """Joints (q1, q2, q3 [rad], q4 [m]) placing the tool tip at ``position`` [m],
    base frame (3.14-3.17)."""
    x, y, z = (float(v) for v in position)
    q4 = math.sqrt(x * x + y * y + z * z)
    q2 = math.atan2(x, math.hypot(y, z))
    q1 = math.atan2(-y, z) if (y != 0.0 or z != 0.0) else 0.0
    return (q1, q2, float(roll), q4)


def check_reach(
    position: Sequence[float],
    limits: Sequence[tuple[float, float]],
    margin: float = DEFAULT_SINGULARITY_MARGIN,
    roll: float | None = None,
) -> Reach:
    """Whether a base-frame target is inside the joint limits and away from singularities.

    Args:
        position: target (x, y, z) in the base frame [m].
        limits: (low, high) of yaw, pitch, roll [rad] and insertion [m].
        margin: least distance of q2 from +-90 deg [rad] (3.23).
        roll: the tool roll at the target [rad]; ``None`` does not check it.
    """
    q = ik(position, 0.0 if roll is None else roll)
    if q[3] < 1e-6:
        return Reach(
            q, "singularity", "the target is at the remote centre of motion (q4 = 0, 3.23)"
        )
    if math.pi / 2 - abs(q[1]) < margin:
        return Reach(
            q,
            "singularity",
            f"pitch q2 = {math.degrees(q[1]):.1f} deg is within "
            f"{math.degrees(margin):.1f} deg of +-90 deg (3.23)",
        )
    for i, (name, (lo, hi)) in enumerate(zip(JOINTS, limits, strict=True)):
        if i == 2 and roll is None:
            continue
        if not lo <= q[i] <= hi:
            unit, scale = ("m", 1.0) if i == 3 else ("deg", 180.0 / math.pi)
            return Reach(
                q,
                "unreachable",
                f"{name} q{i + 1} = {q[i] * scale:.3g} {unit} is outside "
                f"[{lo * scale:.3g}, {hi * scale:.3g}] {unit} (inverse kinematics 3.14-3.17)",
            )
    return Reach(q, "", "")
