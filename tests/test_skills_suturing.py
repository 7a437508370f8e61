"""The suturing skills on synthetic observations: commands, finish and failure conditions.

Each skill runs against an ideal tracker: the next observation's joints are the
joints just commanded, and the tools report what they were commanded (or stay
stuck, to exercise the failure paths). Geometry is checked against independent
computations: scipy rotations, point-to-line distances, numerical arc lengths
and the strand-length bookkeeping of 4.32-4.35.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skills.grasp import Grasp
from skills.hook import Hook
from skills.pass_jaws import PassJaws
from skills.pass_needle import PassNeedle, bite_arc
from skills.place_knot import PlaceKnot
from skills.release import Release
from skills.rotate_about import RotateAbout
from skills.wait_for_operator import WaitForOperator
from skills.wrap import Wrap
from suture_engine.language.loader import load_procedure
from suture_engine.robot.kinematics import forward_kinematics, inverse_kinematics, rotation
from suture_engine.runtime.context import SkillContext
from suture_engine.runtime.observation import (
    CommandMode,
    Observation,
    RobotObservation,
    SceneGeometry,
    SkillStatus,
    StepResult,
    ToolState,
)

ROOT = Path(__file__).resolve().parent.parent
DT = 1e-3
ROLES = {"stitcher": "endobot_1", "grasper": "endobot_2"}


@pytest.fixture(scope="module")
def scene() -> Any:
    return load_procedure(ROOT / "procedures" / "knot-algorithm-1.yaml").scene


def base_pose(scene: Any, robot: str) -> tuple[Any, Any]:
    """Base position and rotation, from scipy (extrinsic x-y-z = Rz Ry Rx)."""
    spec = scene.robots[robot].base
    rot = Rotation.from_euler("xyz", spec.rpy).as_matrix()
    return tuple(spec.position), tuple(rot.reshape(-1))


def tip(scene: Any, robot: str, q: Any) -> np.ndarray:
    pos, rot = base_pose(scene, robot)
    return np.array(pos) + np.array(rot).reshape(3, 3) @ forward_kinematics(q).position


def tool_frame(scene: Any, robot: str, q: Any) -> np.ndarray:
    _, rot = base_pose(scene, robot)
    return np.array(rot).reshape(3, 3) @ rotation(q)


def q_at(scene: Any, robot: str, point: Any, roll: float = 0.0) -> np.ndarray:
    pos, rot = base_pose(scene, robot)
    local = np.array(rot).reshape(3, 3).T @ (np.asarray(point, float) - np.array(pos))
    return inverse_kinematics(local, roll)


def observation(t: float, qs: dict[str, Any], tools: dict[str, ToolState]) -> Observation:
    robots = {
        n: RobotObservation(np.array(q, float), np.zeros(4), np.zeros(6), tools[n])
        for n, q in qs.items()
    }
    return Observation(round(t / DT), t, robots, SceneGeometry())


def apply_tool(state: ToolState, cmd: Any) -> ToolState:
    if cmd is None:
        return state
    return ToolState(
        state.kind,
        state.jaw_closed if cmd.jaw_closed is None else cmd.jaw_closed,
        state.jaw2_closed if cmd.jaw2_closed is None else cmd.jaw2_closed,
        state.hook_extension if cmd.hook_extension is None else cmd.hook_extension,
    )


class Run:
    """An ideal-tracking run of one skill; keeps every observation and result."""

    def __init__(
        self,
        skill: Any,
        scene: Any,
        qs: dict[str, Any],
        tools: dict[str, ToolState],
        *,
        stuck_tools: bool = False,
        max_t: float = 30.0,
    ) -> None:
        self.obs: list[Observation] = []
        self.results: list[StepResult] = []
        poses = {n: base_pose(scene, n) for n in scene.robots}
        obs = observation(0.0, qs, tools)
        ctx = SkillContext("step", ROLES, DT, obs, scene, {}, poses)
        skill.start(ctx)
        t = 0.0
        while t <= max_t:
            result = skill.step(ctx, obs)
            self.obs.append(obs)
            self.results.append(result)
            if result.status is not SkillStatus.RUNNING:
                break
            for name, rc in result.command.robots.items():
                assert rc.mode is CommandMode.POSITION
                qs[name] = np.array(rc.q)
                if not stuck_tools:
                    tools[name] = apply_tool(tools[name], rc.tool)
            t += DT
            obs = observation(t, qs, tools)
        self.skill = skill

    @property
    def status(self) -> SkillStatus:
        return self.results[-1].status

    @property
    def message(self) -> str:
        return self.results[-1].message

    def q(self, robot: str) -> np.ndarray:
        return np.array([o.robots[robot].q for o in self.obs])

    def commanded(self, robot: str) -> np.ndarray:
        return np.array(
            [r.command.robots[robot].q for r in self.results if robot in r.command.robots]
        )


def in_limits(scene: Any, robot: str, qs: np.ndarray) -> bool:
    jl = scene.robots[robot].joint_limits
    lo = np.array([jl.yaw[0], jl.pitch[0], jl.roll[0], jl.insertion[0]])
    hi = np.array([jl.yaw[1], jl.pitch[1], jl.roll[1], jl.insertion[1]])
    return bool(np.all(qs >= lo - 1e-9) and np.all(qs <= hi + 1e-9))


def start_pose(scene: Any) -> tuple[dict[str, Any], dict[str, ToolState]]:
    """Stitcher 10 mm above entry_2, grasper 8 mm to the -y side of it."""
    entry = np.array(scene.tissue.points["entry_2"])
    qs = {
        "endobot_1": q_at(scene, "endobot_1", entry + np.array((0, 0, 0.01))),
        "endobot_2": q_at(scene, "endobot_2", entry + np.array((0.0, -0.008, 0.002))),
    }
    tools = {
        "endobot_1": ToolState("stitcher", jaw_closed=True),
        "endobot_2": ToolState("hook-grasper"),
    }
    return qs, tools


# ----------------------------------------------------------------- rotate-about
def test_rotate_about_keeps_the_tip_on_a_circle_about_op(scene: Any) -> None:
    qs, tools = start_pose(scene)
    # start at a negative roll: from roll 0 the half turn about OP ends just past +pi
    qs["endobot_1"][2] = -0.5
    p_off = np.array((0.0, 0.0, 0.025))
    q_grasper = qs["endobot_2"]
    q_start = np.array(qs["endobot_1"])
    skill = RotateAbout(
        {
            "robot": "stitcher",
            "angle": math.pi,
            "relative_to": "grasper",
            "point": tuple(p_off),
            "speed": 2.0,
        }
    )
    run = Run(skill, scene, qs, tools)
    assert run.status is SkillStatus.SUCCESS, run.message
    o = np.array(scene.robots["endobot_1"].base.position)
    p = tip(scene, "endobot_2", q_grasper) + p_off
    axis = (p - o) / np.linalg.norm(p - o)
    tips = np.array([tip(scene, "endobot_1", q) for q in run.q("endobot_1")])
    rel = tips - o
    radial = np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)
    assert np.ptp(radial) < 1e-6  # constant distance to OP
    assert np.ptp(rel @ axis) < 1e-6  # motion orthogonal to OP
    # the final pose is the start turned by pi about OP: scipy's rotation, tip and frame
    turn = Rotation.from_rotvec(math.pi * axis).as_matrix()
    q_end = run.q("endobot_1")[-1]
    assert np.allclose(tip(scene, "endobot_1", q_end), o + turn @ (tips[0] - o), atol=1e-6)
    expected = turn @ tool_frame(scene, "endobot_1", q_start)
    assert np.allclose(tool_frame(scene, "endobot_1", q_end), expected, atol=1e-6)
    assert in_limits(scene, "endobot_1", run.commanded("endobot_1"))
    # the commanded joints are continuous (no roll wrap jumps)
    assert np.max(np.abs(np.diff(run.commanded("endobot_1"), axis=0))) < 0.01


def test_rotate_about_its_own_tip_is_a_pure_roll(scene: Any) -> None:
    qs, tools = start_pose(scene)
    q0 = np.array(qs["endobot_2"])
    skill = RotateAbout(
        {
            "robot": "grasper",
            "angle": math.pi / 2,
            "relative_to": "grasper",
            "point": (0, 0, 0),
            "speed": 2.0,
        }
    )
    run = Run(skill, scene, qs, tools)
    assert run.status is SkillStatus.SUCCESS, run.message
    q_end = run.q("endobot_2")[-1]
    assert np.allclose(q_end[[0, 1, 3]], q0[[0, 1, 3]], atol=1e-9)
    assert q_end[2] - q0[2] == pytest.approx(math.pi / 2, abs=1e-6)


def test_rotate_about_fails_outside_the_roll_limit(scene: Any) -> None:
    qs, tools = start_pose(scene)
    skill = RotateAbout(
        {"robot": "grasper", "angle": 2 * math.pi, "relative_to": "grasper", "point": (0, 0, 0)}
    )
    run = Run(skill, scene, qs, tools)
    assert run.status is SkillStatus.FAILURE and "roll" in run.message
    assert len(run.results) == 1


def test_rotate_about_fails_when_p_is_the_rcm(scene: Any) -> None:
    qs, tools = start_pose(scene)
    o = scene.robots["endobot_1"].base.position
    run = Run(RotateAbout({"robot": "stitcher", "angle": 1.0, "point": tuple(o)}), scene, qs, tools)
    assert run.status is SkillStatus.FAILURE and "RCM" in run.message


# ----------------------------------------------------------------- grasp / release
def test_grasp_moves_to_the_point_then_closes(scene: Any) -> None:
    qs, tools = start_pose(scene)
    skill = Grasp(
        {
            "robot": "grasper",
            "what": "suture-tail",
            "target": "entry_2",
            "offset": (0, -0.01, 0.004),
        }
    )
    run = Run(skill, scene, qs, tools)
    assert run.status is SkillStatus.SUCCESS, run.message
    goal = np.array(scene.tissue.points["entry_2"]) + np.array((0, -0.01, 0.004))
    assert np.linalg.norm(tip(scene, "endobot_2", run.q("endobot_2")[-1]) - goal) < 1e-3
    assert run.obs[-1].robots["endobot_2"].tool.jaw_closed
    # open all the way to the goal: the jaw is commanded closed only at the end
    closes = [r.command.robots["endobot_2"].tool.jaw_closed for r in run.results]
    assert closes[0] is False and closes[-1] is True
    assert in_limits(scene, "endobot_2", run.commanded("endobot_2"))
    # straight line: every tip lies on the segment from the start to the goal
    tips = np.array([tip(scene, "endobot_2", q) for q in run.q("endobot_2")])
    d = (goal - tips[0]) / np.linalg.norm(goal - tips[0])
    off = (tips - tips[0]) - np.outer((tips - tips[0]) @ d, d)
    assert np.max(np.linalg.norm(off, axis=1)) < 1e-6


def test_grasp_dwells_at_the_goal_once_the_jaw_reports_closed(scene: Any) -> None:
    """With ``dwell`` the skill keeps commanding the goal, jaw closed, for that long after
    the jaw first reports closed; without it, it ends on that tick."""
    params = {"robot": "grasper", "target": "entry_2", "offset": (0, -0.01, 0.004)}
    plain = Run(Grasp(params), scene, *start_pose(scene))
    held = Run(Grasp({**params, "dwell": 0.25}), scene, *start_pose(scene))
    assert plain.status is SkillStatus.SUCCESS and held.status is SkillStatus.SUCCESS

    def first_closed(run: Run) -> float:
        return next(o.t for o in run.obs if o.robots["endobot_2"].tool.jaw_closed)

    assert plain.obs[-1].t == pytest.approx(first_closed(plain))
    assert held.obs[-1].t - first_closed(held) == pytest.approx(0.25, abs=DT + 1e-9)
    assert first_closed(held) == pytest.approx(first_closed(plain))
    # through the dwell: the jaw commanded closed, the tip commanded where it closed
    after = [r for r, o in zip(held.results, held.obs, strict=True) if o.t >= first_closed(held)]
    assert all(r.command.robots["endobot_2"].tool.jaw_closed for r in after)
    qs = np.array([r.command.robots["endobot_2"].q for r in after])
    assert np.max(np.abs(qs - qs[0])) < 1e-12


def test_grasp_fails_when_the_jaw_never_closes(scene: Any) -> None:
    qs, tools = start_pose(scene)
    run = Run(Grasp({"robot": "grasper"}), scene, qs, tools, stuck_tools=True)
    assert run.status is SkillStatus.FAILURE and "closed" in run.message
    assert run.obs[-1].t == pytest.approx(Grasp.CLOSE_S + 0.1, abs=0.01)


def test_grasp_fails_on_an_unreachable_point(scene: Any) -> None:
    qs, tools = start_pose(scene)
    run = Run(Grasp({"robot": "grasper", "target": (0.5, 0.0, 0.0)}), scene, qs, tools)
    assert run.status is SkillStatus.FAILURE and "outside" in run.message


def test_release_opens_and_fails_if_stuck(scene: Any) -> None:
    qs, tools = start_pose(scene)
    tools["endobot_2"] = ToolState("hook-grasper", jaw_closed=True)
    q0 = np.array(qs["endobot_2"])
    run = Run(Release({"robot": "grasper"}), scene, dict(qs), dict(tools))
    assert run.status is SkillStatus.SUCCESS
    assert not run.obs[-1].robots["endobot_2"].tool.jaw_closed
    assert np.allclose(run.q("endobot_2"), q0)
    stuck = Run(Release({"robot": "grasper"}), scene, dict(qs), dict(tools), stuck_tools=True)
    assert stuck.status is SkillStatus.FAILURE


# ----------------------------------------------------------------- hook, pass-jaws
def test_hook_extends_and_retracts_at_its_rate(scene: Any) -> None:
    qs, tools = start_pose(scene)
    run = Run(Hook({"robot": "grasper", "action": "extend", "travel": 0.005}), scene, qs, tools)
    assert run.status is SkillStatus.SUCCESS
    ext = [o.robots["endobot_2"].tool.hook_extension for o in run.obs]
    assert ext[-1] == pytest.approx(0.005, abs=Hook.TOLERANCE)
    assert np.max(np.diff(ext)) <= Hook.RATE * DT + 1e-12
    back = Run(Hook({"robot": "grasper", "action": "retract"}), scene, qs, tools)
    assert back.status is SkillStatus.SUCCESS
    assert back.obs[-1].robots["endobot_2"].tool.hook_extension <= Hook.TOLERANCE


def test_hook_fails_without_a_hook_or_when_stuck(scene: Any) -> None:
    qs, tools = start_pose(scene)
    run = Run(Hook({"robot": "stitcher", "action": "extend"}), scene, qs, tools)
    assert run.status is SkillStatus.FAILURE and "no hook" in run.message
    qs, tools = start_pose(scene)
    stuck = Run(Hook({"robot": "grasper", "action": "extend"}), scene, qs, tools, stuck_tools=True)
    assert stuck.status is SkillStatus.FAILURE


def test_pass_jaws_hands_the_needle_over_without_dropping_it(scene: Any) -> None:
    qs, tools = start_pose(scene)
    run = Run(PassJaws({"robot": "stitcher"}), scene, qs, tools)
    assert run.status is SkillStatus.SUCCESS
    states = [o.robots["endobot_1"].tool for o in run.obs]
    assert all(s.jaw_closed or s.jaw2_closed for s in states)  # never both open
    assert states[-1].jaw2_closed and not states[-1].jaw_closed
    back = Run(PassJaws({"robot": "stitcher"}), scene, qs, tools)
    assert back.status is SkillStatus.SUCCESS
    assert back.obs[-1].robots["endobot_1"].tool.jaw_closed


@pytest.mark.parametrize("dwell", [0.0, 0.3, 1.0])
def test_pass_jaws_keeps_both_jaws_closed_for_the_dwell(scene: Any, dwell: float) -> None:
    """The giving jaw opens only once the receiving jaw has been closed ``dwell`` [s]."""
    qs, tools = start_pose(scene)
    run = Run(PassJaws({"robot": "stitcher", "dwell": dwell}), scene, qs, tools)
    assert run.status is SkillStatus.SUCCESS
    both = [o.t for o in run.obs if o.robots["endobot_1"].tool.jaw2_closed]
    opened = [o.t for o in run.obs if not o.robots["endobot_1"].tool.jaw_closed]
    assert both and opened
    held = opened[0] - both[0]
    assert dwell <= held <= dwell + 0.05


@pytest.mark.parametrize(
    "tool",
    [ToolState("stitcher", True, True), ToolState("stitcher"), ToolState("grasper", True)],
)
def test_pass_jaws_fails_on_an_unknown_holder(scene: Any, tool: ToolState) -> None:
    qs, tools = start_pose(scene)
    tools["endobot_1"] = tool
    run = Run(PassJaws({"robot": "stitcher"}), scene, qs, tools)
    assert run.status is SkillStatus.FAILURE and len(run.results) == 1


# ----------------------------------------------------------------- wrap
def segment_distance(p0: Any, p1: Any, q0: Any, q1: Any, n: int = 400) -> float:
    """Distance between two segments, by dense sampling of both."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    a = p0 + s * (p1 - p0)
    b = q0 + s * (q1 - q0)
    return float(np.min(np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)))


@pytest.mark.parametrize(("direction", "turns"), [("front-to-back", 1), ("back-to-front", 2)])
def test_wrap_goes_over_the_other_shaft(scene: Any, direction: str, turns: int) -> None:
    qs, tools = start_pose(scene)
    q_other = np.array(qs["endobot_2"])
    skill = Wrap(
        {
            "robot": "stitcher",
            "around": "grasper",
            "direction": direction,
            "turns": turns,
            "speed": 0.04,
        }
    )
    run = Run(skill, scene, qs, tools, max_t=60.0)
    assert run.status is SkillStatus.SUCCESS, run.message
    o1 = np.array(scene.robots["endobot_1"].base.position)
    o2 = np.array(scene.robots["endobot_2"].base.position)
    t2 = tip(scene, "endobot_2", q_other)
    axis = (o2 - t2) / np.linalg.norm(o2 - t2)
    tips = np.array([tip(scene, "endobot_1", q) for q in run.q("endobot_1")])
    rel = tips - t2
    radial = rel - np.outer(rel @ axis, axis)
    dist = np.linalg.norm(radial, axis=1)
    on_loop = np.abs(dist - 0.008) < 1e-6
    assert on_loop.sum() > 50
    # swept angle about the shaft, in the plane orthogonal to it: pi (2 turns - 1)
    e1 = radial[on_loop][0] / dist[on_loop][0]
    e2 = np.cross(axis, e1)
    ang = np.unwrap(np.arctan2(radial[on_loop] @ e2, radial[on_loop] @ e1))
    sign = 1.0 if direction == "front-to-back" else -1.0
    assert ang[-1] - ang[0] == pytest.approx(-sign * math.pi * (2 * turns - 1), abs=0.02)
    # the arc starts and ends beside the shaft, level with each other
    assert np.dot(radial[on_loop][0], radial[on_loop][-1]) == pytest.approx(-(0.008**2), abs=1e-8)
    # over the other tool: the arc's middle is on the side facing this robot's RCM
    over = (o1 - t2) - ((o1 - t2) @ axis) * axis
    if turns == 1:
        middle = radial[on_loop][len(ang) // 2]
        assert np.dot(middle, over) / (0.008 * np.linalg.norm(over)) > 0.99
        # and the shafts never meet: the tool segments stay apart all along
        gaps = [
            segment_distance(o1, tips[k], o2, t2)
            for k in range(0, len(tips), max(1, len(tips) // 60))
        ]
        assert min(gaps) > 3e-3
    assert in_limits(scene, "endobot_1", run.commanded("endobot_1"))


@pytest.mark.parametrize(("tolerance", "expected"), [(None, "failure"), (2e-3, "success")])
def test_wrap_tolerance_decides_a_steady_tracking_error(
    scene: Any, tolerance: float | None, expected: str
) -> None:
    """A robot that settles 1.5 mm short along its shaft (measured insertion short of
    the command) misses the default 1 mm tolerance and meets a 2 mm one."""
    qs, tools = start_pose(scene)
    params: dict[str, Any] = {"robot": "stitcher", "around": "grasper", "speed": 0.04}
    if tolerance is not None:
        params["tolerance"] = tolerance
    skill = Wrap(params)
    poses = {n: base_pose(scene, n) for n in scene.robots}
    obs = observation(0.0, qs, tools)
    ctx = SkillContext("step", ROLES, DT, obs, scene, {}, poses)
    skill.start(ctx)
    t = 0.0
    result = skill.step(ctx, obs)
    while result.status is SkillStatus.RUNNING and t < 60.0:
        q = np.array(result.command.robots["endobot_1"].q)
        q[3] -= 1.5e-3
        qs["endobot_1"] = q
        t += DT
        obs = observation(t, qs, tools)
        result = skill.step(ctx, obs)
    assert result.status.name.lower() == expected, result.message


@pytest.mark.parametrize("direction", ["front-to-back", "back-to-front"])
def test_wrap_turns_corners_only_at_rest(scene: Any, direction: str) -> None:
    """Where the tip's direction of motion turns sharply (the approach's waypoint and
    the start of the arc), its speed is near zero: no impulsive acceleration."""
    qs, tools = start_pose(scene)
    run = Run(
        Wrap({"robot": "stitcher", "around": "grasper", "direction": direction}),
        scene,
        qs,
        tools,
        max_t=60.0,
    )
    assert run.status is SkillStatus.SUCCESS, run.message
    tips = np.array([tip(scene, "endobot_1", q) for q in run.q("endobot_1")])
    v = np.diff(tips, axis=0) / DT
    speed = np.linalg.norm(v, axis=1)
    moving = speed > 1e-9

    for k in range(1, len(v)):
        if moving[k] and moving[k - 1]:
            cos = float(v[k] @ v[k - 1]) / (speed[k] * speed[k - 1])
            if cos < math.cos(math.radians(20.0)):
                assert max(speed[k], speed[k - 1]) < 1e-3
    # the motion pauses between the legs (rest-to-rest), at least twice
    stops = np.flatnonzero(np.diff(moving.astype(int)) == 1)
    assert len(stops) >= 2


def test_wrap_fails_around_itself(scene: Any) -> None:
    qs, tools = start_pose(scene)
    run = Run(Wrap({"robot": "stitcher", "around": "stitcher"}), scene, qs, tools)
    assert run.status is SkillStatus.FAILURE


# ----------------------------------------------------------------- pass-needle
def test_bite_arc_geometry_against_a_polyline() -> None:
    pa, pb, n = np.array((0, -0.004, 0)), np.array((0, 0.004, 0)), np.array((0, 0, 2.0))
    arc, length = bite_arc(pa, pb, n, 0.003)
    pts = np.array([arc(s) for s in np.linspace(0, 1, 20001)])
    assert np.allclose(pts[0], pa, atol=1e-12) and np.allclose(pts[-1], pb, atol=1e-12)
    assert pts[10000] == pytest.approx((0, 0, -0.003), abs=1e-12)
    assert np.all(pts[:, 2] <= 1e-12)  # under the surface all the way
    assert length == pytest.approx(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)), rel=1e-6)
    # a semicircle when the depth is half the chord: pi c / 2
    _, half = bite_arc(pa, pb, n, 0.004)
    assert half == pytest.approx(math.pi * 0.008 / 2, rel=1e-12)


def test_pass_needle_stitches_and_pulls_to_the_length(scene: Any) -> None:
    qs, tools = start_pose(scene)
    skill = PassNeedle(
        {
            "robot": "stitcher",
            "entry": "entry_2",
            "exit": "exit_2",
            "pull_length": 0.03,
            "max_tension": 0.5,
            "speed": 0.02,
        }
    )
    run = Run(skill, scene, qs, tools)
    assert run.status is SkillStatus.SUCCESS, run.message
    pb = np.array(scene.tissue.points["exit_2"])
    tips = np.array([tip(scene, "endobot_1", q) for q in run.q("endobot_1")])
    # deepest point of the bite is bite_depth under the surface
    assert tips[:, 2].min() == pytest.approx(-3e-3, abs=1e-5)
    # the needle changed jaws once, at the exit point
    last = run.obs[-1].robots["endobot_1"].tool
    assert last.jaw2_closed and not last.jaw_closed
    # the length the skill tracked matches the distance from the exit point (straight pull)
    metrics = skill.metrics()
    assert metrics["stitch_length_estimate_m"] == pytest.approx(
        np.linalg.norm(tips[-1] - pb), abs=1e-9
    )
    assert metrics["stitch_length_estimate_m"] >= 0.03 - PassNeedle.LENGTH_TOLERANCE
    # extension-rate bound (4.11): (0.5 - F_s) / F_v < speed, so it governs the pull
    bound = (0.5 - PassNeedle.STATIC_DRAG) / PassNeedle.VISCOUS_DRAG
    assert metrics["stitch_extension_rate_bound_m_s"] == pytest.approx(bound)
    dist = np.linalg.norm(tips - pb, axis=1)
    pulling = [i for i, o in enumerate(run.obs) if o.robots["endobot_1"].tool.jaw2_closed]
    rate = np.diff(dist[pulling]) / DT
    assert rate.max() <= bound * 1.001
    assert rate.max() >= 0.9 * bound  # and it is used, not just respected
    assert in_limits(scene, "endobot_1", run.commanded("endobot_1"))


def test_pass_needle_fails_when_the_bound_is_below_the_drag(scene: Any) -> None:
    qs, tools = start_pose(scene)
    skill = PassNeedle(
        {
            "robot": "stitcher",
            "entry": "entry_2",
            "exit": "exit_2",
            "pull_length": 0.03,
            "max_tension": 0.1,
        }
    )
    run = Run(skill, scene, qs, tools)
    assert run.status is SkillStatus.FAILURE and "static drag" in run.message


def test_pass_needle_fails_when_the_jaws_do_not_pass(scene: Any) -> None:
    qs, tools = start_pose(scene)
    skill = PassNeedle(
        {"robot": "stitcher", "entry": "entry_2", "exit": "exit_2", "pull_length": 0.03}
    )
    run = Run(skill, scene, qs, tools, stuck_tools=True)
    assert run.status is SkillStatus.FAILURE and "jaw" in run.message


# ----------------------------------------------------------------- place-knot
def test_place_knot_slides_the_knot_down_keeping_strand_lengths(scene: Any) -> None:
    site = np.array(scene.tissue.points["knot_2"])
    pa = np.array(scene.tissue.points["entry_2"])
    pb = np.array(scene.tissue.points["exit_2"])
    # the strands cross in the knot: the post strand (anchored at the entry point) leaves
    # towards the exit side, the loop strand towards the entry side (Fig. 4.12)
    qs = {
        "endobot_1": q_at(scene, "endobot_1", site + np.array((0.0, -0.02, 0.01))),
        "endobot_2": q_at(scene, "endobot_2", site + np.array((0.0, 0.02, 0.01))),
    }
    tools = {
        "endobot_1": ToolState("stitcher", jaw_closed=True),
        "endobot_2": ToolState("hook-grasper", jaw_closed=True),
    }
    skill = PlaceKnot({"post": "grasper", "loop": "stitcher", "site": "knot_2", "speed": 0.01})
    run = Run(skill, scene, qs, tools)
    assert run.status is SkillStatus.SUCCESS, run.message
    knot0 = site + np.array((0, 0, 0.01))
    knot1 = site + np.array((0, 0, PlaceKnot.SEAT_HEIGHT))
    for robot, anchor in (("endobot_2", pa), ("endobot_1", pb)):
        start = tip(scene, robot, run.q(robot)[0])
        end = tip(scene, robot, run.q(robot)[-1])
        # strand length, pulled leg + bridge leg, is kept (4.32-4.35)
        before = np.linalg.norm(start - knot0) + np.linalg.norm(knot0 - anchor)
        after = np.linalg.norm(end - knot1) + np.linalg.norm(knot1 - anchor)
        assert after == pytest.approx(before, abs=1e-5)
        # beta = beta_min = 0: pulled parallel to the tissue, at the knot's height
        assert end[2] == pytest.approx(knot1[2], abs=1e-6)
        # pulled straight away from the knot along the entry-exit line
        assert np.sign(end[1] - site[1]) == np.sign(start[1] - site[1])
        assert abs(end[1]) > abs(start[1]) and end[0] == pytest.approx(start[0], abs=1e-6)
        assert in_limits(scene, robot, run.commanded(robot))
    m = skill.metrics()
    assert m["knot_placement_error_m"] == pytest.approx(PlaceKnot.SEAT_HEIGHT, abs=1e-5)
    assert m["knot_placement_beta_rad"] == 0.0


def test_place_knot_second_throw_pulls_the_strands_the_other_way(scene: Any) -> None:
    """On a square knot's second throw (7.1-7.3) the loop strand (stitcher) is anchored at
    the entry point and pulled towards the exit's side, the post strand (grasper) the other
    way; each strand's length is kept with those anchors."""
    site = np.array(scene.tissue.points["knot_2"])
    pa = np.array(scene.tissue.points["entry_2"])
    pb = np.array(scene.tissue.points["exit_2"])
    qs = {
        "endobot_1": q_at(scene, "endobot_1", site + np.array((0.0, 0.02, 0.01))),
        "endobot_2": q_at(scene, "endobot_2", site + np.array((0.0, -0.02, 0.01))),
    }
    tools = {
        "endobot_1": ToolState("stitcher", jaw_closed=False, jaw2_closed=True),
        "endobot_2": ToolState("hook-grasper", jaw_closed=True),
    }
    params = {"post": "grasper", "loop": "stitcher", "site": "knot_2", "speed": 0.01}
    skill = PlaceKnot({**params, "throw": 2})
    run = Run(skill, scene, qs, tools)
    assert run.status is SkillStatus.SUCCESS, run.message
    knot0 = site + np.array((0, 0, 0.01))
    knot1 = site + np.array((0, 0, PlaceKnot.SEAT_HEIGHT))
    for robot, anchor, side in (("endobot_2", pb, pa), ("endobot_1", pa, pb)):
        start = tip(scene, robot, run.q(robot)[0])
        end = tip(scene, robot, run.q(robot)[-1])
        before = np.linalg.norm(start - knot0) + np.linalg.norm(knot0 - anchor)
        after = np.linalg.norm(end - knot1) + np.linalg.norm(knot1 - anchor)
        assert after == pytest.approx(before, abs=1e-5)
        # pulled away from the knot towards ``side``
        assert np.sign(end[1] - site[1]) == np.sign(side[1] - site[1])
        assert abs(end[1] - site[1]) > abs(start[1] - site[1])
    # as a first throw, the stitcher would be drawn back across the knot to the entry's side
    first = Run(PlaceKnot(params), scene, dict(qs), tools)
    assert tip(scene, "endobot_1", first.q("endobot_1")[-1])[1] < site[1]


def _sensor(scene: Any, robot: str, q: Any, force_world: Any) -> np.ndarray:
    """The base sensor's reading of a robot at rest at ``q`` with ``force_world`` [N] on its
    tool tip: gravity (the mounted model) less the tip force's wrench about the base."""
    import dataclasses

    from suture_engine.robot.endobot import E1
    from suture_engine.suture.tension import gravity_wrench

    _, rot = base_pose(scene, robot)
    r = np.array(rot).reshape(3, 3)
    g = r.T @ np.array([0.0, 0.0, -9.81])
    prm = dataclasses.replace(E1, gravity=(float(g[0]), float(g[1]), float(g[2])))
    f = r.T @ np.asarray(force_world, float)
    arm = forward_kinematics(q).position
    return gravity_wrench(q, prm) - np.concatenate([f, np.cross(arm, f)])


def test_place_knot_stops_where_the_knot_seats(scene: Any) -> None:
    """With ``seat_tension``, the slide stops, done, once a strand's tension estimated from
    the base sensor reaches it: here the loop strand goes taut (2 N, pulling the stitcher
    back towards the knot) halfway along the slide; the tools stop there. The stitcher
    holds its strand by the needle in jaw 2, as after a first throw: the skill leaves
    both tools' jaws as they are."""
    site = np.array(scene.tissue.points["knot_2"])
    qs = {
        "endobot_1": q_at(scene, "endobot_1", site + np.array((0.0, -0.02, 0.01))),
        "endobot_2": q_at(scene, "endobot_2", site + np.array((0.0, 0.02, 0.01))),
    }
    tools = {
        "endobot_1": ToolState("stitcher", jaw_closed=False, jaw2_closed=True),
        "endobot_2": ToolState("hook-grasper", True),
    }
    tool_commands = []
    params = {"post": "grasper", "loop": "stitcher", "site": "knot_2", "speed": 0.01}
    skill = PlaceKnot({**params, "seat_tension": 1.5})
    poses = {n: base_pose(scene, n) for n in scene.robots}
    knot = site + np.array((0.0, 0.0, 0.01))

    def obs_at(t: float) -> Observation:
        robots = {}
        for n, q in qs.items():
            tip_now = tip(scene, n, q)
            pull = tip_now - knot
            taut = n == "endobot_1" and abs(tip_now[1] - site[1]) > 0.0235
            force = -2.0 * pull / np.linalg.norm(pull) if taut else np.zeros(3)
            wrench = _sensor(scene, n, q, force)
            robots[n] = RobotObservation(np.array(q, float), np.zeros(4), wrench, tools[n])
        return Observation(round(t / DT), t, robots, SceneGeometry())

    obs = obs_at(0.0)
    ctx = SkillContext("step", ROLES, DT, obs, scene, {}, poses)
    skill.start(ctx)
    t, result = 0.0, skill.step(ctx, obs)
    while result.status is SkillStatus.RUNNING and t < 30.0:
        for n, rc in result.command.robots.items():
            qs[n] = np.array(rc.q)
            tool_commands.append(rc.tool)
        t += DT
        result = skill.step(ctx, obs_at(t))
    assert result.status is SkillStatus.SUCCESS, result.message
    assert len(tool_commands) > 1000 and all(c is None for c in tool_commands)
    m = skill.metrics()
    assert 1.5 <= m["knot_placement_seat_tension_N"] < 2.1
    assert 0.05 < m["knot_placement_slide_fraction"] < 0.95
    # stopped where the strand went taut, short of the trajectory's end
    stop = tip(scene, "endobot_1", qs["endobot_1"])
    assert abs(stop[1] - site[1]) == pytest.approx(0.0235, abs=1e-3)
    end = skill.trajectory.end2[-1]
    assert abs(end[1] - site[1]) > abs(stop[1] - site[1]) + 1e-3
    # the hold command is the position reached, at rest
    assert all(rc.qd is None for rc in result.command.robots.values())


def test_place_knot_fails_when_the_pulling_angle_sticks(scene: Any) -> None:
    site = np.array(scene.tissue.points["knot_2"])
    qs = {
        "endobot_1": q_at(scene, "endobot_1", site + np.array((0.0, 0.02, 0.01))),
        "endobot_2": q_at(scene, "endobot_2", site + np.array((0.0, -0.02, 0.01))),
    }
    tools = {"endobot_1": ToolState("stitcher", True), "endobot_2": ToolState("hook-grasper", True)}
    skill = PlaceKnot(
        {"post": "grasper", "loop": "stitcher", "site": "knot_2", "beta": 1.2, "friction": 0.5}
    )
    run = Run(skill, scene, qs, tools)
    assert run.status is SkillStatus.FAILURE and "PlacementInfeasible" in run.message


def test_place_knot_fails_when_the_knot_is_already_down(scene: Any) -> None:
    site = np.array(scene.tissue.points["knot_2"])
    qs = {
        "endobot_1": q_at(scene, "endobot_1", site + np.array((0.0, 0.02, 0.0))),
        "endobot_2": q_at(scene, "endobot_2", site + np.array((0.0, -0.02, 0.0))),
    }
    tools = {"endobot_1": ToolState("stitcher", True), "endobot_2": ToolState("hook-grasper", True)}
    run = Run(
        PlaceKnot({"post": "grasper", "loop": "stitcher", "site": "knot_2"}), scene, qs, tools
    )
    assert run.status is SkillStatus.FAILURE and "not above the seat" in run.message


# ----------------------------------------------------------------- wait-for-operator
def test_wait_for_operator_holds_everyone_and_keeps_running(scene: Any) -> None:
    qs, tools = start_pose(scene)
    q0 = {k: np.array(v) for k, v in qs.items()}
    run = Run(WaitForOperator({}), scene, qs, tools, max_t=0.5)
    assert all(r.status is SkillStatus.RUNNING for r in run.results)
    for name in q0:
        assert np.allclose(run.commanded(name), q0[name])


# ----------------------------------------------------------------- on PyBullet
def _trace_run(tmp_path: Path) -> tuple[dict[str, Any], Any]:
    import json
    import subprocess
    import sys

    out = tmp_path / "run"
    res = subprocess.run(
        [
            sys.executable,
            "-c",
            "from suture_engine.cli import main; main()",
            "run",
            str(ROOT / "tests" / "procedures" / "skills-grasp-rotate.yaml"),
            "--out",
            str(out),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=240,
        check=False,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    from suture_engine.trace.reader import TraceReader

    return json.loads((out / "summary.json").read_text()), TraceReader(out / "trace.mcap")


def test_grasp_rotate_release_on_pybullet(tmp_path: Path) -> None:
    summary, trace = _trace_run(tmp_path)
    assert summary["outcome"] == "succeeded" and summary["final_state"] == "finished"
    assert summary["violations"] == [] and summary["retries"] == 0
    moves = [m.data for m in trace.messages(["/transitions"])]
    assert [m["dest"] for m in moves] == [
        "autonomous/grab",
        "autonomous/rotate",
        "autonomous/let-go",
        "finished",
    ]
    times = [m.log_time_ns for m in trace.messages(["/transitions"])]
    scene = load_procedure(ROOT / "tests" / "procedures" / "skills-grasp-rotate.yaml").scene
    q1 = [(m.log_time_ns, m.data["position"]) for m in trace.messages(["/joint_state/endobot_1"])]
    q2 = {m.log_time_ns: m.data["position"] for m in trace.messages(["/joint_state/endobot_2"])}
    # the measured stitcher tip during the rotation: on a circle about OP (tracking error only)
    o = np.array(scene.robots["endobot_1"].base.position)
    p = tip(scene, "endobot_2", q2[times[1]]) + np.array((0.0, 0.0, 0.01))
    axis = (p - o) / np.linalg.norm(p - o)
    during = [tip(scene, "endobot_1", q) for t, q in q1 if times[1] <= t <= times[2]]
    rel = np.array(during) - o
    radial = np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)
    assert np.ptp(radial) < 0.5e-3 and np.ptp(rel @ axis) < 0.5e-3
    turned = Rotation.from_rotvec(math.radians(60) * axis).as_matrix() @ rel[0]
    assert np.linalg.norm(rel[-1] - turned) < 0.5e-3  # the tip moved ~64 mm


def test_pass_needle_check_flags_tension_bounds(scene: Any) -> None:
    def codes(f_max: float) -> list[str]:
        params = PassNeedle.Params.model_validate(
            {
                "robot": "stitcher",
                "entry": "entry_2",
                "exit": "exit_2",
                "pull_length": 0.03,
                "max_tension": f_max,
            }
        )
        return [p.code for p in PassNeedle.check(params, scene)]

    assert codes(3.0) == []
    assert codes(0.1) == ["tension-bound-too-low"]
    assert codes(scene.tension_limit + 0.5) == ["tension-above-limit"]


def test_wrap_sweep_sets_the_angle_about_the_other_shaft(scene: Any) -> None:
    """``sweep`` overrides the half turn: a full turn ends where the arc began."""
    qs, tools = start_pose(scene)
    q_other = np.array(qs["endobot_2"])
    params = {"robot": "stitcher", "around": "grasper", "sweep": 2 * math.pi, "speed": 0.04}
    run = Run(Wrap(params), scene, qs, tools, max_t=60.0)
    assert run.status is SkillStatus.SUCCESS, run.message
    o2 = np.array(scene.robots["endobot_2"].base.position)
    t2 = tip(scene, "endobot_2", q_other)
    axis = (o2 - t2) / np.linalg.norm(o2 - t2)
    tips = np.array([tip(scene, "endobot_1", q) for q in run.q("endobot_1")])
    rel = tips - t2
    radial = rel - np.outer(rel @ axis, axis)
    on_loop = np.abs(np.linalg.norm(radial, axis=1) - 0.008) < 1e-6
    assert on_loop.sum() > 50
    e1 = radial[on_loop][0] / np.linalg.norm(radial[on_loop][0])
    e2 = np.cross(axis, e1)
    ang = np.unwrap(np.arctan2(radial[on_loop] @ e2, radial[on_loop] @ e1))
    assert ang[-1] - ang[0] == pytest.approx(-2 * math.pi, abs=0.02)
    assert np.allclose(radial[on_loop][0], radial[on_loop][-1], atol=1e-5)
