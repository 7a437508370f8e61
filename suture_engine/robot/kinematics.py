"""EndoBot kinematics by the product of exponentials (thesis 3.1-3.23).

Joints: q1 yaw about the base x axis, q2 pitch about the (rotated) y axis,
q3 roll about the tool z axis, q4 insertion along the tool z axis. All joint
axes pass through the remote centre of motion (RCM) at the base origin, so

    R(q) = e^{ĥ1 q1} e^{ĥ2 q2} e^{ĥ3 q3} = Rx(q1) Ry(q2) Rz(q3)          (3.5, 3.11)
    p(q) = q4 * R(q) e_z = q4 (s2, -s1 c2, c1 c2)                        (3.6, 3.12)

The hot functions use :mod:`math` on Python floats (no numpy per call except
the returned arrays, which callers can preallocate with ``out=``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.errors import SutureError

__all__ = [
    "SINGULARITY_MARGIN",
    "ToolPose",
    "UnreachablePose",
    "analytical_jacobian",
    "forward_kinematics",
    "geometric_jacobian",
    "inverse_kinematics",
    "is_singular",
    "jacobian_determinant",
    "manipulability",
    "rotation",
    "task_vector",
    "task_vector_and_jacobian",
]

SINGULARITY_MARGIN = 1e-4
"""Default margin of :func:`is_singular` on |det J| [m^2]."""

FloatArray = NDArray[np.float64]


def _floats(v: Sequence[float] | FloatArray) -> list[float]:
    """Joint values as Python floats (math on them is ~3x faster than on numpy scalars)."""
    return v.tolist() if isinstance(v, np.ndarray) else [float(x) for x in v]


class UnreachablePose(SutureError):
    """A tool pose that inverse kinematics cannot map to joints.

    Attributes:
        position: the requested tool-tip position [m].
        reason: why it is unreachable.
    """

    code = "unreachable-pose"

    def __init__(self, position: tuple[float, float, float], reason: str) -> None:
        x, y, z = position
        super().__init__(f"tool position ({x:.4g}, {y:.4g}, {z:.4g}) m unreachable: {reason}")
        self.position = position
        self.reason = reason


class ToolPose(NamedTuple):
    """Tool configuration x_T = (r_T, φ) of (3.13).

    Attributes:
        position: tool-tip position in the base frame [m], shape (3,).
        roll: roll angle φ = q3 [rad].
    """

    position: FloatArray
    roll: float


def forward_kinematics(q: Sequence[float] | FloatArray) -> ToolPose:
    """Tool-tip position and roll, (3.12)-(3.13).

    Args:
        q: joints (yaw [rad], pitch [rad], roll [rad], insertion [m]).

    Returns:
        The tool pose.
    """
    q1, q2, q3, q4 = _floats(q)
    c2q4 = math.cos(q2) * q4
    return ToolPose(
        np.array((math.sin(q2) * q4, -math.sin(q1) * c2q4, math.cos(q1) * c2q4)), float(q3)
    )


def task_vector(q: Sequence[float] | FloatArray) -> FloatArray:
    """x = k(q) = (x, y, z, φ) of (3.12)-(3.13) as one array [m, m, m, rad].

    The same floating-point operations as :func:`forward_kinematics`, without the
    :class:`ToolPose` (the per-tick form of the resolved-rate skills).

    Args:
        q: joints (yaw [rad], pitch [rad], roll [rad], insertion [m]).

    Returns:
        The task vector, shape (4,).
    """
    q1, q2, q3, q4 = _floats(q)
    c2q4 = math.cos(q2) * q4
    return np.array((math.sin(q2) * q4, -math.sin(q1) * c2q4, math.cos(q1) * c2q4, q3))


def _fill_jacobian(
    j: FloatArray, q4: float, c1: float, s1: float, c2: float, s2: float
) -> FloatArray:
    """Write the analytical Jacobian (3.21) into ``j`` from the insertion [m] and the
    cosines and sines of the yaw and pitch; returns ``j``."""
    j[0, 0] = 0.0
    j[0, 1] = q4 * c2
    j[0, 2] = 0.0
    j[0, 3] = s2
    j[1, 0] = -q4 * c1 * c2
    j[1, 1] = q4 * s1 * s2
    j[1, 2] = 0.0
    j[1, 3] = -s1 * c2
    j[2, 0] = -q4 * s1 * c2
    j[2, 1] = -q4 * c1 * s2
    j[2, 2] = 0.0
    j[2, 3] = c1 * c2
    j[3, 0] = 0.0
    j[3, 1] = 0.0
    j[3, 2] = 1.0
    j[3, 3] = 0.0
    return j


def task_vector_and_jacobian(
    q: Sequence[float] | FloatArray, out: FloatArray | None = None
) -> tuple[FloatArray, FloatArray]:
    """k(q) (3.13) and the analytical Jacobian (3.21) from one set of sines and cosines.

    Bit for bit :func:`task_vector` and :func:`analytical_jacobian` (same operations).

    Args:
        q: joints [rad, rad, rad, m].
        out: optional preallocated (4, 4) array for the Jacobian.

    Returns:
        (x [m, m, m, rad] shape (4,), J shape (4, 4)).
    """
    q1, q2, q3, q4 = _floats(q)
    c1, s1 = math.cos(q1), math.sin(q1)
    c2, s2 = math.cos(q2), math.sin(q2)
    c2q4 = c2 * q4
    x = np.array((s2 * q4, -s1 * c2q4, c1 * c2q4, q3))
    j = _fill_jacobian(np.zeros((4, 4)) if out is None else out, q4, c1, s1, c2, s2)
    return x, j


def rotation(q: Sequence[float] | FloatArray) -> FloatArray:
    """Tool orientation R_0T(q) = Rx(q1) Ry(q2) Rz(q3), (3.11).

    Args:
        q: joints [rad, rad, rad, m].

    Returns:
        The 3x3 rotation matrix of the tool frame in the base frame.
    """
    q1, q2, q3 = float(q[0]), float(q[1]), float(q[2])
    c1, s1 = math.cos(q1), math.sin(q1)
    c2, s2 = math.cos(q2), math.sin(q2)
    c3, s3 = math.cos(q3), math.sin(q3)
    return np.array(
        (
            (c2 * c3, -c2 * s3, s2),
            (s1 * s2 * c3 + c1 * s3, -s1 * s2 * s3 + c1 * c3, -s1 * c2),
            (-c1 * s2 * c3 + s1 * s3, c1 * s2 * s3 + s1 * c3, c1 * c2),
        )
    )


def inverse_kinematics(
    position: Sequence[float] | FloatArray,
    roll: float,
    min_insertion: float = 1e-9,
) -> FloatArray:
    """Joints for a tool-tip position and roll, (3.14)-(3.17).

    The branch with cos(q2) >= 0 is returned: q4 = |r|, q2 = atan2(x, sqrt(y^2 + z^2)),
    q1 = atan2(-y, z), q3 = φ. (3.15) as printed, tan q2 = x c1 / z, is the same
    angle wherever c1 > 0.

    Args:
        position: tool-tip position (x, y, z) in the base frame [m].
        roll: roll angle φ [rad].
        min_insertion: smallest |r| [m] accepted; at the RCM yaw and pitch are undefined.

    Returns:
        Joints (yaw [rad], pitch [rad], roll [rad], insertion [m]), shape (4,).

    Raises:
        UnreachablePose: if the position is at the RCM (singular, (3.23)) or not finite.
    """
    x, y, z = (float(v) for v in position)
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z) and math.isfinite(roll)):
        raise UnreachablePose((x, y, z), "not finite")
    q4 = math.sqrt(x * x + y * y + z * z)
    if q4 < min_insertion:
        raise UnreachablePose((x, y, z), "tool tip at the remote centre of motion (q4 = 0)")
    q2 = math.atan2(x, math.hypot(y, z))
    q1 = math.atan2(-y, z) if (y != 0.0 or z != 0.0) else 0.0
    return np.array((q1, q2, float(roll), q4))


def analytical_jacobian(
    q: Sequence[float] | FloatArray, out: FloatArray | None = None
) -> FloatArray:
    """Analytical Jacobian J_a = ∂(r_T, φ)/∂q, (3.20)-(3.21), re-derived.

    Columns: ∂r/∂q1 = q4 (0, -c1 c2, -s1 c2), ∂r/∂q2 = q4 (c2, s1 s2, -c1 s2),
    ∂r/∂q3 = 0, ∂r/∂q4 = (s2, -s1 c2, c1 c2); the last row is ∂φ/∂q = (0, 0, 1, 0).

    Args:
        q: joints [rad, rad, rad, m].
        out: optional preallocated (4, 4) array to fill.

    Returns:
        The 4x4 Jacobian (rows x [m], y [m], z [m], roll [rad]).
    """
    q1, q2, _, q4 = _floats(q)
    c1, s1 = math.cos(q1), math.sin(q1)
    c2, s2 = math.cos(q2), math.sin(q2)
    return _fill_jacobian(np.zeros((4, 4)) if out is None else out, q4, c1, s1, c2, s2)


def geometric_jacobian(q: Sequence[float] | FloatArray) -> FloatArray:
    """Geometric Jacobian in the base frame, (3.18)-(3.19), rows ordered as (3.19).

    Rows 0-2: linear velocity of the tool tip [m/s]; rows 3-5: angular velocity of
    the tool [rad/s]. Angular columns: h1 = e_x, R01 h2 = (0, c1, s1),
    R02 h3 = (s2, -s1 c2, c1 c2), 0 for the prismatic joint.

    Args:
        q: joints [rad, rad, rad, m].

    Returns:
        The 6x4 Jacobian.
    """
    q1, q2 = float(q[0]), float(q[1])
    c1, s1 = math.cos(q1), math.sin(q1)
    c2, s2 = math.cos(q2), math.sin(q2)
    j = np.zeros((6, 4))
    analytical_jacobian(q, out=j[:4])
    j[3] = (1.0, 0.0, s2, 0.0)
    j[4] = (0.0, c1, -s1 * c2, 0.0)
    j[5] = (0.0, s1, c1 * c2, 0.0)
    return j


def jacobian_determinant(q: Sequence[float] | FloatArray) -> float:
    """det J_a(q) = -c2 q4^2 [m^2]; (3.22) prints its magnitude c2 q4^2.

    Args:
        q: joints [rad, rad, rad, m].

    Returns:
        The determinant of the analytical Jacobian.
    """
    q4 = float(q[3])
    return -math.cos(float(q[1])) * q4 * q4


def manipulability(q: Sequence[float] | FloatArray) -> float:
    """Yoshikawa's measure sqrt(det(J_a J_a^T)) = |c2| q4^2 [m^2].

    Args:
        q: joints [rad, rad, rad, m].

    Returns:
        The manipulability (0 at the singularities (3.23)).
    """
    return abs(jacobian_determinant(q))


def is_singular(q: Sequence[float] | FloatArray, margin: float = SINGULARITY_MARGIN) -> bool:
    """Whether q is within ``margin`` of a singularity, (3.22)-(3.23).

    The Jacobian loses rank at q2 = ±90° or q4 = 0. The test is |c2| q4^2 < margin.

    Args:
        q: joints [rad, rad, rad, m].
        margin: threshold on |det J_a| [m^2].

    Returns:
        True when near-singular.
    """
    return manipulability(q) < margin
