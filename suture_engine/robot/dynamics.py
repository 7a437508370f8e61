"""EndoBot rigid-body dynamics M(q) q̈ + C(q, q̇) q̇ + G(q) = τ, derived (3.24-3.41).

Derivation (re-done; the printed (3.38)-(3.41) are garbled). Four bodies hang
from the RCM: the yaw arch (turns with q1), the pitch arch (q1, q2), the roll
sleeve (q1-q3) and the insertion body (q1-q4, sliding along the tool axis).
Each has its centre of mass on its own z axis at l_i (the insertion body at
q4 + l4) and a diagonal inertia at the COM; sleeve and insertion body are
symmetric about the tool axis. With ω expressed in each body frame,

    yaw:    ω = (q̇1, 0, 0)
    pitch:  ω = (c2 q̇1, q̇2, s2 q̇1)
    tool:   ωx^2 + ωy^2 = c2^2 q̇1^2 + q̇2^2,  ωz = s2 q̇1 + q̇3

the kinetic energy (3.36) is T = ½ q̇ᵀ M q̇ with, in the base parameters θ of
:class:`~suture_engine.robot.params.DynamicCoefficients` and
a(q4) = 2 h4 q4 + m4 q4^2,

    M11 = I1 - δ s2^2 + a c2^2     M13 = I3 s2     M22 = I2 + a
    M33 = I3                      M44 = m4        (all others 0).

The potential (3.37) with gravity g (base frame) is P = -Σ m_i gᵀ p_ci, and
G = ∂P/∂q (3.31). C is built from the Christoffel symbols of M, so that
Ṁ - 2C is skew-symmetric (3.33). Everything is linear in θ: τ = Y(q, q̇, q̈) θ (3.34).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from suture_engine.robot.params import DynamicCoefficients

__all__ = [
    "N_THETA",
    "coriolis_matrix",
    "coriolis_vector",
    "gravity_floats",
    "gravity_vector",
    "inverse_dynamics",
    "mass_matrix",
    "mass_matrix_inverse",
    "regressor",
]

FloatArray = NDArray[np.float64]
Vec = Sequence[float] | FloatArray
Gravity = tuple[float, float, float]


def _floats(v: Sequence[float] | FloatArray) -> list[float]:
    """Joint values as Python floats (math on them is ~3x faster than on numpy scalars)."""
    return v.tolist() if isinstance(v, np.ndarray) else [float(x) for x in v]


N_THETA = 8
"""Number of base dynamic parameters θ."""


def mass_matrix(q: Vec, th: DynamicCoefficients, out: FloatArray | None = None) -> FloatArray:
    """Mass-inertia matrix M(q) (3.38), derived from (3.36).

    Args:
        q: joints [rad, rad, rad, m].
        th: base dynamic parameters θ.
        out: optional preallocated (4, 4) array.

    Returns:
        The symmetric positive definite 4x4 M(q) [kg*m^2, kg*m, kg].
    """
    _, q2, _, q4 = _floats(q)
    c2, s2 = math.cos(q2), math.sin(q2)
    a = (2.0 * th.h4 + th.m4 * q4) * q4
    m = np.zeros((4, 4)) if out is None else out
    if out is not None:
        m.fill(0.0)
    m[0, 0] = th.i1 - th.delta * s2 * s2 + a * c2 * c2
    m[0, 2] = m[2, 0] = th.i3 * s2
    m[1, 1] = th.i2 + a
    m[2, 2] = th.i3
    m[3, 3] = th.m4
    return m


def mass_matrix_inverse(q: Vec, th: DynamicCoefficients) -> list[list[float]]:
    """M(q)⁻¹ in closed form, using the structure of (3.38): only joints 1 and 3 couple.

    Args:
        q: joints [rad, rad, rad, m].
        th: base dynamic parameters θ.

    Returns:
        4x4 inverse as nested Python lists (cheap to index in a 1 kHz loop).
    """
    _, q2, _, q4 = _floats(q)
    c2, s2 = math.cos(q2), math.sin(q2)
    a = (2.0 * th.h4 + th.m4 * q4) * q4
    m11 = th.i1 - th.delta * s2 * s2 + a * c2 * c2
    m13 = th.i3 * s2
    det = m11 * th.i3 - m13 * m13
    i13 = -m13 / det
    return [
        [th.i3 / det, 0.0, i13, 0.0],
        [0.0, 1.0 / (th.i2 + a), 0.0, 0.0],
        [i13, 0.0, m11 / det, 0.0],
        [0.0, 0.0, 0.0, 1.0 / th.m4],
    ]


def _partials(q: Vec, th: DynamicCoefficients) -> tuple[float, float, float, float]:
    """Non-zero partials of M: ∂M11/∂q2, ∂M11/∂q4, ∂M13/∂q2, ∂M22/∂q4."""
    _, q2, _, q4 = _floats(q)
    c2, s2 = math.cos(q2), math.sin(q2)
    a = (2.0 * th.h4 + th.m4 * q4) * q4
    da = 2.0 * (th.h4 + th.m4 * q4)
    return -2.0 * (th.delta + a) * s2 * c2, da * c2 * c2, th.i3 * c2, da


def coriolis_matrix(q: Vec, qd: Vec, th: DynamicCoefficients) -> FloatArray:
    """Coriolis/centrifugal matrix C(q, q̇) from the Christoffel symbols of M.

    C_kj = Σ_i ½ (∂M_kj/∂q_i + ∂M_ki/∂q_j - ∂M_ij/∂q_k) q̇_i, which makes Ṁ - 2C
    skew-symmetric (3.33).

    Args:
        q: joints [rad, rad, rad, m].
        qd: joint velocities [rad/s, rad/s, rad/s, m/s].
        th: base dynamic parameters θ.

    Returns:
        The 4x4 C(q, q̇).
    """
    p12, p14, p32, p24 = _partials(q, th)
    v1, v2, v3, v4 = _floats(qd)
    c = np.zeros((4, 4))
    c[0, 0] = 0.5 * (p12 * v2 + p14 * v4)
    c[0, 1] = 0.5 * (p12 * v1 + p32 * v3)
    c[0, 2] = 0.5 * p32 * v2
    c[0, 3] = 0.5 * p14 * v1
    c[1, 0] = -0.5 * (p12 * v1 + p32 * v3)
    c[1, 1] = 0.5 * p24 * v4
    c[1, 2] = -0.5 * p32 * v1
    c[1, 3] = 0.5 * p24 * v2
    c[2, 0] = 0.5 * p32 * v2
    c[2, 1] = 0.5 * p32 * v1
    c[3, 0] = -0.5 * p14 * v1
    c[3, 1] = -0.5 * p24 * v2
    return c


def coriolis_vector(q: Vec, qd: Vec, th: DynamicCoefficients) -> FloatArray:
    """C(q, q̇) q̇ (3.40), re-derived.

    Args:
        q: joints [rad, rad, rad, m].
        qd: joint velocities [rad/s, rad/s, rad/s, m/s].
        th: base dynamic parameters θ.

    Returns:
        The Coriolis and centrifugal torques [N*m, N*m, N*m, N], shape (4,).
    """
    p12, p14, p32, p24 = _partials(q, th)
    v1, v2, v3, v4 = _floats(qd)
    return np.array(
        (
            p12 * v1 * v2 + p14 * v1 * v4 + p32 * v2 * v3,
            -0.5 * p12 * v1 * v1 - p32 * v1 * v3 + p24 * v2 * v4,
            p32 * v1 * v2,
            -0.5 * (p14 * v1 * v1 + p24 * v2 * v2),
        )
    )


def _gravity_terms(q: Vec, g: Gravity) -> tuple[float, float, float]:
    """w1 = -gᵀ ∂(R e_z)/∂q1 / c2 ... helpers: (c1 gy + s1 gz, gᵀ ∂u/∂q2, gᵀ u)."""
    q1, q2, _, _ = _floats(q)
    return _gravity_terms_of(q1, q2, g)


def _gravity_terms_of(q1: float, q2: float, g: Gravity) -> tuple[float, float, float]:
    """:func:`_gravity_terms` from the two joint angles that matter [rad]."""
    c1, s1 = math.cos(q1), math.sin(q1)
    c2, s2 = math.cos(q2), math.sin(q2)
    gx, gy, gz = g
    w1 = c1 * gy + s1 * gz
    w2 = gx * c2 + gy * s1 * s2 - gz * c1 * s2
    w4 = gx * s2 - gy * s1 * c2 + gz * c1 * c2
    return w1, w2, w4


def gravity_vector(
    q: Vec, th: DynamicCoefficients, g: Gravity, out: FloatArray | None = None
) -> FloatArray:
    """Gravity torques G(q) = ∂P/∂q (3.31, 3.41), re-derived.

    With u = R e_z = (s2, -s1 c2, c1 c2) and K = ml2 + m4 q4:
    G1 = (ml1 - ml2 + K c2)(c1 gy + s1 gz), G2 = -K gᵀ ∂u/∂q2, G3 = 0, G4 = -m4 gᵀ u.

    Args:
        q: joints [rad, rad, rad, m].
        th: base dynamic parameters θ.
        g: gravity acceleration in the base frame [m/s^2].
        out: optional preallocated (4,) array.

    Returns:
        G(q) [N*m, N*m, N*m, N], shape (4,).
    """
    g0, g1, g2, g3 = gravity_floats(_floats(q), th, g)
    res = np.empty(4) if out is None else out
    res[0] = g0
    res[1] = g1
    res[2] = g2
    res[3] = g3
    return res


def gravity_floats(qf: list[float], th: DynamicCoefficients, g: Gravity) -> list[float]:
    """:func:`gravity_vector` on Python floats, the same operations (the controllers'
    per-tick form).

    Args:
        qf: joints [rad, rad, rad, m] as floats.
        th: base dynamic parameters θ.
        g: gravity acceleration in the base frame [m/s^2].

    Returns:
        G(q) [N*m, N*m, N*m, N] as four floats.
    """
    w1, w2, w4 = _gravity_terms_of(qf[0], qf[1], g)
    k = th.ml2 + th.m4 * qf[3]
    return [(th.ml1 - th.ml2 + k * math.cos(qf[1])) * w1, -k * w2, 0.0, -th.m4 * w4]


def inverse_dynamics(q: Vec, qd: Vec, qdd: Vec, th: DynamicCoefficients, g: Gravity) -> FloatArray:
    """τ = M(q) q̈ + C(q, q̇) q̇ + G(q) (3.32), friction excluded.

    Args:
        q: joints [rad, rad, rad, m].
        qd: joint velocities [rad/s, rad/s, rad/s, m/s].
        qdd: joint accelerations [rad/s^2, rad/s^2, rad/s^2, m/s^2].
        th: base dynamic parameters θ.
        g: gravity acceleration in the base frame [m/s^2].

    Returns:
        Joint torques [N*m, N*m, N*m, N], shape (4,).
    """
    m = mass_matrix(q, th)
    return m @ np.asarray(qdd, dtype=float) + coriolis_vector(q, qd, th) + gravity_vector(q, th, g)


def regressor(q: Vec, qd: Vec, qdd: Vec, g: Gravity) -> FloatArray:
    """Regressor Y(q, q̇, q̈) with Y θ = M q̈ + C q̇ + G (3.34).

    Columns follow :class:`~suture_engine.robot.params.DynamicCoefficients`:
    (I1, I2, I3, m4, ml1, ml2, h4, δ).

    Args:
        q: joints [rad, rad, rad, m].
        qd: joint velocities [rad/s, rad/s, rad/s, m/s].
        qdd: joint accelerations [rad/s^2, rad/s^2, rad/s^2, m/s^2].
        g: gravity acceleration in the base frame [m/s^2].

    Returns:
        The 4x8 regressor.
    """
    _, q2, _, q4 = _floats(q)
    c2, s2 = math.cos(q2), math.sin(q2)
    v1, v2, v3, v4 = _floats(qd)
    a1, a2, a3, a4 = _floats(qdd)
    w1, w2, w4 = _gravity_terms(q, g)
    sc = s2 * c2
    cc = c2 * c2
    y = np.zeros((4, N_THETA))
    # joint 1
    y[0, 0] = a1
    y[0, 2] = s2 * a3 + c2 * v2 * v3
    y[0, 3] = q4 * q4 * cc * a1 - 2.0 * q4 * q4 * sc * v1 * v2 + 2.0 * q4 * cc * v1 * v4
    y[0, 3] += q4 * c2 * w1
    y[0, 4] = w1
    y[0, 5] = (c2 - 1.0) * w1
    y[0, 6] = 2.0 * q4 * cc * a1 - 4.0 * q4 * sc * v1 * v2 + 2.0 * cc * v1 * v4
    y[0, 7] = -s2 * s2 * a1 - 2.0 * sc * v1 * v2
    # joint 2
    y[1, 1] = a2
    y[1, 2] = -c2 * v1 * v3
    y[1, 3] = q4 * q4 * a2 + q4 * q4 * sc * v1 * v1 + 2.0 * q4 * v2 * v4 - q4 * w2
    y[1, 5] = -w2
    y[1, 6] = 2.0 * q4 * a2 + 2.0 * q4 * sc * v1 * v1 + 2.0 * v2 * v4
    y[1, 7] = sc * v1 * v1
    # joint 3
    y[2, 2] = s2 * a1 + a3 + c2 * v1 * v2
    # joint 4
    y[3, 3] = a4 - q4 * cc * v1 * v1 - q4 * v2 * v2 - w4
    y[3, 6] = -cc * v1 * v1 - v2 * v2
    return y
