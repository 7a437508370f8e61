"""rotate-about's step-3/step-4 geometry of algorithm 1 (4.4.1) against independent oracles.

Oracles: scipy's rotations and scalar minimisation, closed-form distances of a
point on a circle to a line, cross-product point-to-line distances, and the
tool axis read as the direction from the RCM point to the tool tip.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation

from skills.rotate_about import (
    STITCHER_BODY,
    STITCHER_JAW,
    STITCHER_NEEDLE,
    SWEPT_PARTS,
    RotateAbout,
    RotateAboutParams,
    instrument_angle,
    segment_distance,
    stem_contact,
    sweep_clearance,
)
from suture_engine.language.loader import load_procedure
from suture_engine.robot.kinematics import forward_kinematics, inverse_kinematics, rotation
from suture_engine.runtime.context import SkillContext
from suture_engine.runtime.observation import (
    Observation,
    RobotObservation,
    SceneGeometry,
    SkillStatus,
    ToolState,
)

ROOT = Path(__file__).resolve().parent.parent
ROLES = {"stitcher": "endobot_1", "grasper": "endobot_2"}


@pytest.fixture(scope="module")
def scene() -> Any:
    return load_procedure(ROOT / "procedures" / "knot-algorithm-1.yaml").scene


def base(scene: Any, robot: str) -> tuple[Any, Any]:
    spec = scene.robots[robot].base
    rot = Rotation.from_euler("xyz", spec.rpy).as_matrix()
    return tuple(spec.position), tuple(rot.reshape(-1))


def tip(scene: Any, robot: str, q: Any) -> np.ndarray:
    pos, rot = base(scene, robot)
    return np.array(pos) + np.array(rot).reshape(3, 3) @ forward_kinematics(q).position


def line_distance(x: Any, a: Any, d: Any) -> float:
    """Distance of x to the infinite line through a along d (cross product)."""
    d = np.asarray(d, float) / np.linalg.norm(d)
    return float(np.linalg.norm(np.cross(np.asarray(x, float) - a, d)))


# ----------------------------------------------------------------- pure geometry
def test_segment_distance_matches_a_scalar_minimisation() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        a, b, x = rng.normal(size=(3, 3))
        best = minimize_scalar(
            lambda s, a=a, b=b, x=x: float(np.linalg.norm(a + s * (b - a) - x)),
            bounds=(0.0, 1.0),
            method="bounded",
            options={"xatol": 1e-10},
        )
        assert segment_distance([x], a, b)[0] == pytest.approx(best.fun, abs=1e-7)


def test_instrument_angle_of_known_directions() -> None:
    assert instrument_angle((0, 0, 1), (0, 0, 2)) == pytest.approx(0.0)
    assert instrument_angle((1, 0, 0), (0, 3, 0)) == pytest.approx(math.pi / 2)
    assert instrument_angle((1, 1, 0), (-1, 0, 0)) == pytest.approx(3 * math.pi / 4)


@pytest.mark.parametrize("angle", [math.pi, -math.pi, math.pi / 2])
def test_sweep_clearance_of_a_point_on_a_circle_about_a_parallel_stem(angle: float) -> None:
    # the axis is z through O; a point at radius rho turns about it; the stem is a long
    # segment parallel to z at (dx, dy): the point's distance to it is the planar distance
    rho, r_stem = 0.008, 0.001
    stem_xy = np.array((0.0, 0.006))  # at +90 deg: on the +pi sweep, off the -pi/2.. sweep
    stem = (np.array((*stem_xy, -0.05)), np.array((*stem_xy, 0.05)))
    result = sweep_clearance(
        (0, 0, 0), (0, 0, 1), (rho, 0, 0), np.eye(3), angle, stem, r_stem, points=[(0, 0, 0)]
    )
    thetas = np.linspace(0.0, angle, 20001)
    planar = np.hypot(rho * np.cos(thetas) - stem_xy[0], rho * np.sin(thetas) - stem_xy[1])
    assert result.distance == pytest.approx(planar.min() - r_stem, abs=1e-6)
    if angle > math.pi / 2 - 1e-9:  # the sweep passes +90 deg: closest is rho - 6 mm
        assert result.distance == pytest.approx(rho - 0.006 - r_stem, abs=1e-6)
        assert result.angle == pytest.approx(math.pi / 2, abs=0.01)
    else:  # the -pi sweep goes the other way round: closest at its end, (-rho, 0)
        assert result.distance == pytest.approx(math.hypot(rho, 0.006) - r_stem, abs=1e-6)


def test_sweep_clearance_against_scipy_rotations() -> None:
    rng = np.random.default_rng(11)
    for _ in range(3):
        o = rng.normal(size=3) * 0.05
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        tip0 = o + rng.normal(size=3) * 0.05
        frame = Rotation.random(random_state=rng).as_matrix()
        stem = (rng.normal(size=3) * 0.03, rng.normal(size=3) * 0.03)
        angle = float(rng.uniform(-math.pi, math.pi))
        got = sweep_clearance(o, axis, tip0, frame, angle, stem, 0.0025, samples=91)
        best = np.inf
        a0, b0 = stem
        for theta in np.linspace(0.0, angle, 91):
            rot = Rotation.from_rotvec(theta * axis).as_matrix()
            pts = [o + rot @ (tip0 + frame @ np.array(p) - o) for p in STITCHER_NEEDLE]
            for x in pts:
                seg = minimize_scalar(
                    lambda s, x=x, a0=a0, b0=b0: float(np.linalg.norm(a0 + s * (b0 - a0) - x)),
                    bounds=(0.0, 1.0),
                    method="bounded",
                    options={"xatol": 1e-10},
                )
                best = min(best, seg.fun - 0.0025)
        assert got.distance == pytest.approx(best, abs=1e-6)
        assert got.instrument_angle == pytest.approx(
            instrument_angle(frame[:, 2], stem[0] - stem[1]), abs=1e-12
        )


def test_swept_parts_hold_the_declared_tool_geometry() -> None:
    needle = np.array(STITCHER_NEEDLE[1:])
    jaw = np.array(STITCHER_NEEDLE[0])
    assert np.allclose(jaw, (-4e-3, 0.0, 3e-3))
    # a 6 mm half circle from the jaw: every point 6 mm from the circle's centre
    centre = jaw + np.array((0.0, 0.0, 6e-3))
    assert np.allclose(np.linalg.norm(needle - centre, axis=1), 6e-3)
    assert np.allclose(needle[-1], jaw + np.array((0.0, 0.0, 12e-3)))
    assert SWEPT_PARTS["needle-tip"] == (STITCHER_NEEDLE[-1],)
    assert set(SWEPT_PARTS["tool"]) == set(STITCHER_NEEDLE) | set(STITCHER_BODY)
    assert np.allclose(STITCHER_JAW, (4e-3, 0.0, 3e-3))


@pytest.mark.parametrize("side", [1.0, -1.0])
@pytest.mark.parametrize("height", [0.015, 0.025, 0.04])
def test_stem_contact_puts_the_open_jaw_against_the_stem(
    scene: Any, side: float, height: float
) -> None:
    b1 = base(scene, "endobot_1")
    o1 = np.array(b1[0])
    t2 = np.array((0.0, -0.012, 0.002))
    o2 = np.array(scene.robots["endobot_2"].base.position)
    c = stem_contact(b1, (t2, o2), height, side, 0.0025)
    u = (o2 - t2) / np.linalg.norm(o2 - t2)
    # the tool tip is where forward kinematics puts it, and the tool passes through O
    assert np.allclose(tip(scene, "endobot_1", c.joints), c.tip, atol=1e-9)
    frame = np.array(b1[1]).reshape(3, 3) @ rotation(c.joints)
    assert line_distance(o1, c.tip, frame[:, 2]) < 1e-9
    # the open jaw's centre is the contact point, 2.5 + 1 mm from the stem's axis,
    # `height` up the stem from its tip
    assert np.allclose(c.tip + frame @ np.array(STITCHER_JAW), c.contact, atol=1e-7)
    assert line_distance(c.contact, t2, u) == pytest.approx(0.0035, abs=1e-7)
    assert (c.stem_point - t2) @ u == pytest.approx(height, abs=1e-9)
    # front or back: the side of the stem given by u x (towards O1, orthogonal to u)
    over = o1 - c.stem_point
    over -= (over @ u) * u
    e_side = np.cross(u, over / np.linalg.norm(over))
    assert (c.contact - c.stem_point) @ e_side == pytest.approx(side * 0.0035, abs=1e-7)
    # the jaws' line (tool x, needle jaw -> open jaw) points at the stem
    assert frame[:, 0] @ e_side * side < -0.9
    # the angle between the instruments: O1 -> tip against O2 -> the stem's tip
    assert c.instrument_angle == pytest.approx(instrument_angle(c.tip - o1, t2 - o2), abs=1e-9)


# ----------------------------------------------------------------- the skill
def run_rotation(
    scene: Any, params: dict[str, Any], q1: Any, q2: Any, o2: Any = None
) -> tuple[Any, list[Any]]:
    """An ideal-tracking run (next joints = commanded joints); (skill, results).

    ``o2`` moves the grasper's base (its RCM point) from where the scene declares it.
    """
    poses = {n: base(scene, n) for n in scene.robots}
    if o2 is not None:
        poses["endobot_2"] = (tuple(o2), poses["endobot_2"][1])

    def observe(t: float, q: Any) -> Observation:
        tools = {"endobot_1": ToolState("stitcher", True), "endobot_2": ToolState("grasper")}
        robots = {
            "endobot_1": RobotObservation(
                np.array(q, float), np.zeros(4), np.zeros(6), tools["endobot_1"]
            ),
            "endobot_2": RobotObservation(
                np.array(q2, float), np.zeros(4), np.zeros(6), tools["endobot_2"]
            ),
        }
        return Observation(round(t * 1000), t, robots, SceneGeometry())

    obs = observe(0.0, q1)
    ctx = SkillContext("rotate", ROLES, 1e-3, obs, scene, {}, poses)
    skill = RotateAbout(RotateAboutParams.model_validate(params))
    skill.start(ctx)
    results = []
    t = 0.0
    while t < 20.0:
        result = skill.step(ctx, obs)
        results.append(result)
        if result.status is not SkillStatus.RUNNING:
            break
        t += 1e-3
        obs = observe(t, result.command.robots["endobot_1"].q)
    return skill, results


def contact_setup(scene: Any, o2: Any, side: float = 1.0) -> tuple[Any, Any, Any]:
    """Grasper tip at (0, -12, 2) mm with its RCM at o2; the stitcher at its step-3 contact."""
    t2 = np.array((0.0, -0.012, 0.002))
    b2 = (tuple(o2), tuple(Rotation.from_euler("xyz", (math.pi, 0, 0)).as_matrix().reshape(-1)))
    r2 = np.array(b2[1]).reshape(3, 3)
    q2 = inverse_kinematics(r2.T @ (t2 - np.array(o2)), 0.0)
    c = stem_contact(base(scene, "endobot_1"), (t2, np.array(o2)), 0.025, side, 0.0025)
    return c, q2, t2


def test_the_skill_fails_before_moving_when_the_needle_tip_would_hit_the_stem(
    scene: Any,
) -> None:
    # instruments 41 deg apart (the grasper's RCM straight above its tip): turning the
    # stitcher +180 deg about OP brings the needle tip through the grasper stem
    o2 = (0.0, -0.012, 0.142)
    c, q2, t2 = contact_setup(scene, o2)
    params = {
        "robot": "stitcher",
        "angle": math.pi,
        "relative_to": "grasper",
        "point": tuple(c.contact - t2),
        "clear_of": "grasper",
    }
    skill, results = run_rotation(scene, params, c.joints, q2, o2)
    assert results[-1].status is SkillStatus.FAILURE and len(results) == 1
    assert "needle-tip" in results[-1].message and "41 deg" in results[-1].message
    assert skill.clearance is not None and skill.clearance.distance < 0.0
    # the other way round the tip stays clear, but the roll (-124 deg at the contact)
    # would pass -180 deg: the roll joint limit stops it instead
    skill, results = run_rotation(scene, {**params, "angle": -math.pi}, c.joints, q2, o2)
    assert math.degrees(c.joints[2]) == pytest.approx(-123.5, abs=0.5)
    assert results[-1].status is SkillStatus.FAILURE and "roll" in results[-1].message
    assert skill.clearance is not None and skill.clearance.distance > 0.001


def test_the_bench_geometry_clears_the_needle_tip_but_not_the_tool(scene: Any) -> None:
    o2 = scene.robots["endobot_2"].base.position
    c, q2, t2 = contact_setup(scene, o2)
    params = {
        "robot": "stitcher",
        "angle": math.pi,
        "relative_to": "grasper",
        "point": tuple(c.contact - t2),
        "clear_of": "grasper",
        "speed": 3.0,
    }
    skill, results = run_rotation(scene, params, c.joints, q2)
    assert results[-1].status is SkillStatus.SUCCESS, results[-1].message
    assert skill.clearance is not None and skill.clearance.distance > 0.003
    assert math.degrees(skill.clearance.instrument_angle) == pytest.approx(68.3, abs=0.5)
    # the tool's tip body turns about the open jaw, 4 mm away, through the stem
    skill, results = run_rotation(scene, {**params, "swept": "tool"}, c.joints, q2)
    assert results[-1].status is SkillStatus.FAILURE and "tool comes -" in results[-1].message
