"""EndoBot kinematics against finite differences, hand-built rotations and PyBullet."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from suture_engine.robot import endobot
from suture_engine.robot.kinematics import UnreachablePose

angle = st.floats(-1.4, 1.4)
insertion = st.floats(0.01, 0.25)
joints = st.tuples(angle, angle, st.floats(-3.0, 3.0), insertion).map(np.array)


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _fk_oracle(q: np.ndarray) -> np.ndarray:
    """Hand-built product of elementary rotations (3.5-3.6), independent of the module."""
    r = _rx(q[0]) @ _ry(q[1]) @ _rz(q[2])
    return r @ np.array([0.0, 0.0, q[3]])


@given(joints)
def test_fk_matches_product_of_rotations(q: np.ndarray) -> None:
    pose = endobot.forward_kinematics(q)
    np.testing.assert_allclose(pose.position, _fk_oracle(q), atol=1e-12)
    assert pose.roll == pytest.approx(q[2])
    np.testing.assert_allclose(endobot.rotation(q), _rx(q[0]) @ _ry(q[1]) @ _rz(q[2]), atol=1e-12)


@given(joints)
def test_ik_round_trip(q: np.ndarray) -> None:
    pose = endobot.forward_kinematics(q)
    q_back = endobot.inverse_kinematics(pose.position, pose.roll)
    np.testing.assert_allclose(q_back, q, atol=1e-9)


@given(st.tuples(st.floats(-0.2, 0.2), st.floats(-0.2, 0.2), st.floats(0.01, 0.2)))
def test_ik_then_fk_reaches_the_point(p: tuple[float, float, float]) -> None:
    q = endobot.inverse_kinematics(p, 0.3)
    np.testing.assert_allclose(endobot.forward_kinematics(q).position, p, atol=1e-12)


def test_ik_rejects_the_rcm_and_nan() -> None:
    with pytest.raises(UnreachablePose) as err:
        endobot.inverse_kinematics((0.0, 0.0, 0.0), 0.0)
    assert err.value.code == "unreachable-pose"
    with pytest.raises(UnreachablePose):
        endobot.inverse_kinematics((math.nan, 0.0, 0.1), 0.0)


def _task(q: np.ndarray) -> np.ndarray:
    return np.append(_fk_oracle(q), q[2])


@given(joints)
def test_analytical_jacobian_matches_central_differences(q: np.ndarray) -> None:
    h = 1e-6
    fd = np.column_stack(
        [(_task(q + h * np.eye(4)[i]) - _task(q - h * np.eye(4)[i])) / (2 * h) for i in range(4)]
    )
    np.testing.assert_allclose(endobot.jacobian(q), fd, atol=1e-8)


@given(joints)
def test_geometric_jacobian_angular_part_matches_rotation_derivative(q: np.ndarray) -> None:
    """ω̂ = Ṙ Rᵀ, with Ṙ from central differences along each joint."""
    h = 1e-6
    jg = endobot.geometric_jacobian(q)
    r = _rx(q[0]) @ _ry(q[1]) @ _rz(q[2])
    for i in range(4):
        dq = h * np.eye(4)[i]
        rp = _rx(q[0] + dq[0]) @ _ry(q[1] + dq[1]) @ _rz(q[2] + dq[2])
        rm = _rx(q[0] - dq[0]) @ _ry(q[1] - dq[1]) @ _rz(q[2] - dq[2])
        w = (rp - rm) / (2 * h) @ r.T
        np.testing.assert_allclose(jg[3:, i], [w[2, 1], w[0, 2], w[1, 0]], atol=1e-8)
    np.testing.assert_allclose(jg[:3], endobot.jacobian(q)[:3], atol=1e-15)


@given(joints)
def test_determinant_and_manipulability(q: np.ndarray) -> None:
    j = endobot.jacobian(q)
    assert endobot.jacobian_determinant(q) == pytest.approx(np.linalg.det(j), abs=1e-12)
    assert endobot.manipulability(q) == pytest.approx(
        math.sqrt(max(np.linalg.det(j @ j.T), 0.0)), abs=1e-9
    )


def test_singularities_of_3_23() -> None:
    assert endobot.is_singular([0.2, math.pi / 2, 0.0, 0.1])
    assert endobot.is_singular([0.2, -math.pi / 2, 0.0, 0.1])
    assert endobot.is_singular([0.2, 0.3, 0.0, 0.0])
    assert not endobot.is_singular([0.2, 0.3, 0.0, 0.1])
    assert np.linalg.matrix_rank(endobot.jacobian([0.2, math.pi / 2, 0.0, 0.1])) < 4
    assert np.linalg.matrix_rank(endobot.jacobian([0.2, 0.3, 0.0, 0.1])) == 4


def test_jacobian_out_argument_is_filled() -> None:
    out = np.full((4, 4), 7.0)
    res = endobot.jacobian([0.1, 0.2, 0.3, 0.1], out=out)
    assert res is out
    np.testing.assert_allclose(out, endobot.jacobian([0.1, 0.2, 0.3, 0.1]))


@given(joints)
def test_task_vector_is_the_product_of_rotations_and_the_roll(q: np.ndarray) -> None:
    from suture_engine.robot.kinematics import task_vector

    x = task_vector(q)
    np.testing.assert_allclose(x[:3], _fk_oracle(q), atol=1e-12)
    assert x[3] == q[2]


@given(joints)
def test_task_vector_and_jacobian_match_fk_and_central_differences(q: np.ndarray) -> None:
    from suture_engine.robot.kinematics import task_vector_and_jacobian

    buf = np.full((4, 4), np.nan)
    x, jac = task_vector_and_jacobian(q, out=buf)
    assert jac is buf
    np.testing.assert_allclose(x[:3], _fk_oracle(q), atol=1e-12)
    h = 1e-6
    fd = np.empty((4, 4))
    for k in range(4):
        dq = np.zeros(4)
        dq[k] = h
        xp = np.r_[_fk_oracle(q + dq), q[2] + dq[2]]
        xm = np.r_[_fk_oracle(q - dq), q[2] - dq[2]]
        fd[:, k] = (xp - xm) / (2 * h)
    np.testing.assert_allclose(jac, fd, atol=1e-8)
    # The per-tick form must give the very same bits as the separate functions (the
    # traces of move-constrained are compared byte for byte).
    assert x.tobytes() == np.r_[endobot.forward_kinematics(q).position, q[2]].tobytes()
    assert jac.tobytes() == endobot.jacobian(q).tobytes()
