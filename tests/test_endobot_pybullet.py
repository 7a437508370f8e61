"""The simulated EndoBot against PyBullet's own kinematics and against the model."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterator

import numpy as np
import pybullet as p
import pytest
from hypothesis import given
from hypothesis import strategies as st

from backends.pybullet.robot import EndoBotSim, SimulationError
from backends.pybullet.sensors import encoder_model, ft_sensor_model
from backends.pybullet.urdf import endobot_urdf
from suture_engine.robot import endobot
from suture_engine.robot.params import E1, E2

angle = st.floats(-1.0, 1.0)
joints = st.tuples(angle, angle, st.floats(-3.0, 3.0), st.floats(0.01, 0.2)).map(np.array)
velocities = st.tuples(*[st.floats(-2.0, 2.0)] * 3, st.floats(-0.2, 0.2)).map(np.array)
torques = st.tuples(*[st.floats(-0.5, 0.5)] * 3, st.floats(-3.0, 3.0)).map(np.array)

TILTED = p.getQuaternionFromEuler([math.pi + 0.3, -0.2, 0.7])


@pytest.fixture
def client() -> Iterator[int]:
    cid = p.connect(p.DIRECT)
    p.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)
    yield cid
    p.disconnect(cid)


@pytest.fixture(scope="module")
def tilted() -> Iterator[tuple[int, EndoBotSim]]:
    """One frictionless E2 on a tilted base, shared by the property tests."""
    cid = p.connect(p.DIRECT)
    p.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)
    sim = EndoBotSim(
        cid,
        E2,
        base_position=(0.1, -0.2, 0.4),
        base_orientation=TILTED,
        friction=False,
        saturate=False,
    )
    yield cid, sim
    p.disconnect(cid)


def _rot(quat: tuple[float, ...] | np.ndarray) -> np.ndarray:
    return np.array(p.getMatrixFromQuaternion(list(quat))).reshape(3, 3)


@given(joints)
def test_fk_matches_pybullet_link_state(tilted: tuple[int, EndoBotSim], q: np.ndarray) -> None:
    _, sim = tilted
    sim.reset(q)
    pos, orn = sim.true_tool_pose()
    r_base = _rot(TILTED)
    pose = endobot.forward_kinematics(q)
    np.testing.assert_allclose(pos, np.array([0.1, -0.2, 0.4]) + r_base @ pose.position, atol=1e-9)
    np.testing.assert_allclose(_rot(orn), r_base @ endobot.rotation(q), atol=1e-6)


@given(joints)
def test_jacobian_matches_pybullet_calculate_jacobian(q: np.ndarray) -> None:
    """calculateJacobian on an identity base (it ignores a fixed base's orientation)."""
    cid = p.connect(p.DIRECT)
    try:
        sim = EndoBotSim(cid, E1, base_position=(0, 0, 0), base_orientation=(0, 0, 0, 1))
        lin, ang = p.calculateJacobian(
            sim.body_id,
            sim.tool_link,
            [0.0, 0.0, 0.0],
            list(q),
            [0.0] * 4,
            [0.0] * 4,
            physicsClientId=cid,
        )
    finally:
        p.disconnect(cid)
    jg = endobot.geometric_jacobian(q)
    np.testing.assert_allclose(jg[:3], np.array(lin), atol=1e-9)
    np.testing.assert_allclose(jg[3:], np.array(ang), atol=1e-9)


@given(joints, velocities, torques)
def test_one_step_follows_the_model_on_a_tilted_base(
    tilted: tuple[int, EndoBotSim], q: np.ndarray, qd: np.ndarray, tau: np.ndarray
) -> None:
    """PyBullet's forward dynamics = M⁻¹(τ - C q̇ - G) with the base-frame gravity."""
    cid, sim = tilted
    sim.reset(q, qd)
    sim.apply(tau)
    p.stepSimulation(physicsClientId=cid)
    _, qd1 = sim.true_state()
    par = sim.model_params
    qdd = np.linalg.solve(
        endobot.mass_matrix(q, par),
        tau - endobot.coriolis_vector(q, qd, par) - endobot.gravity_vector(q, par),
    )
    np.testing.assert_allclose((qd1 - qd) / sim.dt, qdd, rtol=1e-6, atol=1e-6)


def _urdf_moving_mass(params: object) -> float:
    root = ET.fromstring(endobot_urdf(params))  # type: ignore[arg-type]
    return sum(
        float(link.find("inertial/mass").get("value"))  # type: ignore[union-attr, arg-type]
        for link in root.iter("link")
        if link.get("name") != "mount" and link.find("inertial") is not None
    )


@pytest.mark.parametrize("orientation", [(1.0, 0.0, 0.0, 0.0), TILTED])
def test_base_ft_sensor_reads_the_weight_when_static(
    client: int, orientation: tuple[float, ...]
) -> None:
    sim = EndoBotSim(client, E1, base_position=(0, 0, 0.5), base_orientation=orientation)
    q = np.array([0.3, -0.2, 0.5, 0.12])
    sim.reset(q)
    for _ in range(200):  # hold still with gravity compensation
        sim.step(endobot.gravity_vector(sim.true_state().q, sim.model_params))
    state = sim.true_state()
    assert np.abs(state.qd).max() < 1e-9
    wrench = sim.measure().base_wrench.values
    mass = _urdf_moving_mass(E1)
    assert mass == pytest.approx(E1.total_mass + 0.5)  # + the static frame
    r_base = _rot(orientation)
    g = np.array([0.0, 0.0, -9.81])
    np.testing.assert_allclose(wrench[:3], r_base.T @ (-mass * g), atol=1e-6)
    # moment about the RCM of the weights at PyBullet's own link COM positions
    rcm = np.array([0.0, 0.0, 0.5])
    moment = np.zeros(3)
    for link in range(p.getNumJoints(sim.body_id, physicsClientId=client)):
        m = p.getDynamicsInfo(sim.body_id, link, physicsClientId=client)[0]
        com = np.array(p.getLinkState(sim.body_id, link, physicsClientId=client)[0])
        moment -= np.cross(com - rcm, m * g)
    np.testing.assert_allclose(wrench[3:], r_base.T @ moment, atol=1e-6)


def test_static_friction_holds_without_chatter(client: int) -> None:
    sim = EndoBotSim(client, E1, friction_model="c")
    q0 = np.array([0.2, -0.3, 0.4, 0.1])
    sim.reset(q0)
    below = np.array([f.friction.static for f in E1.joints]) * 0.9 * np.array([1, -1, 1, -1])
    signs = []
    for _ in range(1000):
        sim.step(endobot.gravity_vector(sim.true_state().q, sim.model_params) + below)
        signs.append(np.sign(sim.last_friction))
    state = sim.true_state()
    np.testing.assert_allclose(state.q, q0, atol=1e-9)
    assert np.abs(state.qd).max() < 1e-9
    assert np.all(np.array(signs) == np.sign(below))  # friction never flips: no chatter
    np.testing.assert_allclose(sim.last_friction, below, rtol=1e-6)


@pytest.fixture(scope="module")
def rough() -> Iterator[EndoBotSim]:
    """One E1 with static friction (model c), shared by the stiction property tests."""
    cid = p.connect(p.DIRECT)
    p.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)
    yield EndoBotSim(cid, E1, friction_model="c")
    p.disconnect(cid)


@given(joints, st.tuples(*[st.floats(-0.95, 0.95)] * 4).map(np.array))
def test_any_load_below_static_friction_is_held(
    rough: EndoBotSim, q: np.ndarray, k: np.ndarray
) -> None:
    """Joints 1 and 3 couple through M; every joint must still stay exactly at rest."""
    rough.reset(q)
    load = k * np.array([j.friction.static for j in E1.joints])
    for _ in range(30):
        rough.step(endobot.gravity_vector(rough.true_state().q, rough.model_params) + load)
    state = rough.true_state()
    np.testing.assert_allclose(state.q, q, atol=1e-9)
    np.testing.assert_allclose(rough.last_friction, load, atol=1e-9)


@pytest.mark.parametrize("model", ["b", "c"])
def test_static_friction_holds_against_a_steady_push_on_the_tool(client: int, model: str) -> None:
    """A push below the friction level must not make the joints creep; the estimated
    unmodelled torque equals Jᵀ F (oracle: the geometric Jacobian and the force)."""
    sim = EndoBotSim(client, E1, friction_model=model)
    q0 = np.array([0.2, -0.1, 0.3, 0.1])
    sim.reset(q0)
    force_world = np.array([0.3, 0.2, 0.0])  # [N]
    for _ in range(2000):
        sim.apply(endobot.gravity_vector(sim.true_state().q, sim.model_params))
        pos, _ = sim.true_tool_pose()
        p.applyExternalForce(
            sim.body_id,
            sim.tool_link,
            force_world.tolist(),
            pos.tolist(),
            p.WORLD_FRAME,
            physicsClientId=client,
        )
        p.stepSimulation(physicsClientId=client)
    q = sim.true_state().q
    # one step of motion before the push is known (~1e-6), then no creep at all
    np.testing.assert_allclose(q, q0, atol=2e-6)
    force_base = _rot((1.0, 0.0, 0.0, 0.0)).T @ force_world  # EndoBotSim's default base
    expected = endobot.geometric_jacobian(q)[:3].T @ force_base
    np.testing.assert_allclose(sim.external_torque, expected, atol=1e-7)
    np.testing.assert_allclose(sim.last_friction, expected, atol=1e-7)


def test_breakaway_above_static_friction(client: int) -> None:
    sim = EndoBotSim(client, E1, friction_model="d")
    sim.reset([0.0, 0.0, 0.0, 0.1])
    fs = np.array([f.friction.static for f in E1.joints])
    for _ in range(100):
        sim.step(endobot.gravity_vector(sim.true_state().q, sim.model_params) + 1.1 * fs)
    assert np.all(sim.true_state().qd > 1e-4)


def test_steady_velocity_is_coulomb_plus_viscous(client: int) -> None:
    """Constant torque τ > Fc without gravity: q̇ → (τ - Fc)/Fv (3.43) on roll and insertion."""
    p.setGravity(0.0, 0.0, 0.0, physicsClientId=client)
    sim = EndoBotSim(client, E1)
    sim.reset([0.0, 0.0, 0.0, 0.02])
    tau = np.array([0.0, 0.0, 0.1, 0.1])
    for _ in range(3000):
        sim.step(tau)
    qd = sim.true_state().qd
    roll, ins = E1.joints[2].friction, E1.joints[3].friction
    assert qd[2] == pytest.approx((0.1 - roll.coulomb) / roll.viscous, rel=1e-6)
    assert qd[3] == pytest.approx((0.1 - ins.coulomb) / ins.viscous, rel=1e-3)
    assert abs(qd[0]) < 1e-9 and abs(qd[1]) < 1e-9


def _run(seed: int) -> np.ndarray:
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)
        sim = EndoBotSim(
            cid,
            E2,
            encoder=encoder_model(E2, noise_std=1e-4, dropout=0.05, delay_ticks=1),
            ft_sensor=ft_sensor_model(force_noise_std=0.05, torque_noise_std=0.005),
            seed=seed,
        )
        out = []
        for k in range(300):
            m = sim.step(0.3 * np.sin(np.array([1.0, 2.0, 3.0, 4.0]) * k * 1e-2))
            out.append(np.concatenate([m.joints.values, m.base_wrench.values]))
        return np.array(out)
    finally:
        p.disconnect(cid)


def test_deterministic_for_a_seed() -> None:
    a, b = _run(3), _run(3)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, _run(4))


def test_only_positions_are_measured_and_bad_commands_are_typed(client: int) -> None:
    sim = EndoBotSim(client, E1)
    m = sim.measure()
    assert m.joints.values.shape == (4,) and m.base_wrench.values.shape == (6,)
    assert set(m._fields) == {"joints", "base_wrench"}
    with pytest.raises(SimulationError):
        sim.apply([0.0, 0.0, math.nan, 0.0])
    with pytest.raises(SimulationError):
        sim.apply([0.0, 0.0])


def test_torque_saturates_at_the_motor_limit(client: int) -> None:
    sim = EndoBotSim(client, E1)
    sim.apply([100.0, -100.0, 0.0, 0.0])
    assert sim.last_command[0] == pytest.approx(E1.joints[0].motor.max_torque)
    assert sim.last_command[1] == pytest.approx(-E1.joints[1].motor.max_torque)
