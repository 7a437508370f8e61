"""The move-constrained QP: agreement with independent solvers, constraints, slack, warm path."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import LinearConstraint, minimize

from suture_engine.control.constrained_qp import (
    INF,
    ConstrainedQP,
    JointLimits,
    QPError,
    QPWeights,
    extension_rate_bound,
)
from suture_engine.control.fixtures import Circle, Cone, Line, Plane
from suture_engine.robot import endobot

EXIT = np.array([0.02, 0.0, 0.1])
TIGHT = {"eps_abs": 1e-9, "eps_rel": 1e-9, "max_iter": 50000, "time_limit": 10.0}
# Closed-loop tests check behaviour, not speed: a loaded CI machine must not trip the cap.
NO_CAP = {"time_limit": 10.0}


def _pose(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pose = endobot.forward_kinematics(q)
    return np.r_[pose.position, pose.roll], endobot.jacobian(q)


def _scipy_oracle(qp: ConstrainedQP) -> np.ndarray:
    """The same QP solved by scipy's SLSQP from the dense matrices."""
    P, q, A, lo, hi = qp.matrices()
    eq = [i for i in range(qp.m) if lo[i] == hi[i]]
    cons = []
    if eq:
        cons.append({"type": "eq", "fun": lambda z: A[eq] @ z - hi[eq], "jac": lambda z: A[eq]})
    up = [i for i in range(qp.m) if i not in eq and hi[i] < INF / 2]
    dn = [i for i in range(qp.m) if i not in eq and lo[i] > -INF / 2]
    if up:
        cons.append({"type": "ineq", "fun": lambda z: hi[up] - A[up] @ z, "jac": lambda z: -A[up]})
    if dn:
        cons.append({"type": "ineq", "fun": lambda z: A[dn] @ z - lo[dn], "jac": lambda z: A[dn]})
    res = minimize(
        lambda z: 0.5 * z @ P @ z + q @ z,
        np.zeros(qp.n),
        jac=lambda z: P @ z + q,
        constraints=cons,
        method="SLSQP",
        options={"ftol": 1e-15, "maxiter": 2000},
    )
    if not res.success:
        # SLSQP's line search can stall at this tolerance (status 8), depending on the
        # BLAS's threads and code paths: solve again with scipy's interior-point
        # trust-region method, from the same start, an oracle of its own.
        res = minimize(
            lambda z: 0.5 * z @ P @ z + q @ z,
            np.zeros(qp.n),
            jac=lambda z: P @ z + q,
            hess=lambda z: P,
            constraints=[
                LinearConstraint(
                    A,
                    np.where(lo <= -INF / 2, -np.inf, lo),
                    np.where(hi >= INF / 2, np.inf, hi),
                )
            ],
            method="trust-constr",
            options={"gtol": 1e-12, "xtol": 1e-14, "maxiter": 20000},
        )
    assert res.success, res.message
    return np.asarray(res.x)


def _random_instance(
    rng: np.random.Generator, fixture_point: np.ndarray, spread: float = 0.003
) -> dict:
    x = np.r_[fixture_point + rng.normal(scale=spread, size=3), rng.uniform(-1, 1)]
    q = endobot.inverse_kinematics(x[:3], x[3])
    x, J = _pose(q)
    return {
        "q": q,
        "x": x,
        "jacobian": J,
        "v_target": rng.normal(scale=0.05, size=4),
        "x_target": x + rng.normal(scale=0.01, size=4),
        "exit_point": EXIT,
        "extension_rate_max": 0.01,
    }


FIXTURE_SETS = {
    "line": (Line(direction=[1.0, 1.0, 2.0]),),
    "line+cone": (Line(direction=[1.0, 1.0, 2.0]), Cone(axis=[0.0, 0.0, 1.0], half_angle=0.62)),
    "circle": (Circle(center=[0.0, 0.0, 0.15], radius=0.05),),
    "plane": (Plane(point=[0.0, 0.0, 0.12], normal=[0.0, 0.2, 1.0]),),
}
"""Fixture sets the QP is checked on, by name (the tests' ids)."""


@pytest.mark.parametrize("fixtures", list(FIXTURE_SETS.values()), ids=list(FIXTURE_SETS))
def test_solution_agrees_with_scipy_on_random_instances(fixtures: tuple) -> None:
    rng = np.random.default_rng(7)
    qp = ConstrainedQP(fixtures, extension_rate=True, settings=TIGHT)
    for _ in range(12):
        s = rng.uniform(0.05, 0.2)
        if isinstance(fixtures[0], Circle):
            th = rng.uniform(0, 2 * np.pi)
            base = np.array([0.05 * np.cos(th), 0.05 * np.sin(th), 0.15])
        elif isinstance(fixtures[0], Plane):
            base = np.array([rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), 0.12])
        else:
            base = s * np.array([1.0, 1.0, 2.0]) / np.sqrt(6)
        inst = _random_instance(rng, base)
        res = qp.solve(**inst)
        assert res.solved, res.status
        z = _scipy_oracle(qp)
        np.testing.assert_allclose(res.qdot, z[:4], atol=2e-5)


def test_solution_agrees_with_cvxpy() -> None:
    cp = pytest.importorskip("cvxpy")
    rng = np.random.default_rng(11)
    qp = ConstrainedQP(
        [Line(direction=[1.0, 1.0, 2.0]), Cone(axis=[0.0, 0.0, 1.0], half_angle=0.62)],
        extension_rate=True,
        settings=TIGHT,
    )
    for _ in range(6):
        inst = _random_instance(rng, rng.uniform(0.05, 0.2) * np.array([1, 1, 2]) / np.sqrt(6))
        res = qp.solve(**inst)
        P, q, A, lo, hi = qp.matrices()
        z = cp.Variable(qp.n)
        fin_hi, fin_lo = hi < INF / 2, lo > -INF / 2
        cons = [A[fin_hi] @ z <= hi[fin_hi], A[fin_lo] @ z >= lo[fin_lo]]
        prob = cp.Problem(cp.Minimize(0.5 * cp.quad_form(z, cp.psd_wrap(P)) + q @ z), cons)
        prob.solve(solver=cp.CLARABEL)  # an interior-point solver: independent of OSQP
        np.testing.assert_allclose(res.qdot, z.value[:4], atol=1e-5)


def test_constraints_hold_in_the_solution() -> None:
    rng = np.random.default_rng(5)
    line = Line(direction=[1.0, 1.0, 2.0])
    limits = JointLimits(qd_max=np.array([0.5, 0.5, 1.0, 0.05]))
    weights = QPWeights(fixture_gain=20.0)
    qp = ConstrainedQP([line], limits=limits, weights=weights, extension_rate=True, settings=NO_CAP)
    for _ in range(30):
        on_line = rng.uniform(0.05, 0.2) * np.array([1, 1, 2]) / np.sqrt(6)
        inst = _random_instance(rng, on_line, spread=2e-4)
        inst["v_target"] = rng.normal(scale=0.2, size=4)  # pushes against every bound
        res = qp.solve(**inst)
        assert res.solved
        # Feasible: the rows hold up to multiplier / w_s (quadratic slack penalty), ~1e-5.
        assert res.slack_max < 3e-5
        qd = res.qdot
        assert np.all(np.abs(qd) <= limits.qd_max + 2e-5)  # OSQP eps_abs + eps_rel terms
        x, J = inst["x"], inst["jacobian"]
        # C-dot = -k C (6.3-6.4) along the solution.
        np.testing.assert_allclose(line.jacobian(x) @ J @ qd, -20.0 * line.value(x), atol=3e-5)
        d = x[:3] - EXIT
        assert (d / np.linalg.norm(d)) @ J[:3] @ qd <= 0.01 + 3e-5
        assert "line[0]" in res.active and "line[1]" in res.active


def test_infeasible_extension_bound_takes_slack_and_reports_it() -> None:
    # The tension is over its bound: the suture must shorten at 1 m/s, which the joint
    # speed limits forbid. The hard row gives way through its slack, and says so.
    limits = JointLimits(qd_max=np.array([0.5, 0.5, 1.0, 0.05]))
    qp = ConstrainedQP([], limits=limits, extension_rate=True, settings=NO_CAP)
    q = np.array([0.1, 0.2, 0.0, 0.12])
    x, J = _pose(q)
    res = qp.solve(q, x, J, exit_point=np.array([0.0, 0.0, 0.02]), extension_rate_max=-1.0)
    assert res.solved, res.status
    assert res.slack_max > 0.5
    assert "extension_rate" in res.active
    d = x[:3] - np.array([0.0, 0.0, 0.02])
    ldot = (d / np.linalg.norm(d)) @ J[:3] @ res.qdot
    assert ldot < -0.04  # shortens as fast as the limits allow
    assert np.all(np.abs(res.qdot) <= limits.qd_max + 1e-6)


def test_failure_holds_last_command_and_counts() -> None:
    qp = ConstrainedQP([Line(direction=[1.0, 1.0, 2.0])], settings=NO_CAP)
    q = endobot.inverse_kinematics(0.1 * np.array([1, 1, 2]) / np.sqrt(6), 0.0)
    x, J = _pose(q)
    good = qp.solve(q, x, J, v_target=np.array([0.01, 0.01, 0.02, 0.1]))
    assert good.solved and qp.failures == 0
    qp.update_settings(max_iter=1, check_termination=1)
    bad = qp.solve(q, x, J, v_target=np.array([-0.03, -0.03, -0.06, -0.5]))
    assert not bad.solved
    assert bad.status != "solved"
    np.testing.assert_array_equal(bad.qdot, good.qdot)
    bad2 = qp.solve(q, x, J, v_target=np.array([0.03, 0.03, 0.06, 0.5]))
    assert not bad2.solved
    assert qp.failures == 2 and qp.consecutive_failures == 2
    qp.update_settings(max_iter=4000)
    assert qp.solve(q, x, J).solved
    assert qp.consecutive_failures == 0 and qp.failures == 2


def test_time_limit_guard_is_counted_and_holds_the_command() -> None:
    qp = ConstrainedQP([Line(direction=[1.0, 1.0, 2.0])], settings=NO_CAP)
    q = endobot.inverse_kinematics(0.1 * np.array([1, 1, 2]) / np.sqrt(6), 0.0)
    x, J = _pose(q)
    good = qp.solve(q, x, J, v_target=np.array([0.01, 0.01, 0.02, 0.1]))
    assert good.solved and qp.time_limit_hits == 0
    qp.update_settings(time_limit=1e-12)
    bad = qp.solve(q, x, J, v_target=np.array([-0.03, -0.03, -0.06, -0.5]))
    assert not bad.solved and bad.status == "run time limit reached"
    np.testing.assert_array_equal(bad.qdot, good.qdot)
    assert qp.time_limit_hits == 1 and qp.failures == 1


def _closed_loop(qp: ConstrainedQP, ticks: int) -> list[bytes]:
    q = endobot.inverse_kinematics(0.1 * np.array([1, 1, 2]) / np.sqrt(6), 0.0)
    target = np.r_[0.15 * np.array([1, 1, 2]) / np.sqrt(6), 0.5]
    out = []
    for _ in range(ticks):
        x, J = _pose(q)
        res = qp.solve(q, x, J, x_target=target, exit_point=EXIT, extension_rate_max=0.05)
        out.append(res.qdot.tobytes() + str((res.iterations, res.status, res.active)).encode())
        q = q + 1e-3 * res.qdot
    return out


def test_same_inputs_give_bit_identical_commands_and_iterations() -> None:
    # Rho adaptation on a fixed iteration interval: nothing depends on the wall clock.
    a = ConstrainedQP([Line(direction=[1.0, 1.0, 2.0])], extension_rate=True)
    first = _closed_loop(a, 400)
    b = ConstrainedQP([Line(direction=[1.0, 1.0, 2.0])], extension_rate=True)
    second = _closed_loop(b, 400)
    assert first == second
    assert a.failures == 0 and b.failures == 0
    assert len({its for its in first}) > 1  # the commands do change along the run


def test_warm_path_never_sets_up_twice(monkeypatch: pytest.MonkeyPatch) -> None:
    import osqp

    calls = {"setup": 0}
    real_setup = osqp.OSQP.setup

    def counting_setup(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        calls["setup"] += 1
        return real_setup(self, *args, **kwargs)

    monkeypatch.setattr(osqp.OSQP, "setup", counting_setup)
    line = Line(direction=[1.0, 1.0, 2.0])
    qp = ConstrainedQP([line], extension_rate=True, settings=NO_CAP)
    q = endobot.inverse_kinematics(0.1 * np.array([1, 1, 2]) / np.sqrt(6), 0.0)
    target = np.r_[0.15 * np.array([1, 1, 2]) / np.sqrt(6), 0.5]
    for _ in range(1500):
        x, J = _pose(q)
        res = qp.solve(q, x, J, x_target=target, exit_point=EXIT, extension_rate_max=0.5)
        assert res.solved
        q = q + 1e-3 * res.qdot
    assert calls["setup"] == 1
    x, _ = _pose(q)
    # Tracked the target along the line and stayed on it, warm-started every tick.
    assert np.linalg.norm(x - target) < 1e-3
    assert np.abs(line.value(x)).max() < 1e-6


def test_joint_limit_and_singularity_margin_hold_in_closed_loop() -> None:
    limits = JointLimits(q2_margin=0.3, q4_min=0.05)
    qp = ConstrainedQP([], limits=limits, settings=NO_CAP)
    q = np.array([0.0, 1.0, 0.0, 0.1])
    # Target straight above the RCM sideways: pulls q2 towards pi/2 and q4 towards 0.
    target = np.array([0.2, 0.0, 0.0, 0.0])
    inward = np.array([0.0, 0.0, 0.0, 0.0])
    for k in range(3000):
        x, J = _pose(q)
        tgt = target if k < 1500 else inward
        res = qp.solve(q, x, J, x_target=tgt)
        assert res.solved
        q = q + 1e-3 * res.qdot
        assert q[1] <= np.pi / 2 - 0.3 + 1e-3
        assert q[3] >= 0.05 - 1e-4
        assert np.all(q <= limits.q_max + 1e-6) and np.all(q >= limits.q_min - 1e-6)


def test_extension_rate_bound_is_4_11() -> None:
    assert extension_rate_bound(3.0, 1.0, 200.0) == pytest.approx(0.01)
    with pytest.raises(QPError):
        extension_rate_bound(3.0, 1.0, 0.0)


def test_bad_limits_are_typed_errors() -> None:
    with pytest.raises(QPError) as err:
        JointLimits(q_min=np.zeros(4), q_max=np.zeros(4))
    assert err.value.field == "q_min"
    with pytest.raises(QPError):
        QPWeights(task=np.array([1.0, -1.0, 1.0, 1.0]))


_LIMITS = JointLimits(qd_max=np.array([1.0, 1.0, 2.0, 0.1]))
_PROPERTY_QP = ConstrainedQP(
    [Plane(point=[0.0, 0.0, 0.12], normal=[0.0, 0.0, 1.0])],
    limits=_LIMITS,
    extension_rate=True,
    settings={**NO_CAP, "max_iter": 50000},  # unrelated random jumps: a cold start each time
)


@given(
    q=st.tuples(
        st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-3.0, 3.0), st.floats(0.04, 0.19)
    ),
    v=st.tuples(*[st.floats(-0.5, 0.5)] * 4),
    ldot_max=st.floats(-0.2, 0.2),
)
def test_property_bounds_always_hold_and_slack_only_when_needed(
    q: tuple, v: tuple, ldot_max: float
) -> None:
    qa = np.array(q)
    x, J = _pose(qa)
    res = _PROPERTY_QP.solve(
        qa, x, J, v_target=np.array(v), exit_point=EXIT, extension_rate_max=ldot_max
    )
    assert res.solved, res.status
    _, _, _, lo, hi = _PROPERTY_QP.matrices()
    # The joint rows have no slack: they hold whatever the fixture and tension ask
    # (exactly: the command is clipped into the joint box after the solve).
    assert np.all(res.qdot <= hi[:4]) and np.all(res.qdot >= lo[:4])
    assert np.all(np.abs(res.qdot) <= _LIMITS.qd_max)
    assert np.all(qa + 1e-3 * res.qdot <= _LIMITS.q_max + 1e-7)
    # A slack that gave way means the soft rows really conflicted with the joint box:
    # re-solving with the soft rows alone (no joint box) needs no slack.
    if res.slack_max > 1e-3:
        relaxed = ConstrainedQP(
            [Plane(point=[0.0, 0.0, 0.12], normal=[0.0, 0.0, 1.0])],
            limits=JointLimits(
                qd_max=np.full(4, 1e3),
                q_min=np.full(4, -1e3),
                q_max=np.full(4, 1e3),
                q2_margin=1e-3,
                q4_min=-1e2,
            ),
            extension_rate=True,
            settings=NO_CAP,
        )
        r2 = relaxed.solve(
            qa, x, J, v_target=np.array(v), exit_point=EXIT, extension_rate_max=ldot_max
        )
        assert r2.slack_max < 1e-4


def test_active_rows_and_slack_match_a_dense_recomputation() -> None:
    """Active rows and slack_max against A z, l, u from :meth:`matrices` and the solver's
    own z (dense numpy, not the per-row float loop of the result)."""
    rng = np.random.default_rng(11)
    line = Line(direction=[1.0, 1.0, 2.0])
    cone = Cone(axis=[0.0, 0.0, 1.0], half_angle=0.62)
    limits = JointLimits(qd_max=np.array([0.5, 0.5, 1.0, 0.05]))
    qp = ConstrainedQP([line, cone], limits=limits, extension_rate=True, settings=NO_CAP)
    if qp._low is None:
        pytest.skip("this OSQP has no compiled solver object to read z from")
    seen: set[str] = set()
    for _ in range(40):
        on_line = rng.uniform(0.05, 0.2) * np.array([1, 1, 2]) / np.sqrt(6)
        inst = _random_instance(rng, on_line, spread=2e-4)
        inst["v_target"] = rng.normal(scale=0.2, size=4)
        res = qp.solve(**inst)
        assert res.solved
        z = np.array(qp._low.solution.x)
        _, _, A, lo, hi = qp.matrices()
        az = A @ z
        tol = 2.0 * 1e-5 + 1e-9
        near = (np.abs(az - hi) <= tol + 1e-4 * np.abs(hi)) | (
            np.abs(az - lo) <= tol + 1e-4 * np.abs(lo)
        )
        eq = np.array([n.startswith("line[") for n in qp.row_names])
        expected = tuple(n for n, a in zip(qp.row_names, near | eq, strict=True) if a)
        assert res.active == expected
        assert res.slack_max == pytest.approx(np.max(np.abs(z[4:])), abs=1e-15)
        assert np.array_equal(res.qdot, np.clip(z[:4], lo[:4], hi[:4]))
        seen.update(res.active)
    assert any(n.startswith("joint_bound") for n in seen)  # the box was reached too


def _dense_oracle(
    qp: ConstrainedQP, inst: dict
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(P, q, A, l, u) built densely with numpy from the module docstring's formulas,
    independently of the compiled assembly."""
    J, x, q = inst["jacobian"], inst["x"], inst["q"]
    w, lim = qp.weights, qp.limits
    n, m = qp.n, qp.m
    P = np.zeros((n, n))
    P[:4, :4] = J.T @ np.diag(w.task) @ J + w.damping * np.eye(4)
    P[4:, 4:] = w.slack * np.eye(n - 4)
    vref = np.zeros(4)
    if inst.get("x_target") is not None:
        vref = vref + w.position_gain * (inst["x_target"] - x)
    if inst.get("v_target") is not None:
        vref = vref + inst["v_target"]
    qv = np.zeros(n)
    qv[:4] = -J.T @ np.diag(w.task) @ vref
    # joint box: position limits over one horizon, singularity margins, speed limits
    lo = (lim.q_min - q) / lim.horizon
    hi = (lim.q_max - q) / lim.horizon
    edge = np.pi / 2 - lim.q2_margin
    lo[1] = max(lo[1], (-edge - q[1]) / lim.singular_time_constant)
    hi[1] = min(hi[1], (edge - q[1]) / lim.singular_time_constant)
    lo[3] = max(lo[3], (lim.q4_min - q[3]) / lim.singular_time_constant)
    lo = np.clip(lo, -lim.qd_max, lim.qd_max)
    hi = np.maximum(np.clip(hi, -lim.qd_max, lim.qd_max), lo)
    A = np.zeros((m, n))
    A[:4, :4] = np.eye(4)
    A[4:, 4:] = np.eye(m - 4)
    lv = np.full(m, -INF)
    uv = np.full(m, INF)
    lv[:4], uv[:4] = lo, hi
    r = 4
    for fx in qp.fixtures:
        rows = slice(r, r + fx.rows)
        A[rows, :4] = fx.jacobian(x) @ J
        uv[rows] = -w.fixture_gain * fx.value(x)
        if fx.kind == "eq":
            lv[rows] = uv[rows]
        r += fx.rows
    if qp.extension_rate and inst.get("exit_point") is not None:
        d = x[:3] - inst["exit_point"]
        A[r, :4] = d / np.linalg.norm(d) @ J[:3]
        uv[r] = inst["extension_rate_max"]
    return P, qv, A, lv, uv


def _close(actual: np.ndarray, expected: np.ndarray) -> None:
    scale = max(1.0, float(np.max(np.abs(np.where(np.abs(expected) < INF / 2, expected, 0)))))
    np.testing.assert_allclose(actual, expected, rtol=1e-12, atol=1e-12 * scale)


FIXTURE_SETS_MORE = {
    **FIXTURE_SETS,
    "line+plane": (
        Line(direction=[1.0, 1.0, 2.0]),
        Plane(point=[0.0, 0.0, 0.1], normal=[1.0, -1.0, 0.0]),
    ),
    "none": (),
}
"""FIXTURE_SETS, with two rows of equalities and with no fixture at all."""


@pytest.mark.parametrize("fixtures", list(FIXTURE_SETS_MORE.values()), ids=list(FIXTURE_SETS_MORE))
@pytest.mark.parametrize("rate", [True, False], ids=["rate", "no-rate"])
def test_assembly_matches_a_dense_numpy_build(fixtures: tuple, rate: bool) -> None:
    """matrices() (what the compiled kernel wrote) and the value arrays handed to OSQP
    (Px, Ax in the setup's CSC order) against a dense numpy build, to 1e-12."""
    rng = np.random.default_rng(5)
    qp = ConstrainedQP(fixtures, extension_rate=rate)
    for k in range(30):
        inst = _random_instance(rng, np.array([0.01, 0.0, 0.12]), spread=0.02)
        if k % 3 == 1:
            inst["x_target"] = None
        if k % 4 == 2:
            inst["v_target"] = None
        if k % 5 == 3:
            inst["exit_point"] = None
        if k % 7 == 0:  # outside the joint box: the bounds point back into it
            inst["q"] = inst["q"] + rng.normal(scale=2.0, size=4)
        qp._assemble(
            inst["q"],
            inst["x"],
            inst["jacobian"],
            inst["v_target"],
            inst["x_target"],
            inst["exit_point"],
            inst["extension_rate_max"],
        )
        P, q, A, lo, hi = qp.matrices()
        eP, eq, eA, elo, ehi = _dense_oracle(qp, inst)
        for actual, expected in ((P, eP), (q, eq), (A, eA), (lo, elo), (hi, ehi)):
            _close(actual, expected)
        # The value arrays OSQP gets, in the structure set up once: P's upper triangle
        # over qdot by columns then the slack diagonal; A by columns, rows ascending.
        px = [P[i, j] for j in range(4) for i in range(j + 1)]
        px += [P[i, i] for i in range(4, qp.n)]
        ax = [A[i, j] for j in range(4) for i in [j, *range(4, qp.m)]]
        ax += [A[i, i] for i in range(4, qp.m)]
        assert np.array_equal(qp._Px, px) and np.array_equal(qp._Ax, ax)


def test_compiled_kernels_equal_their_python_source_bit_for_bit() -> None:
    """numba compiles the kernels without fastmath: the compiled assembly and result give
    the very bits of the Python source (no fused multiply-adds, no reordered sums)."""
    from suture_engine.control import _qp_kernels as kern

    assemble, finish, compiled = kern.JIT
    if not compiled:
        pytest.skip("numba is not installed: the Python source is what runs")
    rng = np.random.default_rng(9)
    line = Line(direction=[1.0, 1.0, 2.0])
    cone = Cone(axis=[0.0, 0.0, 1.0], half_angle=0.62)
    qp = ConstrainedQP([line, cone], extension_rate=True)
    for k in range(200):
        inst = _random_instance(rng, np.array([0.01, 0.0, 0.12]), spread=0.02)
        c = np.r_[line.value(inst["x"]), cone.value(inst["x"])]
        jc = np.vstack([line.jacobian(inst["x"]), cone.jacobian(inst["x"])])
        p0 = rng.normal(scale=0.05, size=(3, 3))
        # every optional input given; every other instance the rows evaluated as affine
        flags = kern.F_XTARGET | kern.F_VTARGET | kern.F_EXIT | (kern.F_AFFINE if k % 2 else 0)
        outs = []
        for fn in (assemble, assemble.py_func):
            H, g = np.zeros((4, 4)), qp._gflat.copy()
            px, qv, lo, hi, ax = (
                qp._Px.copy(),
                qp._q.copy(),
                qp._l.copy(),
                qp._u.copy(),
                qp._Ax.copy(),
            )
            fn(
                inst["jacobian"], inst["x"], inst["x_target"], inst["v_target"], inst["q"],
                c, jc, p0, qp._eq, inst["exit_point"], 0.01, flags, qp._ext_row, qp._cst,
                H, g, px, qv, lo, hi, qp._a_idx, ax,
            )  # fmt: skip
            outs.append(b"".join(a.tobytes() for a in (H, g, px, qv, lo, hi, ax)))
        assert outs[0] == outs[1]
        z = rng.normal(scale=0.05, size=qp.n)
        res = []
        for fn in (finish, finish.py_func):
            qdot, act = np.zeros(4), np.zeros(qp.m, np.int8)
            slack = fn(z, lo, hi, g, qp._eq, qp._act_tol, qdot, act)
            res.append((float(slack).hex(), qdot.tobytes(), act.tobytes()))
        assert res[0] == res[1]
