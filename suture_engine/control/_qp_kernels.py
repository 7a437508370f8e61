"""The per-tick arithmetic of :class:`~suture_engine.control.constrained_qp.ConstrainedQP`,
compiled by numba.

Two functions, each one call per tick in place of a dozen small numpy calls:

- :func:`assemble` fills the values of P (upper triangle over qdot), q, l, u and A of
  the persistent OSQP problem from the Jacobian, the task error and the fixture rows;
- :func:`finish` clips the solution's joint velocities into the joint box, takes the
  largest slack and marks the active rows.

Both are written as plain scalar loops, one product and one sum at a time in a fixed
order, so that the compiled code and the Python source give the same numbers to the
bit: numba compiles them without ``fastmath`` (no fused multiply-adds, no reordered
sums), so the results do not depend on the CPU either. Without numba the same Python
functions run as they are (the same numbers, about 40x slower).

Numba is imported here, on the first ConstrainedQP only: ``suture validate`` never
loads this module.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from suture_engine.control._compile import compile_kernels

__all__ = [
    "C_DAMP",
    "C_EDGE",
    "C_FIX_GAIN",
    "C_HORIZON",
    "C_INV_TAU",
    "C_POS_GAIN",
    "C_Q4_MIN",
    "C_QD",
    "C_QMAX",
    "C_QMIN",
    "C_SIZE",
    "C_TASK",
    "F_AFFINE",
    "F_EXIT",
    "F_VTARGET",
    "F_XTARGET",
    "JIT",
    "assemble",
    "finish",
]

Array = NDArray[np.float64]

# Layout of the constants vector ``cst`` (one float64 array, filled once at setup).
C_TASK = 0
"""W's diagonal, 4 values [-]."""
C_DAMP = 4
"""lambda, the joint-velocity regularisation [-]."""
C_POS_GAIN = 5
"""K_x [1/s]."""
C_FIX_GAIN = 6
"""-k_c [1/s] (negated)."""
C_HORIZON = 7
"""Look-ahead of the joint position limits [s]."""
C_INV_TAU = 8
"""1 / the singularity approach time constant [1/s]."""
C_EDGE = 9
"""pi/2 - q2_margin [rad]."""
C_Q4_MIN = 10
"""The smallest insertion [m]."""
C_QMIN = 11
"""Lower joint limits, 4 values [rad, rad, rad, m]."""
C_QMAX = 15
"""Upper joint limits, 4 values [rad, rad, rad, m]."""
C_QD = 19
"""Joint speed limits, 4 values [rad/s, rad/s, rad/s, m/s]."""
C_SIZE = 23

# Bits of ``flags``: which optional inputs this tick has.
F_XTARGET = 1
"""x_target given: v_ref gets the position feedback K_x (x_target - x)."""
F_VTARGET = 2
"""v_target given: v_ref gets the feed-forward velocity."""
F_EXIT = 4
"""The extension-rate row is on (exit point and ldot_max given)."""
F_AFFINE = 8
"""The fixture rows are affine, ``C(x) = Jc[:, :3] (p - p0)``: evaluated here, ``c`` unread."""

_INF = 1e30  # OSQP's "no bound" (constrained_qp.INF)


def assemble(
    J: Array,
    x: Array,
    x_target: Array,
    v_target: Array,
    q: Array,
    c: Array,
    jc: Array,
    p0: Array,
    eq: NDArray[np.int8],
    exit_point: Array,
    ldot_max: float,
    flags: int,
    ext_row: int,
    cst: Array,
    H: Array,
    gflat: Array,
    Px: Array,
    qvec: Array,
    lo: Array,
    hi: Array,
    a_idx: NDArray[np.int64],
    Ax: Array,
) -> None:
    """Fill the tick's problem data in place (the module docstring of constrained_qp).

    Args:
        J: the task Jacobian dx/dq, (4, 4).
        x: task vector (x, y, z, phi) [m, m, m, rad].
        x_target: task target (read when ``flags & F_XTARGET``).
        v_target: feed-forward task velocity (read when ``flags & F_VTARGET``).
        q: joint positions [rad, rad, rad, m].
        c: the fixture rows' values C(x), (m_fix,) [row units] (unread with F_AFFINE).
        jc: their Jacobian dC/dx, (m_fix, 4).
        p0: with F_AFFINE, each row's point p0 [m], (m_fix, 3): C_r = Jc_r[:3] (p - p0_r).
        eq: per fixture row, 1 for an equality row.
        exit_point: the suture's exit point [m] (read when ``flags & F_EXIT``).
        ldot_max: the extension rate bound [m/s] (used when ``flags & F_EXIT``).
        flags: ``F_XTARGET | F_VTARGET | F_EXIT | F_AFFINE``: the optional inputs given,
            and whether the fixture rows are affine.
        ext_row: the soft row index of the extension-rate row, -1 when there is none.
        cst: the constants (``C_*`` layout).
        H: out, J^T W J + lambda I, (4, 4).
        gflat: out, the soft rows of A over qdot, row-major, then a trailing 1.0.
        Px: out, P's values (the first 10: H's upper triangle by columns).
        qvec: out, q's values (the first 4: -J^T W v_ref).
        lo: out, lower bounds (joint box, then the soft rows).
        hi: out, upper bounds.
        a_idx: A's values as indices into ``gflat`` (CSC order).
        Ax: out, A's values.
    """
    # JW[i][k] = J[k, i] W_k, then H = JW J + lambda I.
    w0 = cst[C_TASK]
    w1 = cst[C_TASK + 1]
    w2 = cst[C_TASK + 2]
    w3 = cst[C_TASK + 3]
    damp = cst[C_DAMP]
    k = 0
    for j in range(4):
        for i in range(j + 1):
            s = J[0, i] * w0 * J[0, j]
            s = s + J[1, i] * w1 * J[1, j]
            s = s + J[2, i] * w2 * J[2, j]
            s = s + J[3, i] * w3 * J[3, j]
            if i == j:
                s = s + damp
            H[i, j] = s
            H[j, i] = s
            Px[k] = s
            k += 1
    # q = -J^T W v_ref, v_ref = v_target + K_x (x_target - x).
    kx = cst[C_POS_GAIN]
    v0 = 0.0
    v1 = 0.0
    v2 = 0.0
    v3 = 0.0
    if flags & F_XTARGET:
        v0 = (x_target[0] - x[0]) * kx
        v1 = (x_target[1] - x[1]) * kx
        v2 = (x_target[2] - x[2]) * kx
        v3 = (x_target[3] - x[3]) * kx
    if flags & F_VTARGET:
        v0 = v0 + v_target[0]
        v1 = v1 + v_target[1]
        v2 = v2 + v_target[2]
        v3 = v3 + v_target[3]
    for i in range(4):
        s = J[0, i] * w0 * v0
        s = s + J[1, i] * w1 * v1
        s = s + J[2, i] * w2 * v2
        s = s + J[3, i] * w3 * v3
        qvec[i] = -s
    # The joint box: each joint clamped into [-v, v]; outside a bound already: back
    # towards it (at most at the speed limit), never an empty box.
    h = cst[C_HORIZON]
    inv_tau = cst[C_INV_TAU]
    edge = cst[C_EDGE]
    for i in range(4):
        v = cst[C_QD + i]
        a = (cst[C_QMIN + i] - q[i]) / h
        b = (cst[C_QMAX + i] - q[i]) / h
        if i == 1:
            a = max(a, (-edge - q[i]) * inv_tau)
            b = min(b, (edge - q[i]) * inv_tau)
        elif i == 3:
            a = max(a, (cst[C_Q4_MIN] - q[i]) * inv_tau)
        a = min(max(a, -v), v)
        b = max(min(max(b, -v), v), a)
        lo[i] = a
        hi[i] = b
    # Fixture rows: Jc J qdot + s (=|<=) -k_c C(x).
    kc = cst[C_FIX_GAIN]
    m_fix = c.shape[0]
    for r in range(m_fix):
        for j in range(4):
            s = jc[r, 0] * J[0, j]
            s = s + jc[r, 1] * J[1, j]
            s = s + jc[r, 2] * J[2, j]
            s = s + jc[r, 3] * J[3, j]
            gflat[r * 4 + j] = s
        if flags & F_AFFINE:
            cr = jc[r, 0] * (x[0] - p0[r, 0])
            cr = cr + jc[r, 1] * (x[1] - p0[r, 1])
            cr = cr + jc[r, 2] * (x[2] - p0[r, 2])
        else:
            cr = c[r]
        b = cr * kc
        hi[4 + r] = b
        if eq[r]:
            lo[4 + r] = b
    # Extension rate: (p - e)^T / |p - e| J_p qdot + s <= ldot_max.
    if ext_row >= 0:
        base = ext_row * 4
        if flags & F_EXIT:
            d0 = x[0] - exit_point[0]
            d1 = x[1] - exit_point[1]
            d2 = x[2] - exit_point[2]
            dist = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            if dist > 1e-9:
                d0 = d0 / dist
                d1 = d1 / dist
                d2 = d2 / dist
                for j in range(4):
                    gflat[base + j] = d0 * J[0, j] + d1 * J[1, j] + d2 * J[2, j]
            else:
                for j in range(4):
                    gflat[base + j] = 0.0
            hi[4 + ext_row] = ldot_max
        else:
            for j in range(4):
                gflat[base + j] = 0.0
            hi[4 + ext_row] = _INF
    for n in range(a_idx.shape[0]):
        Ax[n] = gflat[a_idx[n]]


def finish(
    z: Array,
    lo: Array,
    hi: Array,
    gflat: Array,
    eq: NDArray[np.int8],
    tol: float,
    qdot: Array,
    active: NDArray[np.int8],
) -> float:
    """Check the solution, clip its joint velocities into the box, mark the active rows.

    A row is active when ``|A z - bound| <= tol + 1e-4 |bound|`` at either bound;
    equality fixture rows always are.

    Args:
        z: the solver's solution (qdot, slacks).
        lo: the tick's lower bounds.
        hi: the tick's upper bounds.
        gflat: the soft rows of A over qdot, row-major.
        eq: per soft row, 1 for an equality row.
        tol: the activity tolerance (2 eps_abs + 1e-9).
        qdot: out, the clipped joint velocities (4,).
        active: out, per row of A, 1 when active.

    Returns:
        The largest slack magnitude (0 without soft rows), or -1 when z is not finite
        (nothing else is then written).
    """
    n = z.shape[0]
    for i in range(n):
        if not math.isfinite(z[i]):
            return -1.0
    z0 = z[0]
    z1 = z[1]
    z2 = z[2]
    z3 = z[3]
    for i in range(4):
        a = z[i]
        b = hi[i]
        d = lo[i]
        qdot[i] = min(max(a, d), b)
        up = abs(a - b) <= tol + 1e-4 * abs(b)
        active[i] = 1 if up or abs(a - d) <= tol + 1e-4 * abs(d) else 0
    slack = 0.0
    for r in range(n - 4):
        i = 4 + r
        s = z[i]
        if abs(s) > slack:
            slack = abs(s)
        if eq[r]:
            active[i] = 1
            continue
        base = r * 4
        a = gflat[base] * z0 + gflat[base + 1] * z1 + gflat[base + 2] * z2 + gflat[base + 3] * z3
        a = a + s
        b = hi[i]
        d = lo[i]
        up = abs(a - b) <= tol + 1e-4 * abs(b)
        active[i] = 1 if up or abs(a - d) <= tol + 1e-4 * abs(d) else 0
    return slack


JIT = compile_kernels(assemble, finish)
"""(assemble, finish, compiled): the functions the QP calls each tick."""
