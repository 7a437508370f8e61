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
from backends.pybullet.sensors import Sensor, SensorModel, encoder_model, ft_sensor_model
from backends.pybullet.urdf import endobot_urdf
from suture_engine.robot import dynamics, endobot
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


class _ReferenceFriction:
    """The friction solve as first written (numpy dynamics, full 4x4 sweeps): the oracle
    the per-tick float path must reproduce."""

    def __init__(self, sim: EndoBotSim, model: str) -> None:
        self.th = sim.model_params.coefficients
        self.g = sim.model_params.gravity
        self.dt = sim.dt
        fr = [j.friction for j in sim.params.joints]
        self.fc = [f.coulomb for f in fr]
        self.fv = [0.0 if model == "a" else f.viscous for f in fr]
        self.fs = [f.static for f in fr]
        self.vs = [f.stribeck_velocity for f in fr]
        self.ds = [f.stribeck_exponent for f in fr]
        self.static = model in ("c", "d")
        self.stribeck = model == "d"
        self.reset()

    def reset(self) -> None:
        self.predicted: list[float] | None = None
        self.last_state: tuple[list[float], list[float]] = ([], [])
        self.last_mass: list[list[float]] = []
        self.external = np.zeros(4)

    def __call__(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> np.ndarray:
        th, dt = self.th, self.dt
        rest = (
            tau - dynamics.coriolis_vector(q, qd, th) - dynamics.gravity_vector(q, th, self.g)
        ).tolist()
        wl = [[dt * x for x in row] for row in dynamics.mass_matrix_inverse(q, th)]
        ql, qdl = q.tolist(), qd.tolist()
        if self.predicted is not None and (ql, qdl) != self.last_state:
            dv = [a - b for a, b in zip(qdl, self.predicted, strict=True)]
            m = self.last_mass
            self.external = self.external + np.array(
                [sum(m[i][j] * dv[j] for j in range(4)) / dt for i in range(4)]
            )
        self.last_state = (ql, qdl)
        self.last_mass = dynamics.mass_matrix(q, th).tolist()
        rest = [r + e for r, e in zip(rest, self.external.tolist(), strict=True)]
        vf = [qdl[i] + sum(wl[i][j] * rest[j] for j in range(4)) for i in range(4)]
        slide, brk = [], []
        for i in range(4):
            at_rest = abs(qdl[i]) <= 1e-7
            fc = self.fc[i]
            if self.stribeck and not at_rest:
                fc += (self.fs[i] - fc) * math.exp(-(abs(qdl[i] / self.vs[i]) ** self.ds[i]))
            slide.append(fc)
            brk.append(self.fs[i] if (self.static and at_rest) else fc)
        tf = [0.0] * 4
        for _ in range(4):
            for i in range(4):
                v_other = vf[i] - sum(wl[i][j] * tf[j] for j in range(4) if j != i)
                wii = wl[i][i]
                if abs(v_other) <= wii * brk[i]:
                    tf[i] = v_other / wii
                else:
                    s = 1.0 if v_other > 0.0 else -1.0
                    v = (v_other - wii * slide[i] * s) / (1.0 + wii * self.fv[i])
                    tf[i] = slide[i] * s + self.fv[i] * v
        self.predicted = [vf[i] - sum(wl[i][j] * tf[j] for j in range(4)) for i in range(4)]
        return np.array(tf)


@pytest.mark.parametrize("model", ["a", "b", "c", "d"])
def test_friction_solve_matches_the_reference_solve(client: int, model: str) -> None:
    """Tracking, holding below break-away, a push on the tool and a teleport, on a tilted
    base: the friction torques and the unmodelled-torque estimate equal the reference
    solve's (same inputs every step) to 1e-12, and both solve branches run."""
    sim = EndoBotSim(client, E2, base_orientation=TILTED, friction_model=model, saturate=False)
    ref = _ReferenceFriction(sim, model)
    fs = np.array([j.friction.static for j in E2.joints])
    held = slid = 0
    for k in range(700):
        q, qd = sim.true_state()
        grav = endobot.gravity_vector(q, sim.model_params)
        if k == 350:
            sim.reset([0.1, 0.4, -0.2, 0.08])  # a teleport voids the prediction
            ref.reset()
            q, qd = sim.true_state()
            grav = endobot.gravity_vector(q, sim.model_params)
        if k % 350 < 120:  # hold: a load below static friction
            tau = grav + 0.8 * fs * np.array([1.0, -1.0, 1.0, -1.0])
        else:  # track a moving target
            t = k * sim.dt
            target = np.array([0.3 * math.sin(4 * t), 0.2 * math.sin(5 * t), math.sin(3 * t), 0.06])
            tau = grav + np.array([3.0, 3.0, 0.3, 80.0]) * (target - q) - 0.02 * qd
        if 200 <= k < 260:
            pos, _ = sim.true_tool_pose()
            p.applyExternalForce(
                sim.body_id, sim.tool_link, [0.4, -0.3, 0.2], pos.tolist(), p.WORLD_FRAME,
                physicsClientId=client,
            )  # fmt: skip
        sim.apply(tau)
        expected = ref(q, qd, tau)
        np.testing.assert_allclose(sim.last_friction, expected, rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(sim.external_torque, ref.external, rtol=0.0, atol=1e-12)
        p.stepSimulation(physicsClientId=client)
        qd_after = sim.true_state().qd
        held += int(np.sum((np.abs(qd_after) <= 1e-9) & (np.abs(expected) > 0.0)))
        slid += int(np.sum(np.abs(qd_after) > 1e-4))
    assert held > 100 and slid > 100
    assert np.abs(ref.external).max() > 0.0 or model == "a"


@given(joints, velocities)
def test_base_wrench_is_the_reaction_moved_to_the_rcm(
    tilted: tuple[int, EndoBotSim], q: np.ndarray, qd: np.ndarray
) -> None:
    """M + c × F with the previous np.cross computation, and what the ideal sensors read."""
    cid, sim = tilted
    sim.reset(q, qd)
    sim.apply([0.1, -0.05, 0.02, 0.3])
    p.stepSimulation(physicsClientId=cid)
    raw = np.array(p.getJointState(sim.body_id, sim.ft_joint, physicsClientId=cid)[2])
    com = np.array(p.getDynamicsInfo(sim.body_id, sim.ft_joint, physicsClientId=cid)[3])
    expected = np.concatenate([raw[:3], raw[3:] + np.cross(com, raw[:3])])
    np.testing.assert_array_equal(sim.true_base_wrench(), expected)
    m = sim.measure()
    np.testing.assert_array_equal(m.base_wrench.values, expected + 0.0)
    np.testing.assert_array_equal(m.joints.values, sim.true_state().q + 0.0)


def test_apply_checks_floats_like_numpy(client: int) -> None:
    sim = EndoBotSim(client, E1, friction=False)
    lim = np.array([j.motor.max_torque for j in E1.joints])
    for tau in ([0.5, -0.5, 0.01, -40.0], np.array([1e308, 1e308, 0.0, 0.0]), [-0.0, 0, 1, 2]):
        sim.apply(tau)  # an overflowing sum of finite torques is no error
        np.testing.assert_array_equal(sim.last_command, np.clip(np.asarray(tau, float), -lim, lim))
    sim.apply(np.array([0.1, 0.2, 0.3, 0.4], dtype=np.float32))
    np.testing.assert_array_equal(sim.last_command, np.array([0.1, 0.2, 0.3, 0.4], np.float32))
    for bad in ([math.inf, 0.0, 0.0, 0.0], [0.0, -math.inf, 0.0, math.inf], np.zeros((2, 2))):
        with pytest.raises(SimulationError):
            sim.apply(bad)


def test_ideal_sensors_skip_draws_only_when_no_one_can_see_them(client: int) -> None:
    """Noisy F/T on the encoders' generator: both draw, so the F/T noise is the seeded
    stream's (normals for 4 encoder channels, a dropout uniform, 6 F/T normals, a
    uniform per tick). All ideal, or the F/T on its own generator: no ideal draws."""
    std = np.array([0.05, 0.05, 0.05, 0.0, 0.0, 0.0])
    noisy = SensorModel(noise_std=tuple(std.tolist()))
    sim = EndoBotSim(client, E1, ft_sensor=noisy, seed=11)
    stream = np.random.default_rng(11)
    for _ in range(5):
        sim.apply(endobot.gravity_vector(sim.true_state().q, sim.model_params))
        p.stepSimulation(physicsClientId=client)
        truth = sim.true_base_wrench()
        m = sim.measure()
        stream.standard_normal(4)
        stream.random()
        noise = stream.standard_normal(6)
        stream.random()
        np.testing.assert_array_equal(m.base_wrench.values, truth + 0.0 + std * noise)
    assert sim._encoder.draw_when_ideal and not sim._ft.draw_when_ideal
    sim._ft = Sensor(noisy, 6, np.random.default_rng(1))  # as the backend swaps it
    sim.measure()
    assert not sim._encoder.draw_when_ideal
    quiet = EndoBotSim(client, E1, seed=11)
    quiet.measure()
    assert not quiet._encoder.draw_when_ideal and not quiet._ft.draw_when_ideal
