"""Shared control (chapter 6): torques against energy gradients and finite differences,
the joint-space set point (6.35-6.36), the stiffness metric, and a short PyBullet run."""

from __future__ import annotations

import numpy as np
import pytest

from suture_engine.control.fixtures import Circle, Cone, Line, Plane
from suture_engine.control.shared import (
    SharedControlError,
    TaskSpaceGains,
    constraint_force,
    effective_stiffness,
    joint_space_setpoint,
    joint_space_shared_control,
    task_space_shared_control,
    task_vector,
)
from suture_engine.robot import endobot

LINE = Line(point=np.zeros(3), direction=np.array([1.0, -1.0, 2.0]))
CIRCLE = Circle(center=np.array([0.0, 0.0, 0.15]), radius=0.05)
PLANE = Plane(point=np.array([0.0, 0.0, 0.12]), normal=np.array([0.1, 0.0, 1.0]))


def _configs(seed: int, n: int = 15) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [
        np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-1, 1), 0.1])
        + np.array([0, 0, 0, rng.uniform(0, 0.08)])
        for _ in range(n)
    ]


@pytest.mark.parametrize("fx", [LINE, CIRCLE, PLANE], ids=lambda f: f.name)
def test_task_space_spring_is_the_gradient_of_its_energy(fx) -> None:  # type: ignore[no-untyped-def]
    # With Kv = 0 and no gravity, (6.24) is tau = -dV/dq of V = 1/2 Kp |C(k(q))|^2.
    kp = 800.0
    gains = TaskSpaceGains(stiffness=kp, damping=0.0)

    def energy(q: np.ndarray) -> float:
        c = fx.value(task_vector(q))
        return 0.5 * kp * float(c @ c)

    h = 1e-7
    for q in _configs(1):
        tau = task_space_shared_control(fx, q, np.zeros(4), gains).tau
        grad = np.array([(energy(q + h * e) - energy(q - h * e)) / (2 * h) for e in np.eye(4)])
        np.testing.assert_allclose(tau, -grad, atol=1e-6)


def test_task_space_damper_dissipates_and_matches_finite_differences() -> None:
    kv = 25.0
    gains = TaskSpaceGains(stiffness=0.0, damping=kv)
    rng = np.random.default_rng(2)
    for q in _configs(3):
        qd = rng.normal(size=4) * 0.3
        out = task_space_shared_control(LINE, q, qd, gains)
        h = 1e-7
        cdot = (LINE.value(task_vector(q + h * qd)) - LINE.value(task_vector(q - h * qd))) / (2 * h)
        np.testing.assert_allclose(out.constraint_force, -kv * cdot, atol=1e-6)
        # Power into the robot is -Kv |C-dot|^2 <= 0 (6.21).
        assert qd @ out.tau == pytest.approx(-kv * cdot @ cdot, rel=1e-6, abs=1e-12)


def test_gravity_is_added() -> None:
    q = np.array([0.2, 0.1, 0.0, 0.12])
    g = endobot.gravity_vector(q)
    a = task_space_shared_control(LINE, q, np.zeros(4), TaskSpaceGains()).tau
    b = task_space_shared_control(LINE, q, np.zeros(4), TaskSpaceGains(), gravity=g).tau
    np.testing.assert_allclose(b - a, g)


def test_cone_pushes_only_from_outside() -> None:
    cone = Cone(apex=np.zeros(3), axis=np.array([0.0, 0.0, 1.0]), half_angle=0.3)
    inside = endobot.inverse_kinematics(np.array([0.0, 0.0, 0.1]), 0.0)
    outside = endobot.inverse_kinematics(np.array([0.08, 0.0, 0.1]), 0.0)
    g = TaskSpaceGains(stiffness=500.0, damping=0.0)
    np.testing.assert_allclose(task_space_shared_control(cone, inside, np.zeros(4), g).tau, 0.0)
    out = task_space_shared_control(cone, outside, np.zeros(4), g)
    assert out.deviation[0] > 0 and out.constraint_force[0] < 0
    # The push lowers g: a small step along -J^-1 (force) moves the tip back inside.
    tau = out.tau
    step = np.linalg.solve(endobot.mass_matrix(outside), tau) * 1e-4
    assert cone.value(task_vector(outside + step))[0] < out.deviation[0]


@pytest.mark.parametrize("fx", [LINE, CIRCLE, PLANE], ids=lambda f: f.name)
def test_joint_space_setpoint_6_35_6_36(fx) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(4)
    for q in _configs(5):
        qd = rng.normal(size=4) * 0.2
        sp = joint_space_setpoint(fx, q, qd)
        x = task_vector(q)
        # (6.35): on the fixture, same free coordinates as the measured pose.
        np.testing.assert_allclose(fx.value(sp.x), 0.0, atol=1e-12)
        np.testing.assert_allclose(fx.free(sp.x), fx.free(x), atol=1e-10)
        np.testing.assert_allclose(task_vector(sp.q), sp.x, atol=1e-12)  # q_d = k^-1(x_d)
        # (6.36): x_d's velocity equals the time derivative of (6.35) along the motion.
        h = 1e-6
        xp = joint_space_setpoint(fx, q + h * qd, qd).x
        xm = joint_space_setpoint(fx, q - h * qd, qd).x
        np.testing.assert_allclose(sp.xd, (xp - xm) / (2 * h), atol=1e-6)
        np.testing.assert_allclose(endobot.jacobian(q) @ sp.qd, sp.xd, atol=1e-10)


def test_joint_space_law_6_37() -> None:
    q = np.array([0.3, -0.2, 0.4, 0.13])
    qd = np.array([0.1, -0.2, 0.3, 0.01])
    kp, kd = np.array([50.0, 50.0, 1.0, 1000.0]), np.array([1.0, 1.0, 0.1, 30.0])
    g = endobot.gravity_vector(q)
    tau, sp = joint_space_shared_control(LINE, q, qd, kp, kd, gravity=g)
    np.testing.assert_allclose(tau, -kp * (q - sp.q) - kd * (qd - sp.qd) + g)
    # On the line and moving along it, the law only compensates gravity.
    on = endobot.inverse_kinematics(0.12 * LINE.direction / np.linalg.norm(LINE.direction), 0.0)
    along = np.linalg.solve(endobot.jacobian(on), np.r_[LINE.direction / 10, 0.5])
    tau0, _ = joint_space_shared_control(LINE, on, along, kp, kd, gravity=g)
    np.testing.assert_allclose(tau0, g, atol=1e-9)


def test_constraint_force_inverts_6_52() -> None:
    rng = np.random.default_rng(6)
    for q in _configs(7):
        fc = rng.normal(size=2) * 5
        x = task_vector(q)
        tau = endobot.jacobian(q).T @ (LINE.jacobian(x).T @ fc)  # (6.52)
        np.testing.assert_allclose(constraint_force(LINE, q, tau), fc, atol=1e-9)


def test_effective_stiffness_on_hand_built_signals() -> None:
    t = np.linspace(0, 8, 8001)
    e = np.stack([0.0047 * np.sin(2.1 * t), 0.0041 * np.cos(1.3 * t)], axis=1)
    f = np.stack([1003.0 * e[:, 0], 1002.0 * e[:, 1]], axis=1)
    rep = effective_stiffness(e, f)
    np.testing.assert_allclose(rep.max_deviation, [0.0047, 0.0041], rtol=1e-6)
    np.testing.assert_allclose(rep.stiffness, [1003.0, 1002.0], rtol=1e-9)
    # A row that never deviates has no stiffness to report.
    rep0 = effective_stiffness(np.zeros((3, 1)), np.ones((3, 1)))
    assert np.isnan(rep0.stiffness[0])
    with pytest.raises(SharedControlError):
        effective_stiffness(np.zeros((3, 2)), np.zeros((4, 2)))


def test_short_pybullet_run_holds_the_line_at_the_desired_stiffness() -> None:
    pytest.importorskip("pybullet")
    from suture_engine.control.shared_experiment import run_experiment, thesis_line

    res = run_experiment(thesis_line(), controller="task", duration=2.0, stiffness=1000.0)
    assert res.saturated_ticks == 0
    # The operator pushed several millimetres off the line and slid along it.
    assert np.all(res.table.max_deviation > 0.002)
    assert res.free_travel > 0.02
    # Table 6.2: effective stiffness from (6.53)-(6.54) within 5 % of the desired.
    np.testing.assert_allclose(res.table.stiffness, 1000.0, rtol=0.05)
    # Physics side: the operator's normal force against the deviation, same stiffness
    # up to inertia and joint friction.
    np.testing.assert_allclose(res.operator_slope, 1000.0, rtol=0.15)


def test_operator_pushes_with_the_same_impedance_in_all_directions() -> None:
    from suture_engine.control.shared_experiment import OperatorModel, thesis_line

    op = OperatorModel(push=0.02, stiffness=300.0, damping=0.0)
    line = thesis_line()
    f0 = np.array([0.12, 0.0])
    dirs = []
    for t in np.linspace(0.6, 0.6 + op.push_period, 40, endpoint=False):
        h = op.hand(line, f0, float(t))
        # The hand circles the line at `push` from it, at the sliding free coordinate.
        assert np.linalg.norm(line.value(h)) == pytest.approx(0.02, rel=1e-9)
        on = line.project(h)
        force, _ = op.wrench(line, f0, float(t), on, np.zeros(3))
        # On the line, the force is K_h times the hand's offset: normal to the line.
        np.testing.assert_allclose(force, 300.0 * (h[:3] - on[:3]), atol=1e-12)
        assert abs(force @ line.direction) < 1e-9 * np.linalg.norm(line.direction)
        dirs.append(line.value(h) / 0.02)
    # Over one push period the direction turns all the way round the line.
    angles = np.unwrap(np.arctan2([d[1] for d in dirs], [d[0] for d in dirs]))
    assert np.ptp(angles) > 2 * np.pi * 0.9
