"""move-constrained's per-tick arithmetic along an affine fixture (a line, a plane),
compiled by numba.

- :func:`smoothstep_reference`: the task reference x(t) and its forward-difference
  velocity (x(t + h) - x(t)) / h, where x(tt) = D [c0; f0 + sigma(tt) (f_goal - f0)] +
  (p0, 0) is the fixture's inverse map (:meth:`~suture_engine.control.fixtures.
  EqualityFixture.affine_inverse`) and sigma the smoothstep s^2 (3 - 2 s) of
  s = clip(tt / duration, 0, 1);
- :func:`integrate_and_track`: the joint reference's Euler step q_ref += qdot dt (and
  the command's copy of it), and the running peak of the measured deviation
  |C(x)| = |Jc[:, :3] (p - p0)| (:meth:`~suture_engine.control.fixtures.Fixture.affine`).

Written as scalar loops in a fixed order, compiled without ``fastmath``: the compiled
code gives the bits of this Python source on any CPU (without numba the source runs as
it is). The Euler step is numpy's element-wise ``q_ref += qdot * dt`` to the bit. The
products D [c; f] and Jc (p - p0) are summed term by term, so they may differ in the last
bit from the fixture's own numpy ``inverse`` and ``value`` (BLAS products);
``tests/test_move_constrained`` checks them against each other to 1e-12. Imported when an
autonomous move-constrained step starts on a line or a plane (never by ``suture validate``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from suture_engine.control._compile import compile_kernels

__all__ = ["JIT", "integrate_and_track", "smoothstep_reference"]

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


def integrate_and_track(
    q_ref: Array,
    qdot: Array,
    dt: float,
    q_cmd: Array,
    x_meas: Array,
    jc: Array,
    p0: Array,
    peak: Array,
    track: bool,
) -> None:
    """One tick's joint reference step and, with ``track``, the deviation's peak.

    Args:
        q_ref: the joint reference [rad, rad, rad, m], (4,); advanced in place.
        qdot: the QP's joint velocities [rad/s, rad/s, rad/s, m/s], (4,).
        dt: the control period [s].
        q_cmd: out, a copy of the advanced q_ref (the position command), (4,).
        x_meas: the measured task vector [m, m, m, rad], (4,).
        jc: the fixture's constant constraint Jacobian, (m, 4).
        p0: the fixture's point [m], (3,).
        peak: the running max |C_r(x)| per row [m], (m,); updated in place (NaN stays).
        track: update ``peak`` (not on a tick the skill fails).
    """
    for i in range(4):
        q = q_ref[i] + qdot[i] * dt
        q_ref[i] = q
        q_cmd[i] = q
    if not track:
        return
    for r in range(jc.shape[0]):
        e = jc[r, 0] * (x_meas[0] - p0[0])
        e = e + jc[r, 1] * (x_meas[1] - p0[1])
        e = e + jc[r, 2] * (x_meas[2] - p0[2])
        a = abs(e)
        p = peak[r]
        # np.maximum's rule: NaN if either is NaN, else the larger
        if a != a or p != p:
            peak[r] = math.nan
        elif a > p:
            peak[r] = a


JIT = compile_kernels(smoothstep_reference, integrate_and_track)
"""(smoothstep_reference, integrate_and_track, compiled): what move-constrained calls."""
