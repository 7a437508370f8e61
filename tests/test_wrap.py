"""``wrap`` around a bent-tip grasper's bent arm (``around_segment: tip``, algorithm 3).

The arm's geometry from the encoders (:func:`skills.wrap.bent_arm`) is checked against a
construction from positions and scipy rotations; the planned loop against the circle's
definition (radius about the arm's axis, distance along it); the shaft clearance against
dense sampling of both of the grasper's segments (shaft and bent arm).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skills.tool_path import ik_world, tip_world
from skills.wrap import BENT_ARM, BENT_JAW_END, Wrap, WrapParams, bent_arm
from suture_engine.language.loader import load_procedure
from suture_engine.runtime.context import SkillContext
from suture_engine.runtime.observation import (
    Observation,
    RobotObservation,
    SceneGeometry,
    SkillStatus,
    ToolState,
)

ROOT = Path(__file__).resolve().parent.parent
PROC = ROOT / "procedures" / "knot-algorithm-3.yaml"


@pytest.fixture(scope="module")
def proc() -> Any:
    return load_procedure(PROC)


def bases_of(scene: Any) -> dict[str, Any]:
    out = {}
    for name, spec in scene.robots.items():
        rot = Rotation.from_euler("xyz", spec.base.rpy).as_matrix()
        out[name] = (tuple(spec.base.position), tuple(rot.reshape(-1)))
    return out


def test_bent_arm_matches_a_construction_from_positions_and_scipy(proc: Any) -> None:
    bases = bases_of(proc.scene)
    base = bases["endobot_2"]
    rng = np.random.default_rng(3)
    for _ in range(20):
        point = np.array([0.0, -0.014, 0.025]) + rng.normal(scale=0.01, size=3)
        roll = float(rng.uniform(-1.0, 1.0))
        q = ik_world(point, roll, base)
        bend = tuple(rng.uniform(-1.5, 1.5, size=2))
        joint, arm = bent_arm(q, base, bend)
        # the shaft runs from the RCM point O' to the tip: the tool's z, from positions
        o2 = np.array(base[0])
        z = (point - o2) / np.linalg.norm(point - o2)
        np.testing.assert_allclose(joint, point - BENT_ARM * z, atol=1e-9)
        # tool frame = base rotation (x) roll about the tool's z; the bend is intrinsic x, y'
        rot = np.array(base[1]).reshape(3, 3) @ _tool_rotation(q)
        expected = (Rotation.from_matrix(rot) * Rotation.from_euler("XY", bend)).apply([0, 0, 1])
        np.testing.assert_allclose(arm, expected, atol=1e-9)
        assert rot[:, 2] == pytest.approx(z, abs=1e-9)


def _tool_rotation(q: Any) -> np.ndarray:
    """The tool frame in the base frame: yaw about x, pitch about y, roll about z (3.12)."""
    return Rotation.from_euler("XYZ", [q[0], q[1], q[2]]).as_matrix()


def plan(proc: Any, bend: tuple[float, float], **overrides: Any) -> tuple[Wrap, Any, Any]:
    """The ``loop`` wrap with the holder where the stitch's pull leaves it (the stitched
    start: its tip 40 mm along the normal from the exit) and the grasper at ``present``'s
    goal, bent by ``bend``."""
    from backends.pybullet.scene import STITCHED_PULL

    scene = proc.scene
    bases = bases_of(scene)
    present = proc.states["present"].params
    points = scene.tissue.points
    grasper_tip = np.asarray(points[present.target]) + np.asarray(present.offset)
    holder_tip = np.asarray(points["exit_2"]) + STITCHED_PULL * np.asarray(scene.tissue.normal)
    qs = {
        "endobot_1": ik_world(holder_tip, 0.0, bases["endobot_1"]),
        "endobot_2": ik_world(grasper_tip, 0.0, bases["endobot_2"]),
    }
    kind = overrides.pop("kind", "bent-tip-grasper")
    tools = {"endobot_1": ToolState("grasper", True), "endobot_2": ToolState(kind, bend=bend)}
    obs = Observation(
        0,
        0.0,
        {n: RobotObservation(q, np.zeros(4), np.zeros(6), tools[n]) for n, q in qs.items()},
        SceneGeometry(),
    )
    ctx = SkillContext("loop", dict(proc.roles), 1e-3, obs, scene, {}, bases)
    params = proc.states["loop"].params.model_dump()
    params.update(overrides)
    skill = Wrap(WrapParams.model_validate(params))
    skill.start(ctx)
    return skill, qs, bases


def sampled_gap(skill: Wrap, qs: Any, bases: Any, bend: Any) -> float:
    """Holder shaft to grasper (shaft and arm), by dense sampling of the segments."""
    o1 = np.asarray(bases["endobot_1"][0])
    o2 = np.asarray(bases["endobot_2"][0])
    joint, arm = bent_arm(qs["endobot_2"], bases["endobot_2"], bend)
    s = np.linspace(0.0, 1.0, 201)[:, None]
    grasper = np.vstack([o2 + s * (joint - o2), joint + s * (BENT_JAW_END * arm)])
    gap = math.inf
    for path in skill._paths:
        for q in path.table[::20]:
            t1 = tip_world(q, bases["endobot_1"])
            holder = o1 + s * (t1 - o1)
            d = np.linalg.norm(holder[:, None, :] - grasper[None, :, :], axis=2)
            gap = min(gap, float(d.min()))
    return gap


def procedure_bend(proc: Any) -> tuple[float, float]:
    return tuple(proc.states["bend"].params.angles)  # type: ignore[return-value]


def test_the_loop_circles_the_bent_arm(proc: Any) -> None:
    bend = procedure_bend(proc)
    skill, qs, bases = plan(proc, bend)
    assert skill._failure == ""
    p = skill.params
    assert isinstance(p, WrapParams) and p.height is not None
    joint, arm = bent_arm(qs["endobot_2"], bases["endobot_2"], bend)
    pts = np.array([skill.loop_point(s) for s in np.linspace(0.0, 1.0, 73)])
    rel = pts - joint
    along = rel @ arm
    radial = np.linalg.norm(rel - np.outer(along, arm), axis=1)
    np.testing.assert_allclose(along, p.height, atol=1e-12)
    np.testing.assert_allclose(radial, p.radius, atol=1e-12)
    # a full turn: the loop's angle about the arm advances through 2 pi
    ref = rel[0] - along[0] * arm
    ang = np.unwrap(
        [
            math.atan2(float(np.cross(ref, r) @ arm), float(ref @ r))
            for r in rel - np.outer(along, arm)
        ]
    )
    assert abs(ang[-1] - ang[0]) == pytest.approx(2 * math.pi, abs=1e-9)
    # the planned joints put the tip on the loop
    loop = skill._paths[-1]
    for s_, q in zip(np.linspace(0.0, 1.0, len(loop.table)), loop.table, strict=True):
        if round(s_ * 100) % 10 == 0:
            assert np.linalg.norm(tip_world(q, bases["endobot_1"]) - skill.loop_point(s_)) < 1e-6


@pytest.mark.parametrize("direction", ["front-to-back", "back-to-front"])
def test_around_the_arm_towards_the_holder_the_shafts_stay_apart(proc: Any, direction: str) -> None:
    bend = procedure_bend(proc)
    skill, qs, bases = plan(proc, bend, direction=direction)
    assert skill._failure == ""
    assert skill.shaft_gap >= 5e-3
    # sampled on a 0.06-0.6 mm grid over the segments: within the grid of the exact value
    assert sampled_gap(skill, qs, bases, bend) == pytest.approx(skill.shaft_gap, abs=5e-4)


def test_around_an_arm_pointing_away_or_the_straight_stem_the_shafts_cross(proc: Any) -> None:
    away = (0.0, math.pi / 2)
    skill, qs, bases = plan(proc, away)
    assert skill.shaft_gap < 1e-3 and sampled_gap(skill, qs, bases, away) < 1.5e-3
    assert "would cross the other tool's shaft or bent arm" in skill._failure
    stem, _, _ = plan(proc, (0.0, 0.0), around_segment="shaft", height=None, radius=8e-3)
    assert stem.shaft_gap < 1e-3 and "cross the other shaft" in stem._failure


def test_refused_loop_holds_the_holder(proc: Any) -> None:
    skill, qs, _ = plan(proc, (0.0, 0.0), kind="grasper")
    assert "no bent arm" in skill._failure
    tools = {"endobot_1": ToolState("grasper", True), "endobot_2": ToolState("grasper")}
    obs = Observation(
        0,
        0.0,
        {n: RobotObservation(q, np.zeros(4), np.zeros(6), tools[n]) for n, q in qs.items()},
        SceneGeometry(),
    )
    result = skill.step(None, obs)
    assert result.status is SkillStatus.FAILURE
    np.testing.assert_allclose(result.command.robots["endobot_1"].q, qs["endobot_1"])
