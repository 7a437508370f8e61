"""LQR design and the feedback-linearising controller, checked against the ARE and physics."""

from __future__ import annotations

import numpy as np
import pytest

from suture_engine.control.lqr import (
    FeedbackLinearizingLQR,
    LqrDesignError,
    LqrWeights,
    double_integrator,
    integral_augmented,
    lqr_gain,
)
from suture_engine.control.model import ControlModel


def _are_residual(a, b, q, r, p):  # type: ignore[no-untyped-def]
    """A^T P + P A + Q - P B R^-1 B^T P, written out from (5.45)."""
    return a.T @ p + p @ a + q - p @ b @ np.linalg.inv(r) @ b.T @ p


def test_gain_leaves_near_zero_riccati_residual() -> None:
    a, b = double_integrator(4)
    a, b = integral_augmented(a, b, np.hstack([np.eye(4), np.zeros((4, 4))]))
    q = np.diag([1e4, 2e4, 5e3, 1e3, 1.0, 2.0, 0.5, 3.0, 1e4, 1e4, 1e3, 1e3])
    r = np.diag([1.0, 0.5, 2.0, 1.0])
    design = lqr_gain(a, b, q, r)
    res = _are_residual(a, b, q, r, design.riccati)
    assert np.max(np.abs(res)) < 1e-8 * np.max(np.abs(q))
    # K = R^-1 B^T P (5.44) and P symmetric positive definite
    np.testing.assert_allclose(design.gain, np.linalg.solve(r, b.T @ design.riccati), atol=1e-9)
    assert np.all(np.linalg.eigvalsh((design.riccati + design.riccati.T) / 2) > 0)
    assert np.all(np.linalg.eigvals(a - b @ design.gain).real < 0)


def test_scalar_double_integrator_matches_closed_form() -> None:
    # Hand-derived for x'' = u, Q = diag(qp, qv), R = rho:
    # K = [sqrt(qp/rho), sqrt(qv/rho + 2 sqrt(qp/rho))]
    qp, qv, rho = 400.0, 3.0, 0.5
    a, b = double_integrator(1)
    k = lqr_gain(a, b, np.diag([qp, qv]), [[rho]]).gain[0]
    k1 = np.sqrt(qp / rho)
    assert k[0] == pytest.approx(k1, rel=1e-9)
    assert k[1] == pytest.approx(np.sqrt(qv / rho + 2.0 * k1), rel=1e-9)


def test_uncontrollable_pair_raises_typed_error() -> None:
    a = np.diag([1.0, 2.0])
    b = np.array([[1.0], [0.0]])  # the unstable mode at 2 cannot be reached
    with pytest.raises(LqrDesignError):
        lqr_gain(a, b, np.eye(2), [[1.0]])


def _pendulum_model(scale: float = 1.0) -> ControlModel:
    """A 2-joint stand-in: configuration-dependent M, gravity, friction (hand-built)."""

    def mass(q):  # type: ignore[no-untyped-def]
        return scale * np.array([[0.05 + 0.01 * np.cos(q[1]), 0.002], [0.002, 0.2]])

    def coriolis(q, qd):  # type: ignore[no-untyped-def]
        return np.zeros((2, 2))

    def gravity(q):  # type: ignore[no-untyped-def]
        return scale * np.array([0.13 * 9.81 * np.sin(q[0]), 0.2 * 9.81])

    return ControlModel(mass, coriolis, gravity, np.array([0.1, 0.07]), np.array([0.04, 0.7]))


def _plant(model: ControlModel):  # type: ignore[no-untyped-def]
    def rhs(t, x, tau):  # type: ignore[no-untyped-def]
        q, qd = x[:2], x[2:]
        fr = model.coulomb * np.tanh(qd / 1e-3) + model.viscous * qd
        qdd = np.linalg.solve(model.mass_matrix(q), tau - model.gravity_vector(q) - fr)
        return np.concatenate([qd, qdd])

    return rhs


def _step(rhs, x, tau, dt=1e-3, sub=4):  # type: ignore[no-untyped-def]
    """Classical RK4 over one control period, torque held (an integrator written here)."""
    h = dt / sub
    for _ in range(sub):
        k1 = rhs(0.0, x, tau)
        k2 = rhs(0.0, x + 0.5 * h * k1, tau)
        k3 = rhs(0.0, x + 0.5 * h * k2, tau)
        k4 = rhs(0.0, x + h * k3, tau)
        x = x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def test_tracks_a_sine_on_an_independently_integrated_plant() -> None:
    true = _pendulum_model()
    ctrl = FeedbackLinearizingLQR(
        true, 1e-3, LqrWeights(position=1e5, velocity=1e2, integral=1e5, effort=1.0)
    )
    rhs = _plant(true)
    x = np.array([0.1, 0.0, 0.0, 0.0])
    dt = 1e-3
    errs = []
    for k in range(3000):
        t = k * dt
        qd_ = np.array([0.2 * np.sin(2 * t), 0.01 * np.sin(3 * t)])
        vd = np.array([0.4 * np.cos(2 * t), 0.03 * np.cos(3 * t)])
        ad = np.array([-0.8 * np.sin(2 * t), -0.09 * np.sin(3 * t)])
        tau = ctrl.update(x[:2], x[2:], qd_, vd, ad).copy()
        x = _step(rhs, x, tau)
        errs.append(
            np.abs(x[:2] - np.array([0.2 * np.sin(2 * (t + dt)), 0.01 * np.sin(3 * (t + dt))]))
        )
    errs_arr = np.array(errs)
    assert errs_arr[0, 0] > 0.05  # it started off the reference
    assert np.max(errs_arr[2000:]) < 2e-3


def test_integral_action_removes_steady_state_error_from_model_mismatch() -> None:
    true = _pendulum_model()
    wrong = _pendulum_model(scale=0.8)  # 20 % wrong mass and gravity
    rhs = _plant(true)
    finals = {}
    for integral in (False, True):
        ctrl = FeedbackLinearizingLQR(
            wrong, 1e-3, LqrWeights(1e4, 10.0, 1e5, 1.0), integral=integral
        )
        x = np.array([0.3, 0.02, 0.0, 0.0])
        target = np.array([0.3, 0.02])
        for _ in range(3000):
            tau = ctrl.update(x[:2], x[2:], target, np.zeros(2)).copy()
            x = _step(rhs, x, tau)
        finals[integral] = np.abs(x[:2] - target)
    assert np.max(finals[False]) > 1e-3
    assert np.max(finals[True]) < 0.1 * np.max(finals[False])


def test_endobot_model_coriolis_vector_matches_matrix_product() -> None:
    from suture_engine.control.model import endobot_control_model

    model = endobot_control_model()
    rng = np.random.default_rng(5)
    for _ in range(5):
        q, qd = rng.uniform(-0.5, 0.5, 4), rng.normal(size=4)
        q[3] = 0.1
        np.testing.assert_allclose(
            model.coriolis_torque(q, qd), model.coriolis_matrix(q, qd) @ qd, atol=1e-12
        )
