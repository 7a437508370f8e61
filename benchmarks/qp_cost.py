"""What one tick of move-constrained's QP costs, three ways (DESIGN section 6).

A closed loop of N ticks at 1 kHz: the EndoBot tool tip follows a target that slides
along a line fixture (plus a cone and the suture extension-rate row), and each tick's
QP is solved

1. warm: the persistent ConstrainedQP, matrices filled in place, OSQP update + warm
   start (what the skill runs), split into our assembly and OSQP's update + solve;
2. re-setup: the same matrices handed to a fresh OSQP problem each tick (fresh
   scipy.sparse matrices, setup, solve);
3. cvxpy: the same QP as a parametrised cvxpy problem (compiled once, parameters
   updated each tick, solved with its default QP solver).

Prints median and p99 [us] and the ratios. Usage: ``python benchmarks/qp_cost.py [N]``.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from suture_engine.control.constrained_qp import INF, ConstrainedQP
from suture_engine.control.fixtures import Cone, Line
from suture_engine.robot import endobot


def _pose(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pose = endobot.forward_kinematics(q)
    return np.r_[pose.position, pose.roll], endobot.jacobian(q)


def _stats(ns: list[int]) -> tuple[float, float]:
    us = np.asarray(ns, dtype=float) / 1e3
    return float(np.median(us)), float(np.percentile(us, 99))


def main(n: int = 3000) -> None:
    import cvxpy as cp
    import osqp
    import scipy.sparse as sp

    a = np.array([1.0, -1.0, 2.0]) / np.sqrt(6.0)
    fixtures = [Line(point=np.zeros(3), direction=a), Cone(axis=a, half_angle=0.3)]
    qp = ConstrainedQP(fixtures, extension_rate=True)
    exit_point = np.array([0.0, 0.0, 0.05])
    q = endobot.inverse_kinematics(0.12 * a, 0.0)

    # The cvxpy twin, compiled once: same variables, cost and rows as qp.matrices().
    nq, ns = 4, qp.n - 4
    z = cp.Variable(qp.n)
    Lp = cp.Parameter((4, 4))  # W^1/2 J, so the cost is DPP
    vp = cp.Parameter(4)
    Gp = cp.Parameter((ns, 4))
    lo_p, hi_p = cp.Parameter(qp.m), cp.Parameter(qp.m)
    w = qp.weights
    cost = 0.5 * cp.sum_squares(Lp @ z[:nq] - vp) + 0.5 * w.damping * cp.sum_squares(z[:nq])
    cost += 0.5 * w.slack * cp.sum_squares(z[nq:])
    rows = cp.hstack([z[:nq], Gp @ z[:nq] + z[nq:]])
    cvx = cp.Problem(cp.Minimize(cost), [rows >= lo_p, rows <= hi_p])

    warm, assemble, osqp_only, resetup, cvx_t = [], [], [], [], []
    max_diff_setup = max_diff_cvx = 0.0
    failures = 0
    settings = {"verbose": False, "polishing": False, "eps_abs": 1e-5, "eps_rel": 1e-5}
    for k in range(n):
        t = k * 1e-3
        x, J = _pose(q)
        s_target = 0.12 + 0.03 * np.sin(2 * np.pi * t / 2.0)
        x_target = np.r_[s_target * a, 0.5 * np.sin(t)]
        v_target = np.r_[0.03 * np.pi * np.cos(2 * np.pi * t / 2.0) * a, 0.5 * np.cos(t)]
        kw = {
            "v_target": v_target,
            "x_target": x_target,
            "exit_point": exit_point,
            "extension_rate_max": 0.02,
        }
        t0 = time.perf_counter_ns()
        res = qp.solve(q, x, J, **kw)
        warm.append(time.perf_counter_ns() - t0)
        failures += 0 if res.solved else 1
        # Split: our in-place assembly alone, then OSQP's update + solve alone.
        t0 = time.perf_counter_ns()
        qp._assemble(q, x, J, v_target, x_target, exit_point, 0.02)
        assemble.append(time.perf_counter_ns() - t0)
        low = qp._low
        if low is not None:
            t0 = time.perf_counter_ns()
            low.update_data_vec(q=qp._q, l=qp._l, u=qp._u)
            low.update_data_mat(P_x=qp._Px, P_i=None, A_x=qp._Ax, A_i=None)
            low.solve()
            osqp_only.append(time.perf_counter_ns() - t0)

        P, qv, A, lo, hi = qp.matrices()
        t0 = time.perf_counter_ns()
        fresh = osqp.OSQP()
        fresh.setup(
            sp.triu(sp.csc_matrix(P), format="csc"), qv, sp.csc_matrix(A), lo, hi, **settings
        )
        r2 = fresh.solve(raise_error=False)
        resetup.append(time.perf_counter_ns() - t0)
        if r2.info.status == "solved":
            max_diff_setup = max(max_diff_setup, float(np.abs(r2.x[:4] - res.qdot).max()))

        t0 = time.perf_counter_ns()
        Lp.value = np.sqrt(w.task)[:, None] * J
        vref = v_target + w.position_gain * (x_target - x)
        vp.value = np.sqrt(w.task) * vref
        Gp.value = A[4:, :4]
        lo_p.value = np.maximum(lo, -INF)
        hi_p.value = np.minimum(hi, INF)
        cvx.solve()
        cvx_t.append(time.perf_counter_ns() - t0)
        if cvx.status == "optimal" and z.value is not None:
            max_diff_cvx = max(max_diff_cvx, float(np.abs(z.value[:4] - res.qdot).max()))
        q = q + 1e-3 * res.qdot

    skip = 50
    rows_out = [
        ("warm: ConstrainedQP.solve (assembly + update + solve)", warm),
        ("  of which in-place assembly", assemble),
        ("  of which OSQP update + warm-started solve", osqp_only),
        ("re-setup: fresh OSQP problem each tick", resetup),
        (f"cvxpy (parametrised, solver {cvx.solver_stats.solver_name})", cvx_t),
    ]
    print(f"QP per tick: {qp.n} variables, {qp.m} rows, {n} ticks ({skip} warm-up ticks dropped)")
    print(f"{'':58s} {'median [us]':>12s} {'p99 [us]':>10s}")
    for name, data in rows_out:
        if data:
            med, p99 = _stats(data[skip:])
            print(f"{name:58s} {med:12.1f} {p99:10.1f}")
    wm = _stats(warm[skip:])[0]
    print(f"ratio re-setup / warm (median): {_stats(resetup[skip:])[0] / wm:.1f}x")
    print(f"ratio cvxpy / warm (median):    {_stats(cvx_t[skip:])[0] / wm:.1f}x")
    print(f"solver failures (held commands): {failures}")
    print(f"max |qdot - re-setup qdot| = {max_diff_setup:.2e}, vs cvxpy = {max_diff_cvx:.2e}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3000)
