"""Ligation algorithm 2's procedure (thesis 4.4.2): timeouts and the slide-to-tip target.

The geometry is rebuilt here from the scene alone (base positions, the grasp
target of ``grab-tail``, straight 5 mm shafts from each tip back through its RCM
point), not from the skills' code.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from suture_engine.language.loader import load_procedure

ROOT = Path(__file__).resolve().parent.parent
SHAFT_RADIUS = 2.5e-3
"""Radius of both robots' shafts in the plain PyBullet model [m] (5 mm tools)."""
START_Q = (0.0, 0.0, 0.0, 0.08)
"""Joints of the start pose (yaw, pitch, roll [rad], insertion [m])."""


def _segment_distance(p1: Any, q1: Any, p2: Any, q2: Any, n: int = 600) -> float:
    """Smallest distance between two segments [m], by dense sampling."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    a = p1 + s * (q1 - p1)
    b = p2 + s * (q2 - p2)
    return float(np.min(np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)))


def _base(proc: Any, role: str) -> tuple[Any, Any]:
    spec = proc.scene.robots[proc.roles[role]].base
    rot = Rotation.from_euler("xyz", spec.rpy).as_matrix()
    return np.asarray(spec.position, dtype=float), rot


@pytest.mark.parametrize("mirror", [False, True])
def test_slide_to_tip_target_lies_beside_and_beyond_the_grasper_tip(mirror: bool) -> None:
    proc: Any = load_procedure(
        ROOT / "procedures" / "knot-algorithm-2.yaml", params={"mirror": mirror}
    )
    grab = proc.states["grab-tail"].params
    points = proc.scene.tissue.points
    tip2 = np.asarray(points[grab.target], dtype=float) + np.asarray(grab.offset)
    o1, _ = _base(proc, "stitcher")
    o2, _ = _base(proc, "grasper")
    slide = proc.states["slide-to-tip"].params
    assert slide.relative_to == "grasper"
    goal = tip2 + np.asarray(slide.target) + np.asarray(slide.offset)
    up = (o2 - tip2) / np.linalg.norm(o2 - tip2)  # along the grasper stem, tip to RCM
    rel = goal - tip2
    lateral = float(np.linalg.norm(rel - (rel @ up) * up))
    # beside the stem (not on it: the tools collided there) ...
    assert lateral > 2.0 * SHAFT_RADIUS
    # ... just beyond the tip along the stem, not back up it ...
    assert -(rel @ up) >= 0.0
    assert lateral < 10e-3 and -(rel @ up) <= 3e-3
    # ... above the tissue, and the two shafts do not touch there
    assert goal[2] > 1e-3
    clearance = _segment_distance(goal, o1, tip2, o2)
    assert clearance > 2.0 * SHAFT_RADIUS + 1e-3


def test_slide_to_tip_ends_on_the_side_where_the_loop_over_the_hook_ends() -> None:
    sides = []
    for mirror in (False, True):
        proc: Any = load_procedure(
            ROOT / "procedures" / "knot-algorithm-2.yaml", params={"mirror": mirror}
        )
        sides.append(np.asarray(proc.states["slide-to-tip"].params.target))
        assert proc.states["over-hook"].params.direction == (
            "back-to-front" if mirror else "front-to-back"
        )
    # the two throws end on opposite sides of the stem (along the world y, across it)
    assert sides[0][1] * sides[1][1] < 0.0


def _min_jerk_duration(distance: float, speed: float) -> float:
    # quintic 10 s^3 - 15 s^4 + 6 s^5: peak rate 15/8 at s = 1/2
    return 15.0 / 8.0 * distance / speed


def test_stitch_approach_timeout_covers_its_move_from_the_start_pose() -> None:
    from suture_engine.robot.kinematics import forward_kinematics

    proc: Any = load_procedure(ROOT / "procedures" / "stitch.yaml")
    state = proc.states["approach"]
    p = state.params
    o1, rot = _base(proc, "stitcher")
    start = o1 + rot @ np.asarray(forward_kinematics(START_Q).position)
    goal = np.asarray(proc.scene.tissue.points[p.target], dtype=float) + np.asarray(p.offset)
    duration = _min_jerk_duration(float(np.linalg.norm(goal - start)), p.speed)
    assert state.timeout is not None
    assert state.timeout >= duration + 1.0  # 1 s for move-to to settle


def test_tighten_and_slide_timeouts_cover_their_moves() -> None:
    proc: Any = load_procedure(ROOT / "procedures" / "knot-algorithm-2.yaml")
    tighten = proc.states["tighten"]
    d = float(np.linalg.norm(tighten.params.target))
    assert tighten.timeout >= _min_jerk_duration(d, tighten.params.speed) + 1.0
    slide = proc.states["slide-to-tip"]
    # the slide starts where the loop over the hook ends: a loop radius off the stem,
    # 10 mm up it
    radius = proc.states["over-hook"].params.radius
    longest = float(np.linalg.norm(np.asarray(slide.params.target))) + radius + 10e-3
    assert slide.timeout >= _min_jerk_duration(longest, slide.params.speed) + 1.0


def _skills(proc: Any) -> list[str]:
    out: list[str] = []
    for state in proc.states.values():
        if state.skill is not None:
            out.append(state.skill)
        if state.use is not None:
            out.extend(_skills(state.use))
    return out


@pytest.mark.parametrize("algorithm", [1, 2, 3])
def test_the_second_throw_of_a_square_knot_makes_no_second_stitch(algorithm: int) -> None:
    proc: Any = load_procedure(
        ROOT / "procedures" / "square-knot.yaml", params={"algorithm": algorithm}
    )
    first = proc.states["simple-knot"].use.states["stitch"].use
    second = proc.states["mirrored-knot"].use.states["stitch"].use
    assert "pass-needle" in _skills(first)
    assert _skills(second) == []


NOT_REPEATABLE = {"wrap", "rotate-about", "pass-jaws", "pass-needle"}
"""Skills whose repetition changes the result (another loop, another roll or half
turn, the needle passed back, another bite); re-running them is no retry."""


@pytest.mark.parametrize("algorithm", [1, 2, 3])
def test_no_retry_re_runs_a_step_that_cannot_be_repeated(algorithm: int) -> None:
    proc: Any = load_procedure(ROOT / "procedures" / f"knot-algorithm-{algorithm}.yaml")
    previous = {
        state.on["done"]: name
        for name, state in proc.states.items()
        if isinstance(state.on.get("done"), str)
    }
    checked = 0
    for name, state in proc.states.items():
        policy = state.on.get("failed")
        before = previous.get(name)
        if policy is None or before is None:
            continue
        prev = proc.states[before]
        skills = _skills(prev.use) if prev.use is not None else [prev.skill]
        if NOT_REPEATABLE & set(skills):
            checked += 1
            assert policy.retry == 0, f"{name}: a retry would re-run {before} ({skills})"
    assert checked >= 2
