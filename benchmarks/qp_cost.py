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

import os
import sys
import time

import numpy as np

from suture_engine.control.constrained_qp import INF, ConstrainedQP
from suture_engine.control.fixtures import Cone, Line
from suture_engine.robot import endobot


def _pose(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pose = endobot.forward_kinematics(q)
    return np.r_[pose.position, pose.roll], endobot.jacobian(q)


def _stats(ns: list[int]) -> tuple[float, float, float]:
    us = np.asarray(ns, dtype=float) / 1e3
    return float(np.median(us)), float(np.percentile(us, 90)), float(np.percentile(us, 99))


class CvxpyTwin:
    """The same QP as a :class:`ConstrainedQP`, as a parametrised cvxpy problem.

    Compiled once; :meth:`solve` copies the QP's current matrices into the parameters
    (after ``ConstrainedQP.solve`` assembled them) and solves. Other benchmarks (the
    engine tick) can reuse it.
    """

    def __init__(self, qp: ConstrainedQP) -> None:
        import cvxpy as cp

        self.qp = qp
        nq, ns = 4, qp.n - 4
        self.z = cp.Variable(qp.n)
        self.L = cp.Parameter((4, 4))  # W^1/2 J, so the cost is DPP
        self.v = cp.Parameter(4)
        self.G = cp.Parameter((ns, 4))
        self.lo, self.hi = cp.Parameter(qp.m), cp.Parameter(qp.m)
        w = qp.weights
        z = self.z
        cost = 0.5 * cp.sum_squares(self.L @ z[:nq] - self.v)
        cost += 0.5 * w.damping * cp.sum_squares(z[:nq]) + 0.5 * w.slack * cp.sum_squares(z[nq:])
        rows = cp.hstack([z[:nq], self.G @ z[:nq] + z[nq:]])
        self.problem = cp.Problem(cp.Minimize(cost), [rows >= self.lo, rows <= self.hi])

    def solve(self, jacobian: np.ndarray, v_ref: np.ndarray) -> np.ndarray | None:
        """Solve with the QP's current rows; returns qdot or None if not optimal."""
        qp = self.qp
        sw = np.sqrt(qp.weights.task)
        _, _, A, lo, hi = qp.matrices()
        self.L.value = sw[:, None] * jacobian
        self.v.value = sw * v_ref
        self.G.value = A[4:, :4]
        self.lo.value = np.maximum(lo, -INF)
        self.hi.value = np.minimum(hi, INF)
        self.problem.solve()
        if self.problem.status != "optimal" or self.z.value is None:
            return None
        return np.asarray(self.z.value[:4])


def resetup_solve(qp: ConstrainedQP, settings: dict) -> tuple[np.ndarray | None, str]:
    """Solve the QP's current matrices on a fresh OSQP problem (fresh sparse matrices)."""
    import osqp
    import scipy.sparse as sp

    P, qv, A, lo, hi = qp.matrices()
    fresh = osqp.OSQP()
    fresh.setup(sp.triu(sp.csc_matrix(P), format="csc"), qv, sp.csc_matrix(A), lo, hi, **settings)
    res = fresh.solve(raise_error=False)
    return (res.x[:4] if res.info.status == "solved" else None), str(res.info.status)


def main(n: int = 3000) -> None:
    a = np.array([1.0, -1.0, 2.0]) / np.sqrt(6.0)
    fixtures = [Line(point=np.zeros(3), direction=a), Cone(axis=a, half_angle=0.3)]
    qp = ConstrainedQP(fixtures, extension_rate=True)
    exit_point = np.array([0.0, 0.0, 0.05])
    q = endobot.inverse_kinematics(0.12 * a, 0.0)
    twin = CvxpyTwin(qp)
    w = qp.weights

    warm, assemble, osqp_only, resetup, cvx_t = [], [], [], [], []
    failures = 0
    settings = {"verbose": False, "polishing": False, "eps_abs": 1e-5, "eps_rel": 1e-5}
    # Pass 1: the warm path alone, in closed loop; keep each tick's inputs and answer.
    ticks = []
    for k in range(n):
        t = k * 1e-3
        x, J = _pose(q)
        s_target = 0.12 + 0.03 * np.sin(2 * np.pi * t / 2.0)
        x_target = np.r_[s_target * a, 0.5 * np.sin(t)]
        v_target = np.r_[0.03 * np.pi * np.cos(2 * np.pi * t / 2.0) * a, 0.5 * np.cos(t)]
        t0 = time.perf_counter_ns()
        res = qp.solve(
            q,
            x,
            J,
            v_target=v_target,
            x_target=x_target,
            exit_point=exit_point,
            extension_rate_max=0.02,
        )
        warm.append(time.perf_counter_ns() - t0)
        failures += 0 if res.solved else 1
        ticks.append((q, x, J, v_target, x_target, res.qdot if res.solved else None))
        q = q + 1e-3 * res.qdot
    # Pass 2: the split of the warm path (assembly alone; OSQP update + solve alone).
    low = qp._low
    for q, x, J, v_target, x_target, _ in ticks:
        t0 = time.perf_counter_ns()
        qp._assemble(q, x, J, v_target, x_target, exit_point, 0.02)
        assemble.append(time.perf_counter_ns() - t0)
        if low is not None:
            t0 = time.perf_counter_ns()
            low.update_data_vec(q=qp._q, l=qp._l, u=qp._u)
            low.update_data_mat(P_x=qp._Px, P_i=None, A_x=qp._Ax, A_i=None)
            low.solve()
            osqp_only.append(time.perf_counter_ns() - t0)
    # Pass 3 and 4: the same tick inputs, re-set-up each tick, then through cvxpy.
    max_diff_setup = max_diff_cvx = 0.0
    for q, x, J, v_target, x_target, qdot in ticks:
        qp._assemble(q, x, J, v_target, x_target, exit_point, 0.02)  # untimed
        t0 = time.perf_counter_ns()
        qd_setup, _ = resetup_solve(qp, settings)
        resetup.append(time.perf_counter_ns() - t0)
        if qd_setup is not None and qdot is not None:
            max_diff_setup = max(max_diff_setup, float(np.abs(qd_setup - qdot).max()))
    for q, x, J, v_target, x_target, qdot in ticks:
        qp._assemble(q, x, J, v_target, x_target, exit_point, 0.02)  # untimed
        vref = v_target + w.position_gain * (x_target - x)
        t0 = time.perf_counter_ns()
        qd_cvx = twin.solve(J, vref)
        cvx_t.append(time.perf_counter_ns() - t0)
        if qd_cvx is not None and qdot is not None:
            max_diff_cvx = max(max_diff_cvx, float(np.abs(qd_cvx - qdot).max()))

    skip = 50
    rows_out = [
        ("warm: ConstrainedQP.solve (assembly + update + solve)", warm),
        ("  of which in-place assembly", assemble),
        ("  of which OSQP update + warm-started solve", osqp_only),
        ("re-setup: fresh OSQP problem each tick (incl. sparse build)", resetup),
        (f"cvxpy (parametrised, solver {twin.problem.solver_stats.solver_name})", cvx_t),
    ]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine: {os.cpu_count()} cores, 1-min load average {load:.1f} at the end")
    print(f"QP per tick: {qp.n} variables, {qp.m} rows, {n} ticks ({skip} warm-up ticks dropped)")
    print(f"{'':62s} {'median [us]':>12s} {'p90 [us]':>10s} {'p99 [us]':>10s}")
    for name, data in rows_out:
        if data:
            med, p90, p99 = _stats(data[skip:])
            print(f"{name:62s} {med:12.1f} {p90:10.1f} {p99:10.1f}")
    wm = _stats(warm[skip:])[0]
    print(f"ratio re-setup / warm (median): {_stats(resetup[skip:])[0] / wm:.1f}x")
    print(f"ratio cvxpy / warm (median):    {_stats(cvx_t[skip:])[0] / wm:.1f}x")
    print(f"warm-path ticks not solved (command held; time_limit 50 ms guard): {failures}")
    print(
        f"agreement on solved ticks: max |qdot_warm - qdot_resetup| = {max_diff_setup:.2e},"
        f" max |qdot_warm - qdot_cvxpy| = {max_diff_cvx:.2e} [rad/s or m/s]"
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3000)
