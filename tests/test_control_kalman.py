"""Kalman observer: Riccati residual, duality, and velocity estimation from noisy positions."""

from __future__ import annotations

import numpy as np
import pytest

from suture_engine.control.kalman import KalmanVelocityObserver, kalman_gain
from suture_engine.control.lqr import double_integrator


def test_gain_satisfies_its_riccati_equation() -> None:
    a, _ = double_integrator(3)
    c = np.hstack([np.eye(3), np.zeros((3, 3))])
    qo = np.diag([0, 0, 0, 50.0, 200.0, 10.0])
    ro = np.diag([1e-8, 4e-8, 1e-7])
    design = kalman_gain(a, c, qo, ro)
    s = design.covariance
    res = a @ s + s @ a.T + qo - s @ c.T @ np.linalg.inv(ro) @ c @ s  # (5.56) written out
    assert np.max(np.abs(res)) < 1e-8 * np.max(np.abs(qo))
    np.testing.assert_allclose(design.gain, s @ c.T @ np.linalg.inv(ro), rtol=1e-10)
    assert np.all(design.poles.real < 0)


def test_scalar_observer_matches_closed_form() -> None:
    # Hand-derived for q'' = w, y = q + v: L = [sqrt(2) (qo/ro)^(1/4), sqrt(qo/ro)].
    qo, ro = 100.0, 1e-6
    a, _ = double_integrator(1)
    gain = kalman_gain(a, [[1.0, 0.0]], np.diag([0.0, qo]), [[ro]]).gain.ravel()
    assert gain[1] == pytest.approx(np.sqrt(qo / ro), rel=1e-9)
    assert gain[0] == pytest.approx(np.sqrt(2.0) * (qo / ro) ** 0.25, rel=1e-9)


def test_estimates_velocity_of_a_known_trajectory_from_noisy_positions() -> None:
    dt = 1e-3
    obs = KalmanVelocityObserver(1, dt, process_noise=1e3, measurement_noise=1e-9)
    rng = np.random.default_rng(1)
    t = np.arange(4000) * dt
    q = 0.5 * np.sin(3 * t)
    v = 1.5 * np.cos(3 * t)
    acc = -4.5 * np.sin(3 * t)
    est = np.empty_like(t)
    for k in range(t.size):
        y = np.array([q[k] + rng.normal(0, 2e-5)])
        est[k] = obs.update(y, np.array([acc[k - 1] if k else 0.0]))[1]  # u held since k-1
    err = est[500:] - v[500:]
    assert np.sqrt(np.mean(err**2)) < 0.02
    assert abs(np.mean(err)) < 1e-3
    # Raw differentiation of the same noise is far worse.
    raw = np.diff(q + rng.normal(0, 2e-5, size=t.size)) / dt
    assert np.sqrt(np.mean((raw[500:] - v[501:]) ** 2)) > 0.02


def test_sampled_gain_satisfies_the_discrete_riccati_equation() -> None:
    obs = KalmanVelocityObserver(2, 1e-3, process_noise=[50.0, 500.0], measurement_noise=1e-9)
    # Rebuild the sampled noise model by brute-force quadrature (independent of Van Loan).
    dt, n = obs.dt, 2
    phi = np.eye(4)
    phi[:n, n:] = dt * np.eye(n)
    s = np.linspace(0.0, dt, 2001)
    integrand = []
    for si in s:
        e = np.eye(4)
        e[:n, n:] = si * np.eye(n)
        integrand.append(e @ obs.qo @ e.T)
    qd = np.trapezoid(np.array(integrand), s, axis=0)
    rd = obs.ro / dt
    c = obs.c
    # Find the prior covariance from the gain's fixed point by iterating the Riccati map.
    p = np.eye(4)
    for _ in range(20000):
        k = p @ c.T @ np.linalg.inv(c @ p @ c.T + rd)
        p = phi @ (p - k @ c @ p) @ phi.T + qd
    k = p @ c.T @ np.linalg.inv(c @ p @ c.T + rd)
    np.testing.assert_allclose(obs.discrete_gain, k, rtol=1e-4, atol=1e-9)


def test_per_joint_update_equals_matrix_predictor_corrector() -> None:
    obs = KalmanVelocityObserver(4, 1e-3, process_noise=[10.0, 100.0, 1e3, 50.0])
    rng = np.random.default_rng(3)
    x = np.zeros(8)
    y0 = rng.normal(size=4)
    obs.update(y0, np.zeros(4))
    x[:4] = y0
    c = obs.c
    for _ in range(50):
        y, u = rng.normal(size=4), rng.normal(size=4)
        prior = obs.transition @ x + obs.input_matrix @ u  # expm-discretised model
        x = prior + obs.discrete_gain @ (y - c @ prior)
        np.testing.assert_allclose(obs.update(y, u), x, rtol=1e-10, atol=1e-12)
