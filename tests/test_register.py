"""``register`` (skills/register.py): the plan against the scene's posts, the static check,
and how the interpreter applies a registration to later steps."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any, ClassVar

import numpy as np
import pytest

from skills.register import Register, RegisterParams
from suture_engine.language.loader import load_procedure
from suture_engine.robot.kinematics import inverse_kinematics
from suture_engine.robot.registration import segment_closest, shaft_segment
from suture_engine.runtime.automaton import FailurePolicy, Outcome, Plan, StepSpec, Then
from suture_engine.runtime.interpreter import Interpreter
from suture_engine.runtime.testing import IdealBackend, ScriptedSkill
from suture_engine.runtime.trajectory import rpy_matrix, tool_tip_world, world_to_base

ROOT = Path(__file__).resolve().parent.parent
PROC = load_procedure(ROOT / "procedures" / "register-bases.yaml")
SCENE = PROC.scene
BASES = {n: (tuple(s.base.position), rpy_matrix(s.base.rpy)) for n, s in SCENE.robots.items()}


def _with(state: str) -> dict[str, Any]:
    return PROC.states[state].params.model_dump()


def _ctx(robot: str, q: Any) -> Any:
    obs = SimpleNamespace(
        t=0.0, robots={robot: SimpleNamespace(q=np.asarray(q, float), base_wrench=np.zeros(6))}
    )
    roles = {"stitcher": "endobot_1", "grasper": "endobot_2"}
    return SimpleNamespace(
        robot=lambda r: roles.get(r, r), base_poses=BASES, scene=SCENE, dt=1e-3, start=obs
    )


STARTS = {
    # the stitched start: the stitcher's tip 40 mm over the exit, the grasper at its home
    "stitcher": (
        "endobot_1",
        inverse_kinematics(world_to_base((0.0, 0.004, 0.04), BASES["endobot_1"]), 0.0),
    ),
    "grasper": ("endobot_2", np.array([0.0, 0.0, 0.0, 0.08])),
}


def _planned(state: str) -> tuple[str, Any, Register, RegisterParams]:
    """A bundled registration state's skill, planned from its start joints."""
    robot, q0 = STARTS[state]
    skill = Register(RegisterParams(**_with(state)))
    skill.start(_ctx(robot, q0))
    assert isinstance(skill.params, RegisterParams)
    return robot, q0, skill, skill.params


@pytest.mark.parametrize("state", sorted(STARTS))
def test_the_bundled_plan_keeps_the_shaft_off_every_post_between_touches(state: str) -> None:
    robot, q0, skill, p = _planned(state)
    radius = p.shaft_radius
    q = q0
    approaches = 0
    after_approach = False
    for kind, _k, goal, _speed in skill._moves:
        if kind == "approach":
            approaches += 1
        elif not after_approach:  # (a back-off starts at the contact, wherever it was)
            # an independent sampling of the joint path, finer than the planner's
            for s in np.linspace(0.0, 1.0, 101):
                qs = q + s * (np.asarray(goal) - q)
                tip = tool_tip_world(qs, BASES[robot])
                a, b = shaft_segment(BASES[robot][0], tip, 6e-3, 0.3)
                for post in SCENE.posts.values():
                    foot = np.asarray(post.position, float)
                    top = foot + np.array([0.0, 0.0, post.height])
                    d = segment_closest(a, b, foot, top).distance
                    assert d - post.radius - radius > 1e-3
        after_approach = kind == "approach"
        q = np.asarray(goal, float)
    assert approaches == len(p.touches)
    np.testing.assert_allclose(q, q0)  # it ends where it started


@pytest.mark.parametrize("state", sorted(STARTS))
def test_each_approach_ends_past_the_models_contact_along_the_normal(state: str) -> None:
    robot, _q0, skill, p = _planned(state)
    starts: dict[int, Any] = {}
    for kind, k, goal, _speed in skill._moves:
        a, b = shaft_segment(BASES[robot][0], tool_tip_world(goal, BASES[robot]), 6e-3, 0.3)
        post = SCENE.posts[p.touches[k].post] if k >= 0 else None
        if post is None:
            continue
        foot = np.asarray(post.position, float)
        d = segment_closest(a, b, foot, foot + np.array([0.0, 0.0, post.height])).distance
        contact = post.radius + p.shaft_radius
        if kind == "approach":
            assert d == pytest.approx(contact - p.overtravel, abs=2e-4)
            assert k in starts
        # the start's normal is square to the post, not quite to the shaft: within 0.5 mm
        elif k not in starts and kind == "move" and abs(d - contact - p.clearance) < 5e-4:
            starts[k] = goal
    assert sorted(starts) == list(range(len(p.touches)))


def test_a_touch_of_a_post_the_scene_lacks_is_a_located_problem() -> None:
    params = RegisterParams(robot="grasper", touches=[{"post": "nowhere"}])
    problems = Register.check(params, SCENE)
    assert [pr.code for pr in problems] == ["unknown-post"]
    assert problems[0].path == "touches[0].post"
    assert "grasper_near" in problems[0].message


def test_a_state_turned_off_is_not_checked_against_the_scene(tmp_path: Path) -> None:
    from suture_engine.validation.checks import validate_file

    procs = tmp_path / "procedures"
    (procs / "scenes").mkdir(parents=True)
    for name in ("knot-algorithm-2.yaml", "register-bases.yaml", "stitch.yaml"):
        text = (ROOT / "procedures" / name).read_text()
        # registration on a scene without posts: the caller's, inherited
        text = text.replace("'bench-posts' if register else 'bench'", "'bench'")
        text = text.replace("scene: scenes/bench-posts.yaml\n", "")
        (procs / name).write_text(text)
    bench = (ROOT / "procedures" / "scenes" / "bench.yaml").read_text()
    (procs / "scenes" / "bench.yaml").write_text(bench)
    path = procs / "knot-algorithm-2.yaml"
    assert validate_file(path) == []  # `when:` turns the registration off
    codes = [p.code for p in validate_file(path, params={"register": True})]
    assert codes and set(codes) == {"unknown-post"}


def test_the_square_knot_registers_first_on_the_square_bench_with_posts() -> None:
    from suture_engine.language.loader import load_procedure
    from suture_engine.runtime.plan import compile_procedure
    from suture_engine.validation.checks import validate_file

    path = ROOT / "procedures" / "square-knot.yaml"
    off = load_procedure(path)
    assert off.scene.posts == {} and off.scene.suture.length == pytest.approx(0.14)
    on = load_procedure(path, params={"register": True})
    assert sorted(on.scene.posts) == sorted(SCENE.posts)
    assert on.scene.suture == off.scene.suture and on.scene.robots == off.scene.robots
    plan = compile_procedure(on)
    assert plan.initial == "register.stitcher"
    assert plan.steps["register.stitcher"].on_done == "register.grasper"
    # then the jig stays (remove_posts off by default: a step turned off), and the knot
    assert plan.steps["register.grasper"].on_done == "register.remove-posts"
    assert not plan.steps["register.remove-posts"].enabled
    # then the reload's steps, off without reload, and the knot
    step = plan.steps["register.remove-posts"].on_done
    for name in ("reload-cut", "reload-over", "reload-load"):
        assert step == name and not plan.steps[step].enabled
        step = plan.steps[step].on_done
    assert step.startswith("simple-knot.")
    assert validate_file(path, params={"register": True}) == []
    # algorithm 3 registers on the bent-tip bench with its posts
    alg3 = load_procedure(path, params={"register": True, "algorithm": 3})
    bare = load_procedure(path, params={"algorithm": 3, "register": False})
    assert bare.scene.posts == {} and sorted(alg3.scene.posts) == sorted(SCENE.posts)
    # and by default since 2026-12-07
    assert load_procedure(path, params={"algorithm": 3}).scene.posts == alg3.scene.posts
    assert alg3.scene.suture == bare.scene.suture and alg3.scene.robots == bare.scene.robots
    assert validate_file(path, params={"register": True, "algorithm": 3}) == []


class _Registers(ScriptedSkill):
    """Succeeds at once with a fixed correction of endobot_1's base."""

    base_corrections: ClassVar[dict[str, Any]] = {"endobot_1": (1e-3, -2e-3, 0.5e-3)}


class _Sees(ScriptedSkill):
    seen: ClassVar[list[Any]] = []

    def start(self, ctx: Any) -> None:
        super().start(ctx)
        _Sees.seen.append(dict(ctx.base_poses))


@pytest.mark.parametrize(
    "calibration",
    [None, (-1e-3, 2e-3, -0.5e-3)],
    ids=["declared", "miscalibrated by minus the correction"],
)
def test_a_registration_moves_the_bases_every_later_step_sees(
    calibration: tuple[float, float, float] | None,
) -> None:
    """Each step sees the declared base plus a calibration error (the belief before any
    registration), then plus the registration's correction; a correction equal to minus
    the error leaves exactly the declared base."""
    _Sees.seen = []
    policy = FailurePolicy(0, Then.FAIL)
    plan = Plan(
        "p",
        "before",
        {
            "before": StepSpec("before", lambda: _Sees("before"), "register", policy),
            "register": StepSpec("register", lambda: _Registers("register"), "after", policy),
            "after": StepSpec("after", lambda: _Sees("after"), "end", policy),
        },
        {"end": Outcome.SUCCEEDED},
    )
    be = IdealBackend()
    errors = None if calibration is None else {"endobot_1": calibration}
    it = Interpreter(plan, be, be.reset(), scene=SCENE, calibration_error=errors)
    assert it.run("p", "ideal").outcome == "succeeded"
    before, after = _Sees.seen
    declared = BASES["endobot_1"][0]
    believed = np.subtract(before["endobot_1"][0], declared)
    np.testing.assert_allclose(believed, calibration or (0.0, 0.0, 0.0), atol=1e-15)
    moved = np.subtract(after["endobot_1"][0], before["endobot_1"][0])
    np.testing.assert_allclose(moved, (1e-3, -2e-3, 0.5e-3), atol=1e-15)
    if calibration is not None:  # the correction took the error out
        np.testing.assert_allclose(after["endobot_1"][0], declared, atol=1e-15)
    assert after["endobot_2"] == before["endobot_2"]
    assert after["endobot_2"][0] == BASES["endobot_2"][0]
    assert after["endobot_1"][1] == before["endobot_1"][1]  # the rotation is kept


@pytest.mark.slow
def test_registration_in_physics_recovers_an_injected_base_error(tmp_path: Path) -> None:
    # ground truth (the injected error) is used to grade the estimate only
    from suture_engine.runtime.run import run_procedure

    errors = {"endobot_1": (1.0e-3, -1.2e-3, 0.8e-3), "endobot_2": (-0.5e-3, 0.6e-3, -0.9e-3)}
    result = run_procedure(
        ROOT / "procedures" / "register-bases.yaml",
        backend="pybullet-surgical-stitched",
        seed=1,
        out=tmp_path / "run",
        backend_options={"base_error": errors},
    )
    assert result.summary.outcome == "succeeded"
    metrics = result.summary.metrics
    for robot, error in errors.items():
        got = [metrics[f"registration_{robot}_{axis}_mm"] * 1e-3 for axis in "xyz"]
        np.testing.assert_allclose(got, error, atol=1.5e-4)
        assert metrics[f"registration_{robot}_least_seen"] > 0.3
