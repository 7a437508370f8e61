"""Identification (3.5) on a one-link plant integrated here by RK4 (an independent oracle)."""

from __future__ import annotations

import numpy as np
import pytest

from suture_engine.robot.excitation import schroeder_multisine
from suture_engine.robot.identification import (
    GravityShape,
    IdentificationError,
    column_correlation,
    differential_regressor,
    energy_regressor,
    estimate_motion,
    fit_differential,
    fit_energy,
    fit_friction,
    least_squares,
    validate,
)

TRUE = {"I": 0.0487, "ml": 0.1273, "Fc": 0.127, "Fv": 0.044}
G = 9.81
DT = 0.001


def _simulate(tau_of_k, n, x0=(0.0, 0.0), sub=10):  # type: ignore[no-untyped-def]
    """RK4 of I q'' + ml g sin q + Fc tanh(q'/1e-4) + Fv q' = tau, torque held per sample."""
    h = DT / sub
    q, v = x0
    qs, taus = np.empty(n), np.empty(n)

    def acc(q: float, v: float, tau: float) -> float:
        fr = TRUE["Fc"] * np.tanh(v / 1e-4) + TRUE["Fv"] * v
        return (tau - TRUE["ml"] * G * np.sin(q) - fr) / TRUE["I"]

    for k in range(n):
        qs[k] = q
        tau = tau_of_k(k, q, v)
        taus[k] = tau
        for _ in range(sub):
            k1q, k1v = v, acc(q, v, tau)
            k2q, k2v = v + 0.5 * h * k1v, acc(q + 0.5 * h * k1q, v + 0.5 * h * k1v, tau)
            k3q, k3v = v + 0.5 * h * k2v, acc(q + 0.5 * h * k2q, v + 0.5 * h * k2v, tau)
            k4q, k4v = v + h * k3v, acc(q + h * k3q, v + h * k3v, tau)
            q += h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    return qs, taus


@pytest.fixture(scope="module")
def schroeder_run() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    sig = schroeder_multisine(8.0, DT, 0.6, period_samples=4000, n_sines=16)
    q, tau = _simulate(lambda k, q, v: sig.u[k], sig.u.size, sub=4)
    return q, tau, sig.u


def test_differential_model_recovers_all_four_parameters(schroeder_run) -> None:  # type: ignore[no-untyped-def]
    q, tau, _ = schroeder_run
    est = fit_differential(q, tau, DT, GravityShape.SINE, cutoff_hz=20.0)
    clean = fit_differential(q, tau, DT, GravityShape.SINE, cutoff_hz=None)
    for a, b in zip(est[:4], clean[:4], strict=True):
        assert a == pytest.approx(b, rel=0.05)
    assert est.inertia == pytest.approx(TRUE["I"], rel=0.02)
    assert est.gravity_moment == pytest.approx(TRUE["ml"], rel=0.02)
    assert est.coulomb == pytest.approx(TRUE["Fc"], rel=0.05)
    assert est.viscous == pytest.approx(TRUE["Fv"], rel=0.05)
    assert np.isfinite(est.condition)


def test_energy_model_with_friction_first(schroeder_run) -> None:  # type: ignore[no-untyped-def]
    q, tau, _ = schroeder_run
    friction = fit_friction(*_constant_velocity_data(), GravityShape.SINE)
    est = fit_energy(q, tau, DT, GravityShape.SINE, window=50, friction=friction)
    assert est.inertia == pytest.approx(TRUE["I"], rel=0.03)
    assert est.gravity_moment == pytest.approx(TRUE["ml"], rel=0.03)


def test_energy_columns_coulomb_viscous_strongly_correlated(schroeder_run) -> None:  # type: ignore[no-untyped-def]
    q, tau, _ = schroeder_run
    qd = np.append(np.diff(q) / DT, 0.0)
    rows, _ = energy_regressor(q, qd, tau, DT, GravityShape.SINE, window=50)
    r = column_correlation(rows)
    assert r[2, 3] > 0.8  # Table 3.2 reports 0.94 on the real robot
    assert abs(r[0, 2]) < 0.3


def _constant_velocity_data() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity PI loop (Fig. 3.17) at several speeds; keep the steady halves."""
    qs, vs, ts = [], [], []
    for vref in (-1.5, -0.8, -0.3, 0.3, 0.8, 1.5):
        integ = [0.0]

        def law(k, q, v, vref=vref, integ=integ):  # type: ignore[no-untyped-def]
            e = vref - v
            integ[0] += e * DT
            return 2.0 * e + 40.0 * integ[0]

        n = 1500
        q, tau = _simulate(law, n, x0=(-0.6 * np.sign(vref), 0.0), sub=2)
        v = np.gradient(q, DT)
        keep = slice(700, n - 5)
        qs.append(q[keep])
        vs.append(v[keep])
        ts.append(tau[keep])
    return np.concatenate(qs), np.concatenate(vs), np.concatenate(ts)


def test_friction_from_constant_velocity_loop() -> None:
    q, v, tau = _constant_velocity_data()
    est = fit_friction(q, v, tau, GravityShape.SINE)
    assert est.coulomb == pytest.approx(TRUE["Fc"], rel=0.03)
    assert est.viscous == pytest.approx(TRUE["Fv"], rel=0.05)
    assert est.gravity_moment == pytest.approx(TRUE["ml"], rel=0.03)


def test_validation_residual_uncorrelated_with_input(schroeder_run) -> None:  # type: ignore[no-untyped-def]
    q, tau, u = schroeder_run
    _, qd, qdd = estimate_motion(q, DT, None)
    phi = differential_regressor(q, qd, qdd, GravityShape.SINE)
    true = [TRUE["I"], TRUE["ml"], TRUE["Fc"], TRUE["Fv"]]
    good = validate(phi[10:-10], true, tau[10:-10], u[10:-10])
    assert good.relative_residual < 0.05
    assert abs(good.input_correlation) < 0.1
    wrong = validate(phi[10:-10], [0.5 * true[0], *true[1:]], tau[10:-10], u[10:-10])
    assert wrong.relative_residual > 2 * good.relative_residual


def test_rank_deficient_regressor_raises() -> None:
    t = np.linspace(0, 1, 100)
    with pytest.raises(IdentificationError):
        least_squares(np.column_stack([t, 2 * t]), t)
    with pytest.raises(IdentificationError):
        least_squares(np.ones((2, 3)), np.ones(2))


# --- On the simulated robot (PyBullet) --------------------------------------------------


@pytest.mark.parametrize("joint", [0, 1, 3])
def test_single_joint_gravity_shape_matches_robot_model(joint: int) -> None:
    """The single-joint structure (3.73) against the robot model's own G(q)."""
    from suture_engine.robot import endobot
    from suture_engine.robot.identification_experiment import JOINT_PLANS, joint_truth
    from suture_engine.robot.params import E1

    plan = JOINT_PLANS[joint]
    truth = joint_truth(E1, joint, plan.hold)
    for x in np.linspace(-0.8, 0.8, 9):
        q = np.array(plan.hold, dtype=float)
        q[joint] = x if joint != 3 else 0.1 + 0.1 * x
        g_model = endobot.gravity_vector(q, E1)[joint]
        g_single = truth.gravity_moment * G * plan.shape.shape(np.array([q[joint]]))[0]
        assert g_single == pytest.approx(g_model, rel=1e-9, abs=1e-12)
        assert endobot.mass_matrix(q, E1)[joint, joint] == pytest.approx(truth.inertia)


def test_pybullet_yaw_joint_recovered_within_5_percent_clean() -> None:
    from suture_engine.robot.identification_experiment import identify_robot

    report = identify_robot(joints=(0,), duration=4.0)
    (res,) = report.joints
    for k in range(4):
        assert res.estimate[k] == pytest.approx(res.truth[k], rel=0.05), k


def test_cli_identify_rejects_bad_options_and_prints_table() -> None:
    from typer.testing import CliRunner

    from suture_engine.cli import app

    runner = CliRunner()
    bad = runner.invoke(app, ["identify", "--signal", "white"])
    assert bad.exit_code == 2
    assert "unknown signal" in bad.output
    assert "Traceback" not in bad.output
    ok = runner.invoke(app, ["identify", "--joint", "3", "--duration", "3", "--method", "energy"])
    assert ok.exit_code == 0, ok.output
    assert "E13 roll" in ok.output and "Fv" in ok.output


@pytest.mark.slow
@pytest.mark.parametrize("method", ["differential", "energy"])
def test_pybullet_all_joints_within_5_percent_schroeder_clean(method: str) -> None:
    from suture_engine.robot.identification_experiment import identify_robot

    report = identify_robot(method=method)
    for res in report.joints:
        for k in range(4):
            if np.isnan(res.truth[k]):
                continue
            assert res.estimate[k] == pytest.approx(res.truth[k], rel=0.05), (res.joint, k)


@pytest.mark.slow
def test_pybullet_realistic_encoder_noise_inertia_and_gravity_within_10_percent() -> None:
    from suture_engine.robot.identification_experiment import identify_robot

    report = identify_robot(encoder_noise=1e-5, quantised=True, method="energy")
    for res in report.joints:
        for k in range(2):
            if not np.isnan(res.truth[k]):
                assert res.estimate[k] == pytest.approx(res.truth[k], rel=0.10), (res.joint, k)
