"""EndoBot dynamics: PyBullet inverse dynamics as the oracle, and the properties of 3.3.2."""

from __future__ import annotations

import dataclasses
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pybullet as p
import pytest
from hypothesis import given
from hypothesis import strategies as st

from backends.pybullet.urdf import endobot_urdf
from suture_engine.robot import dynamics, endobot
from suture_engine.robot.params import E1, E2, EndoBotParams

angle = st.floats(-1.0, 1.0)
rate = st.floats(-3.0, 3.0)
joints = st.tuples(angle, angle, st.floats(-3.0, 3.0), st.floats(0.0, 0.2)).map(np.array)
velocities = st.tuples(rate, rate, rate, st.floats(-0.3, 0.3)).map(np.array)
accelerations = st.tuples(*[st.floats(-10.0, 10.0)] * 4).map(np.array)
gravities = st.tuples(*[st.floats(-9.81, 9.81)] * 3)
robots = st.sampled_from([E1, E2])


@pytest.fixture(scope="module")
def sim() -> Iterator[tuple[int, dict[str, int]]]:
    """A DIRECT client with E1 and E2 loaded (identity base: PyBullet's inverse
    dynamics ignores a fixed base's orientation)."""
    cid = p.connect(p.DIRECT)
    ids: dict[str, int] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for params, tool in ((E1, True), (E2, True), (E1, False)):
            key = params.name + ("" if tool else "-no-tool")
            path = Path(tmp) / f"{key}.urdf"
            path.write_text(endobot_urdf(params, include_tool=tool))
            ids[key] = p.loadURDF(
                str(path),
                useFixedBase=True,
                flags=p.URDF_USE_INERTIA_FROM_FILE,
                physicsClientId=cid,
            )
        yield cid, ids
    p.disconnect(cid)


@given(robots, joints, velocities, accelerations, gravities)
def test_inverse_dynamics_matches_pybullet(
    sim: tuple[int, dict[str, int]],
    params: EndoBotParams,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    g: tuple[float, float, float],
) -> None:
    cid, ids = sim
    p.setGravity(*g, physicsClientId=cid)
    par = dataclasses.replace(params, gravity=g)
    model = endobot.inverse_dynamics(q, qd, qdd, par)
    by_regressor = endobot.regressor(q, qd, qdd, par) @ np.array(par.coefficients)
    keys = [params.name] + ([f"{params.name}-no-tool"] if params is E1 else [])
    for key in keys:  # with the tool link the insertion body is split in two: same dynamics
        oracle = p.calculateInverseDynamics(
            ids[key], list(q), list(qd), list(qdd), physicsClientId=cid
        )
        np.testing.assert_allclose(model, oracle, atol=1e-9, rtol=1e-7)
        np.testing.assert_allclose(by_regressor, oracle, atol=1e-9, rtol=1e-7)


def test_thesis_lumped_values_are_the_model_coefficients() -> None:
    """At the reference pose, single-joint models (3.73) see Table 3.4 exactly."""
    for params, table in (
        (E1, (0.0487, 0.0441, 0.0006, 0.2451, 0.1273, 0.1122)),
        (E2, (0.0528, 0.0427, 0.0005, 0.2605, 0.1305, 0.1155)),
    ):
        m = endobot.mass_matrix(np.zeros(4), params)
        np.testing.assert_allclose(np.diag(m), table[:4], rtol=1e-12)
        # gravity torque of joint i at small angle a: ml g sin(a) with g = 9.81 (3.73)
        a = 0.3
        g1 = endobot.gravity_vector([a, 0.0, 0.0, 0.0], params)[0]
        g2 = endobot.gravity_vector([0.0, a, 0.0, 0.0], params)[1]
        assert g1 == pytest.approx(table[4] * 9.81 * np.sin(a), rel=1e-12)
        assert g2 == pytest.approx(table[5] * 9.81 * np.sin(a), rel=1e-12)


@given(robots, joints)
def test_mass_matrix_symmetric_positive_definite(params: EndoBotParams, q: np.ndarray) -> None:
    m = endobot.mass_matrix(q, params)
    np.testing.assert_array_equal(m, m.T)
    assert np.linalg.eigvalsh(m).min() > 0.0


@given(robots, joints)
def test_closed_form_inverse_matches_numpy(params: EndoBotParams, q: np.ndarray) -> None:
    inv = dynamics.mass_matrix_inverse(q, params.coefficients)
    np.testing.assert_allclose(inv, np.linalg.inv(endobot.mass_matrix(q, params)), rtol=1e-10)


@given(robots, joints, velocities, st.tuples(*[st.floats(-1.0, 1.0)] * 4).map(np.array))
def test_mdot_minus_2c_is_skew_symmetric(
    params: EndoBotParams, q: np.ndarray, qd: np.ndarray, x: np.ndarray
) -> None:
    h = 1e-6
    mdot = (endobot.mass_matrix(q + h * qd, params) - endobot.mass_matrix(q - h * qd, params)) / (
        2 * h
    )
    s = mdot - 2.0 * endobot.coriolis_matrix(q, qd, params)
    np.testing.assert_allclose(s, -s.T, atol=1e-7)
    assert abs(x @ s @ x) < 1e-7


@given(robots, joints, velocities)
def test_coriolis_matrix_and_vector_agree(
    params: EndoBotParams, q: np.ndarray, qd: np.ndarray
) -> None:
    np.testing.assert_allclose(
        endobot.coriolis_matrix(q, qd, params) @ qd,
        endobot.coriolis_vector(q, qd, params),
        atol=1e-12,
    )


@given(robots, joints, velocities, accelerations, gravities)
def test_regressor_reproduces_the_model(
    params: EndoBotParams,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    g: tuple[float, float, float],
) -> None:
    par = dataclasses.replace(params, gravity=g)
    y = endobot.regressor(q, qd, qdd, par)
    theta = np.array(par.coefficients)
    np.testing.assert_allclose(y @ theta, endobot.inverse_dynamics(q, qd, qdd, par), atol=1e-10)


def test_regressor_columns_are_a_minimal_base_set() -> None:
    """Stacked over random motions, Y has full column rank: θ is identifiable (3.52)."""
    rng = np.random.default_rng(2)
    rows = []
    for _ in range(40):
        q = np.append(rng.uniform(-1, 1, 3), rng.uniform(0, 0.2))
        rows.append(endobot.regressor(q, rng.normal(size=4), rng.normal(size=4), E1))
    stacked = np.vstack(rows)
    assert np.linalg.matrix_rank(stacked) == dynamics.N_THETA == stacked.shape[1]


def test_gravity_is_the_gradient_of_potential_energy() -> None:
    """G = ∂P/∂q (3.31), with P summed over the rigid bodies by hand."""
    params = E1

    def potential(q: np.ndarray) -> float:
        r1 = endobot.rotation([q[0], 0.0, 0.0, 0.0])
        r = endobot.rotation(q)
        g = np.array(params.gravity)
        b1, b2, b3, b4 = params.bodies
        pos = [
            r1[:, 2] * b1.com_z,
            r[:, 2] * b2.com_z,
            r[:, 2] * b3.com_z,
            r[:, 2] * (q[3] + b4.com_z),
        ]
        return -sum(b.mass * float(g @ c) for b, c in zip(params.bodies, pos, strict=True))

    rng = np.random.default_rng(1)
    for _ in range(20):
        q = np.append(rng.uniform(-1, 1, 3), rng.uniform(0, 0.2))
        h = 1e-6
        fd = [
            (potential(q + h * np.eye(4)[i]) - potential(q - h * np.eye(4)[i])) / (2 * h)
            for i in range(4)
        ]
        np.testing.assert_allclose(endobot.gravity_vector(q, params), fd, atol=1e-8)
