"""move-constrained's start/step on the runtime's types (no physics: perfect tracking)."""

from __future__ import annotations

import numpy as np
import pytest

from skills.move_constrained import MoveConstrained
from suture_engine.control.fixtures import Circle, Line
from suture_engine.control.shared import task_vector
from suture_engine.robot import endobot
from suture_engine.runtime.context import SkillContext
from suture_engine.runtime.observation import (
    CommandMode,
    Observation,
    RobotObservation,
    SceneGeometry,
    SkillStatus,
    ToolState,
)

ROBOT = "endobot_1"


def _obs(
    t: float, q: np.ndarray, qd: np.ndarray | None = None, exit_point=(0, 0, 0)
) -> Observation:  # type: ignore[no-untyped-def]
    ro = RobotObservation(
        q=np.asarray(q, dtype=float),
        qd=np.zeros(4) if qd is None else np.asarray(qd, dtype=float),
        base_wrench=np.zeros(6),
        tool=ToolState(),
    )
    return Observation(
        tick=round(t * 1e3), t=t, robots={ROBOT: ro}, scene=SceneGeometry(exit_point=exit_point)
    )


def _ctx(obs: Observation, params: dict | None = None) -> SkillContext:
    return SkillContext(step="s", roles={"arm": ROBOT}, dt=1e-3, start=obs, params=params or {})


def _run(skill: MoveConstrained, q0: np.ndarray, ctx_params: dict | None = None, **obs_kw):  # type: ignore[no-untyped-def]
    """Perfect joint tracking: the next measured q is the commanded set point."""
    obs = _obs(0.0, q0, **obs_kw)
    ctx = _ctx(obs, ctx_params)
    skill.start(ctx)
    q = q0.copy()
    xs = []
    for k in range(20000):
        res = skill.step(ctx, _obs(k * 1e-3, q, **obs_kw))
        cmd = res.command.robots[ROBOT]
        assert cmd.mode is CommandMode.POSITION
        q = np.array(cmd.q)
        xs.append(task_vector(q))
        if res.status is not SkillStatus.RUNNING:
            return res, np.array(xs)
    raise AssertionError("no outcome")


def test_autonomous_line_reaches_the_target_on_the_line() -> None:
    direction = np.array([1.0, 1.0, 2.0])
    unit = direction / np.linalg.norm(direction)
    q0 = endobot.inverse_kinematics(0.08 * unit, 0.0)
    skill = MoveConstrained(
        {
            "robot": "arm",
            "fixture": "line",
            "direction": tuple(direction),
            "target": tuple(0.14 * unit + np.array([0.004, -0.003, 0.0])),  # off the line
            "speed": 0.02,
        }
    )
    res, xs = _run(skill, q0)
    assert res.status is SkillStatus.SUCCESS, res.message
    line = Line(direction=direction)
    assert np.abs([line.value(x) for x in xs]).max() < 1e-6
    # The target projected on the line (6.35), reached to the skill's tolerance.
    goal = line.project(np.r_[0.14 * unit + np.array([0.004, -0.003, 0.0]), 0.0])
    assert np.linalg.norm(xs[-1][:3] - goal[:3]) <= MoveConstrained.TOLERANCE
    assert skill.last_qp is not None and skill.last_qp.solved


def test_autonomous_circle_goes_the_short_way_and_respects_the_extension_rate() -> None:
    circle = Circle(center=np.array([0.0, 0.0, 0.12]), radius=0.03)
    start = circle.inverse(np.zeros(2), np.array([0.0, 0.0]))
    q0 = endobot.inverse_kinematics(start[:3], 0.0)
    target = circle.inverse(np.zeros(2), np.array([-2.0, 0.0]))[:3]
    exit_point = np.array([0.03, 0.0, 0.14])  # the suture leaves the tissue here
    skill = MoveConstrained(
        {
            "robot": "arm",
            "fixture": "circle",
            "point": (0.0, 0.0, 0.12),
            "radius": 0.03,
            "target": tuple(target),
            "speed": 0.03,
            "max_tension": 2.0,
        }
    )
    # (4.11): ldot_max = (2.0 - 0.5) / 300 = 5 mm/s.
    params = {"suture_static_friction": 0.5, "suture_viscous_coefficient": 300.0}
    res, xs = _run(skill, q0, ctx_params=params, exit_point=tuple(exit_point))
    assert res.status is SkillStatus.SUCCESS, res.message
    assert np.abs([circle.value(x) for x in xs]).max() < 1e-5
    theta = np.unwrap([circle.free(x)[0] for x in xs])
    assert theta.min() >= -2.0 - 1e-3 and theta.max() <= 1e-3  # the short way: clockwise
    dist = np.linalg.norm(xs[:, :3] - exit_point, axis=1)
    assert np.max(np.diff(dist)) / 1e-3 <= 0.005 + 1e-4
    assert np.max(np.diff(dist)) / 1e-3 > 0.004  # the bound was reached: it was binding


def test_shared_mode_returns_the_6_24_torques_and_reports_stiffness() -> None:
    direction = np.array([1.0, -1.0, 2.0])
    line = Line(direction=direction)
    skill = MoveConstrained(
        {
            "robot": "arm",
            "fixture": "line",
            "direction": tuple(direction),
            "mode": "shared",
            "duration": 1.0,
        }
    )
    on = 0.1 * direction / np.linalg.norm(direction)
    q = endobot.inverse_kinematics(on + np.array([0.003, 0.0, 0.0]), 0.2)
    obs = _obs(0.0, q)
    skill.start(_ctx(obs))
    # While the fixture captures the tool (CAPTURE_S), nothing enters the metrics.
    far = endobot.inverse_kinematics(on + np.array([0.02, 0.0, 0.0]), 0.2)
    skill.step(_ctx(obs), _obs(0.1, far))
    assert np.isnan(skill.metrics()["constraint_stiffness_N_per_m"])
    res = skill.step(_ctx(obs), _obs(MoveConstrained.CAPTURE_S, q))
    cmd = res.command.robots[ROBOT]
    assert cmd.mode is CommandMode.TORQUE
    x = task_vector(q)
    fc = -MoveConstrained.STIFFNESS * line.value(x)
    expected = endobot.jacobian(q).T @ (line.jacobian(x).T @ fc) + endobot.gravity_vector(q)
    np.testing.assert_allclose(cmd.tau, expected, atol=1e-10)
    m = skill.metrics()
    assert m["desired_stiffness_N_per_m"] == MoveConstrained.STIFFNESS
    assert m["constraint_stiffness_N_per_m"] == pytest.approx(MoveConstrained.STIFFNESS)
    assert m["max_deviation_m"] == pytest.approx(np.abs(line.value(x)).max())
    assert skill.step(_ctx(obs), _obs(1.0, q)).status is SkillStatus.SUCCESS


def test_shared_mode_reports_no_stiffness_without_a_push() -> None:
    direction = np.array([1.0, -1.0, 2.0])
    skill = MoveConstrained(
        {"robot": "arm", "fixture": "line", "direction": tuple(direction), "mode": "shared"}
    )
    on = 0.1 * direction / np.linalg.norm(direction)
    q = endobot.inverse_kinematics(on + np.array([1e-8, 0.0, 0.0]), 0.0)  # noise-level offset
    obs = _obs(0.0, q)
    skill.start(_ctx(obs))
    skill.step(_ctx(obs), _obs(1.0, q))
    assert np.isnan(skill.metrics()["constraint_stiffness_N_per_m"])


class _JointSpaceMoveConstrained(MoveConstrained):
    SHARED_SPACE = "joint"


def test_joint_space_shared_mode_restores_and_leaves_free_motion_alone() -> None:
    direction = np.array([1.0, -1.0, 2.0])
    line = Line(direction=direction)
    unit = direction / np.linalg.norm(direction)
    skill = _JointSpaceMoveConstrained(
        {"robot": "arm", "fixture": "line", "direction": tuple(direction), "mode": "shared"}
    )
    on = endobot.inverse_kinematics(0.1 * unit, 0.3)
    obs = _obs(0.0, on)
    skill.start(_ctx(obs))
    # On the line and moving along it (and rolling): only gravity compensation (6.37).
    along = np.linalg.solve(endobot.jacobian(on), np.r_[0.02 * unit, 0.5])
    tau = skill.step(_ctx(obs), _obs(0.6, on, qd=along)).command.robots[ROBOT].tau
    np.testing.assert_allclose(tau, endobot.gravity_vector(on), atol=1e-9)
    # Off the line at rest: the task-space force pushes back towards it.
    off = endobot.inverse_kinematics(0.1 * unit + np.array([0.002, 0.001, 0.0]), 0.3)
    tau = skill.step(_ctx(obs), _obs(0.7, off)).command.robots[ROBOT].tau
    force = np.linalg.solve(endobot.jacobian(off).T, tau - endobot.gravity_vector(off))
    e = line.value(task_vector(off))
    assert (line.jacobian(task_vector(off)).T @ e) @ force < 0
    m = skill.metrics()
    assert m["max_deviation_m"] == pytest.approx(np.abs(e).max())
    assert "desired_stiffness_N_per_m" not in m
    assert m["constraint_stiffness_N_per_m"] > 1000.0  # stiff joint PD (Table 6.3: 6268)


def _smoothstep(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


@pytest.mark.parametrize("skip", [False, True], ids=["every-tick", "skipped-ticks"])
def test_reference_is_the_smoothstep_along_the_line_and_reuses_only_equal_times(
    skip: bool,
) -> None:
    """The reference (kept between ticks) against a hand-built smoothstep between the
    start's projection on the line and the goal, and bit for bit against a fresh
    evaluation at every tick (reuse only when the times are equal)."""
    direction = np.array([1.0, 1.0, 2.0])
    unit = direction / np.linalg.norm(direction)
    q0 = endobot.inverse_kinematics(0.08 * unit + np.array([0.001, 0.0, 0.0]), 0.2)
    skill = MoveConstrained(
        {
            "robot": "arm",
            "fixture": "line",
            "direction": tuple(direction),
            "target": tuple(0.1 * unit),
            "speed": 0.05,
        }
    )
    skill.start(_ctx(_obs(0.0, q0)))
    x0 = task_vector(q0)
    start = np.r_[unit * (unit @ x0[:3]), x0[3]]  # x0 projected on the line, its roll
    goal = np.r_[0.1 * unit, x0[3]]
    duration = skill._duration
    ticks = [k for k in range(round(duration * 1e3) + 50) if not (skip and k % 3 == 1)]
    h = 1e-3
    for k in ticks:
        t = k * 1e-3
        x, v = skill._reference(t)
        expected = start + _smoothstep(t / duration) * (goal - start)
        after = start + _smoothstep((t + h) / duration) * (goal - start)
        np.testing.assert_allclose(x, expected, atol=1e-12)
        np.testing.assert_allclose(v, (after - expected) / h, atol=1e-8)
        fresh = skill._at(t)
        assert x.tobytes() == fresh.tobytes()
        assert v.tobytes() == ((skill._at(t + h) - fresh) / h).tobytes()
    assert skill._final_ref is not None  # past the duration: computed once, velocity 0
    assert not np.any(skill._final_ref[1])


def _reference_cases() -> list:
    from suture_engine.control.fixtures import Plane

    rng = np.random.default_rng(4)
    fixtures = [
        Line(point=[0.0, 0.0, 0.0], direction=[0.0, 0.0, 1.0]),
        Line(point=[0.01, -0.02, 0.03], direction=[1.0, 1.0, -2.0]),
        Line(point=[0.0, 0.01, 0.0], direction=[0.3, -0.7, 1.1], thesis_form=True),
        Plane(point=[0.0, 0.0, 0.12], normal=[0.0, 0.2, 1.0]),
    ]
    cases = []
    for fx in fixtures:
        for _ in range(25):
            x0 = np.r_[rng.normal(scale=0.05, size=3), rng.uniform(-1, 1)]
            goal = np.r_[rng.normal(scale=0.05, size=3), rng.uniform(-1, 1)]
            f0 = fx.free(x0)
            df = fx.free(fx.project(goal)) - f0
            cases.append((fx, f0, df, float(rng.uniform(0.1, 3.0))))
    return cases


def test_compiled_reference_matches_the_fixtures_inverse_to_1e12() -> None:
    """The line/plane reference kernel against d^-1 by the fixture's own numpy (the path
    of _at) and a numpy forward difference, before, along and after the smoothstep."""
    from suture_engine.control._move_kernels import JIT

    kernel = JIT[0]
    h = 1e-3
    for fx, f0, df, duration in _reference_cases():
        d, p0 = fx.affine_inverse()
        c0 = np.zeros(fx.rows)
        for t in (-0.01, 0.0, 0.3 * duration, duration - h / 2, duration, duration + 1.0):
            x, v = np.empty(4), np.empty(4)
            kernel(t, h, duration, f0, df, c0, d, p0, x, v)

            def at(tt: float, f0=f0, df=df, duration=duration, fx=fx, c0=c0) -> np.ndarray:
                s = min(max(tt / duration, 0.0), 1.0)
                return fx.inverse(c0, f0 + s * s * (3.0 - 2.0 * s) * df)

            ex, ex_next = at(t), at(t + h)
            np.testing.assert_allclose(x, ex, rtol=1e-12, atol=1e-15)
            # the difference of two references: 1e-12 of the positions over h
            np.testing.assert_allclose(v, (ex_next - ex) / h, rtol=1e-9, atol=1e-12 / h)
            if t >= duration:
                assert np.all(v == 0.0)


def test_compiled_reference_equals_its_python_source_bit_for_bit() -> None:
    from suture_engine.control._move_kernels import JIT

    kernel, _, compiled = JIT
    if not compiled:
        pytest.skip("numba is not installed: the Python source is what runs")
    for fx, f0, df, duration in _reference_cases():
        d, p0 = fx.affine_inverse()
        for t in (0.0, 0.37 * duration, duration):
            outs = []
            for fn in (kernel, kernel.py_func):
                x, v = np.empty(4), np.empty(4)
                fn(t, 1e-3, duration, f0, df, np.zeros(fx.rows), d, p0, x, v)
                outs.append(x.tobytes() + v.tobytes())
            assert outs[0] == outs[1]


def test_autonomous_reference_on_a_line_is_the_compiled_one_and_agrees_with_at() -> None:
    """A started line step takes the compiled reference (a circle keeps _at's numpy), and
    along the motion its reference and velocity agree with _at's to 1e-12."""
    direction = np.array([1.0, 1.0, 2.0])
    unit = direction / np.linalg.norm(direction)
    q0 = endobot.inverse_kinematics(0.08 * unit, 0.0)
    skill = MoveConstrained(
        {"robot": "arm", "fixture": "line", "direction": tuple(direction),
         "target": tuple(0.14 * unit), "speed": 0.02}
    )  # fmt: skip
    skill.start(_ctx(_obs(0.0, q0)))
    assert skill._ref_kernel is not None
    for t in np.linspace(0.0, skill._duration + 0.01, 57):
        x, v = skill._reference(float(t))
        ex, ex_next = skill._at(float(t)), skill._at(float(t) + 1e-3)
        np.testing.assert_allclose(x, ex, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(v, (ex_next - ex) / 1e-3, rtol=1e-9, atol=1e-9)
    circle = MoveConstrained(
        {"robot": "arm", "fixture": "circle", "point": (0.0, 0.0, 0.12), "radius": 0.03,
         "target": (0.0, 0.03, 0.12)}
    )  # fmt: skip
    start = Circle(center=np.array([0.0, 0.0, 0.12]), radius=0.03).inverse(np.zeros(2), np.zeros(2))
    circle.start(_ctx(_obs(0.0, endobot.inverse_kinematics(start[:3], 0.0))))
    assert circle._ref_kernel is None


def test_compiled_step_and_deviation_peak_match_numpy() -> None:
    """integrate_and_track: q_ref's Euler step is numpy's ``q_ref += qdot * dt`` to the
    bit; the deviation peak is np.maximum(peak, |fixture.value(x)|) to 1e-12 (NaN kept);
    compiled and Python source agree bit for bit."""
    from suture_engine.control._move_kernels import JIT
    from suture_engine.control.fixtures import Plane

    _, track, compiled = JIT
    rng = np.random.default_rng(8)
    for fx in (
        Line(point=[0.01, -0.02, 0.03], direction=[1.0, 1.0, -2.0]),
        Line(point=[0.0, 0.01, 0.0], direction=[0.3, -0.7, 1.1], thesis_form=True),
        Plane(point=[0.0, 0.0, 0.12], normal=[0.0, 0.2, 1.0]),
    ):
        jc, p0 = fx.affine()
        fns = [track, track.py_func] if compiled else [track]
        q0 = rng.normal(size=4)
        states = [(q0.copy(), np.zeros(fx.rows)) for _ in fns]  # (q_ref, peak) per function
        expected_q, expected_peak = q0.copy(), np.zeros(fx.rows)
        for k in range(300):
            qdot, x = rng.normal(scale=0.1, size=4), rng.normal(scale=0.05, size=4)
            on = k % 7 != 3
            expected_q += qdot * 1e-3
            if on:
                np.maximum(expected_peak, np.abs(fx.value(x)), out=expected_peak)
            cmds = []
            for fn, (q_ref, peak) in zip(fns, states, strict=True):
                q_cmd = np.empty(4)
                fn(q_ref, qdot, 1e-3, q_cmd, x, jc, p0, peak, on)
                assert q_ref.tobytes() == expected_q.tobytes() == q_cmd.tobytes()
                np.testing.assert_allclose(peak, expected_peak, rtol=1e-12, atol=1e-15)
                cmds.append(peak.tobytes())
            assert len(set(cmds)) == 1
        q_ref, peak = states[0]
        track(q_ref, np.zeros(4), 1e-3, np.empty(4), np.full(4, np.nan), jc, p0, peak, True)
        assert np.all(np.isnan(peak))  # as np.maximum: a NaN deviation stays
