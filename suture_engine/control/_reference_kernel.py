"""move-constrained's smoothstep reference along an affine fixture, compiled by numba.

One call per tick gives the task reference x(t) and its forward-difference velocity
(x(t + h) - x(t)) / h, where x(tt) = D [c0; f0 + sigma(tt) (f_goal - f0)] + (p0, 0) is
the inverse map of a line or a plane (:meth:`~suture_engine.control.fixtures.
EqualityFixture.affine_inverse`) and sigma the smoothstep s^2 (3 - 2 s) of
s = clip(tt / duration, 0, 1).

Written as scalar loops in a fixed order, compiled without ``fastmath``: the compiled
code gives the bits of this Python source on any CPU (without numba the source runs as
it is). The product D [c; f] is summed term by term, so it may differ in the last bit
from the fixture's own numpy ``inverse`` (a BLAS product); ``tests/test_move_constrained``
checks them against each other to 1e-12. Imported when an autonomous move-constrained
step starts on a line or a plane (never by ``suture validate``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["JIT", "smoothstep_reference"]

Array = NDArray[np.float64]


def smoothstep_reference(
    t: float,
    h: float,
    duration: float,
    f0: Array,
    df: Array,
    c0: Array,
    D: Array,
    p0: Array,
    x: Array,
    v: Array,
) -> None:
    """Fill ``x`` with x(t) and ``v`` with (x(t + h) - x(t)) / h (the module docstring).

    Args:
        t: time since the step's start [s].
        h: the velocity's difference step [s].
        duration: the smoothstep's duration [s].
        f0: the free coordinates at the start, (4 - m,).
        df: f_goal - f0, (4 - m,).
        c0: the constraint values of the reference (zeros), (m,).
        D: the inverse map's matrix, (4, 4).
        p0: the inverse map's offset, a point [m], (3,).
        x: out, the reference [m, m, m, rad], (4,).
        v: out, its velocity [m/s, m/s, m/s, rad/s], (4,).
    """
    m = c0.shape[0]
    cf = np.empty(4)
    xn = np.empty(4)
    for k in range(2):
        tt = t if k == 0 else t + h
        s = min(max(tt / duration, 0.0), 1.0)
        sigma = s * s * (3.0 - 2.0 * s)
        for i in range(m):
            cf[i] = c0[i]
        for i in range(4 - m):
            cf[m + i] = f0[i] + sigma * df[i]
        out = x if k == 0 else xn
        for i in range(4):
            a = D[i, 0] * cf[0]
            a = a + D[i, 1] * cf[1]
            a = a + D[i, 2] * cf[2]
            a = a + D[i, 3] * cf[3]
            out[i] = a + p0[i] if i < 3 else a
    for i in range(4):
        v[i] = (xn[i] - x[i]) / h


def _jit() -> tuple[Callable[..., Any], bool]:
    """(smoothstep_reference, compiled): numba's compiled version, or the Python one."""
    try:
        import numba
    except ImportError:  # the same numbers, slower
        return smoothstep_reference, False
    return numba.njit(cache=True, nogil=True)(smoothstep_reference), True


JIT = _jit()
"""(smoothstep_reference, compiled): the function move-constrained calls each tick."""
