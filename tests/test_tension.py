"""Tension estimation from the base F/T sensor (7.5-7.10) against PyBullet.

Oracle: PyBullet's own physics. A known force is applied at (or near) the
tool tip with ``applyExternalForce``; the robot is held static by torques from
PyBullet's ``calculateInverseDynamics`` (gravity) and ``calculateJacobian``
(J^T F), so nothing of the estimator's model enters the simulated reading.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from suture_engine.robot import endobot
from suture_engine.suture.tension import (
    TensionEstimator,
    TensionEstimatorError,
    gravity_wrench,
    tip_wrench,
    wrench_transform,
)

pb = pytest.importorskip("pybullet")


@pytest.fixture()
def sim():  # type: ignore[no-untyped-def]
    from backends.pybullet.robot import EndoBotSim

    cid = pb.connect(pb.DIRECT)
    # PyBullet's calculateInverseDynamics ignores a fixed base's orientation, so the
    # base stays unrotated here; a skewed gravity still exercises every axis.
    pb.setGravity(1.5, -2.0, 9.5, physicsClientId=cid)
    robot = EndoBotSim(cid, base_orientation=(0.0, 0.0, 0.0, 1.0), friction=False, saturate=False)
    yield robot
    pb.disconnect(cid)


def _hold(sim, q, force_world, point_local=(0.0, 0.0, 0.0)):  # type: ignore[no-untyped-def]
    """Apply a world force at a point of the tool link, hold the robot with PyBullet's
    own inverse dynamics and Jacobian, step once; return (reading, |qd|)."""
    sim.reset(q)
    cid, body, link = sim.client, sim.body_id, sim.tool_link
    ql = [float(x) for x in q]
    zero = [0.0] * 4
    g_tau = np.array(pb.calculateInverseDynamics(body, ql, zero, zero, physicsClientId=cid))
    jl, _ = pb.calculateJacobian(body, link, list(point_local), ql, zero, zero, physicsClientId=cid)
    tau = g_tau - np.array(jl).T @ np.asarray(force_world)
    pos, orn = pb.getLinkState(body, link, computeForwardKinematics=True, physicsClientId=cid)[4:6]
    rot = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)
    at = np.asarray(pos) + rot @ np.asarray(point_local)
    pb.applyExternalForce(
        body, link, list(force_world), at.tolist(), pb.WORLD_FRAME, physicsClientId=cid
    )
    meas = sim.step(tau)
    return meas.base_wrench.values, float(np.abs(sim.true_state().qd).max())


def _random_pose(rng: np.random.Generator) -> np.ndarray:
    return np.array(
        [rng.uniform(-0.8, 0.8), rng.uniform(-0.8, 0.8), rng.uniform(-2.0, 2.0), 0.03]
    ) + np.array([0.0, 0.0, 0.0, rng.uniform(0.0, 0.15)])


def test_unloaded_reading_is_the_gravity_model_plus_a_constant(sim) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(3)
    np.testing.assert_allclose(sim._base_rot, np.eye(3), atol=1e-12)
    offsets = []
    for _ in range(6):
        q = _random_pose(rng)
        reading, qd = _hold(sim, q, np.zeros(3))
        assert qd < 1e-6
        offsets.append(reading - gravity_wrench(q, sim.model_params))
    offsets_a = np.array(offsets)
    # the constant is the static frame above the sensor: 0.5 kg at z = -0.25 m (the URDF)
    np.testing.assert_allclose(offsets_a - offsets_a[0], 0.0, atol=1e-6)
    g = np.array(sim.model_params.gravity)
    static = -np.concatenate((0.5 * g, np.cross((0.0, 0.0, -0.25), 0.5 * g)))
    np.testing.assert_allclose(offsets_a[0], static, atol=1e-6)


def test_estimator_recovers_a_known_tip_force_at_random_static_poses(sim) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(7)
    base_rot = sim._base_rot  # world <- base
    q0 = np.array([0.1, -0.1, 0.0, 0.08])
    est = TensionEstimator((1.0, 0.0, 0.0), sim.model_params, cutoff=math.inf)
    reading, _ = _hold(sim, q0, np.zeros(3))
    est.tare(reading, q0)
    for _ in range(12):
        q = _random_pose(rng)
        f_world = rng.uniform(-15.0, 15.0, 3)
        e = rng.normal(size=3)
        e /= np.linalg.norm(e)
        est.set_direction(e)
        reading, qd = _hold(sim, q, f_world)
        assert qd < 1e-6  # held static: the motion wrench really is zero
        out = est.update(reading, q)
        f_base = base_rot.T @ f_world
        np.testing.assert_allclose(out.force, f_base, atol=2e-4)
        np.testing.assert_allclose(out.moment, 0.0, atol=2e-4)  # a pure tip force
        assert out.tension == pytest.approx(-float(f_base @ e), abs=2e-4)


def test_moment_at_the_tip_of_an_off_tip_force(sim) -> None:  # type: ignore[no-untyped-def]
    """A force applied 2 cm off the tip leaves the moment r x f about the tip (7.9)."""
    rng = np.random.default_rng(11)
    base_rot = sim._base_rot
    q = np.array([0.3, -0.2, 0.7, 0.1])
    unloaded, _ = _hold(sim, q, np.zeros(3))
    est = TensionEstimator((0.0, 0.0, 1.0), sim.model_params, cutoff=math.inf)
    est.tare(unloaded, q)
    local = np.array([0.0, 0.02, -0.01])  # in the tool frame
    f_world = rng.uniform(-10.0, 10.0, 3)
    reading, _ = _hold(sim, q, f_world, local)
    out = est.update(reading, q)
    r_base = endobot.rotation(q) @ local
    f_base = base_rot.T @ f_world
    np.testing.assert_allclose(out.force, f_base, atol=2e-4)
    np.testing.assert_allclose(out.moment, np.cross(r_base, f_base), atol=2e-4)


def test_wrench_transform_preserves_power() -> None:
    """The adjoint pair: a wrench's power on a rigid-body twist is frame-independent."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        w = rng.normal(size=6)
        rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        p = rng.normal(size=3)
        v_o, omega = rng.normal(size=3), rng.normal(size=3)
        power_o = w[:3] @ v_o + w[3:] @ omega
        v_e = v_o + np.cross(omega, p)  # velocity of the point p
        we = wrench_transform(w, rot, p)
        power_e = we[:3] @ (rot.T @ v_e) + we[3:] @ (rot.T @ omega)
        assert power_e == pytest.approx(power_o, rel=1e-10, abs=1e-10)


def test_tip_wrench_without_load_is_zero_for_the_model() -> None:
    q = [0.2, 0.1, -0.3, 0.12]
    np.testing.assert_allclose(tip_wrench(gravity_wrench(q), q), 0.0, atol=1e-12)


def test_low_pass_time_constant() -> None:
    """A step of force settles like a first-order lag of cut-off fc: 63% after 1/(2 pi fc)."""
    q = [0.0, 0.0, 0.0, 0.1]
    est = TensionEstimator((1.0, 0.0, 0.0), dt=1e-3, cutoff=10.0)
    unloaded = gravity_wrench(q)
    est.update(unloaded, q)
    loaded = unloaded.copy()
    loaded[0] += 5.0  # mount pushes +x: the environment pulls the tool -x, tension +5 N
    loaded[3:] += np.cross([0.0, 0.0, 0.1], [5.0, 0.0, 0.0])
    n_tau = round(1.0 / (2.0 * math.pi * 10.0) / 1e-3)
    values = [est.update(loaded, q).tension for _ in range(5 * n_tau)]
    assert values[n_tau - 1] == pytest.approx(5.0 * (1.0 - math.exp(-1.0)), rel=0.03)
    assert values[-1] == pytest.approx(5.0, rel=0.01)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"direction": (0.0, 0.0, 0.0)}, "direction"),
        ({"direction": (1.0, 0.0, 0.0), "dt": 0.0}, "dt"),
        ({"direction": (1.0, 0.0, 0.0), "cutoff": -1.0}, "cutoff"),
    ],
)
def test_bad_configuration_is_a_typed_error(kwargs: dict[str, object], name: str) -> None:
    with pytest.raises(TensionEstimatorError) as err:
        TensionEstimator(**kwargs)  # type: ignore[arg-type]
    assert err.value.name == name
