"""Ligation algorithm 2's procedure (thesis 4.4.2): timeouts and the slide-to-tip target.

The geometry is rebuilt here from the scene alone (base positions, the grasp
target of ``grab-tail``, straight 5 mm shafts from each tip back through its RCM
point), not from the skills' code.
"""

from __future__ import annotations

import math
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


JAW_REGION = 6e-3
"""Length behind each tool tip that the shafts' collision cylinders leave out [m]."""
JAW_INNER = 3e-3
"""Distance from the stitcher's tip to the inner face of either closed jaw [m]."""


def _lifted_tip(proc: Any) -> Any:
    """The grasper's tip after the first throw's lift [m]: the grab point plus the lift."""
    grab = proc.states["grab-tail"].params
    lift = proc.states["lift-tail"].params
    entry = np.asarray(proc.scene.tissue.points[grab.target], dtype=float)
    return entry + np.asarray(grab.offset) + np.asarray(lift.target)


@pytest.mark.parametrize(("mirror", "tail_mm"), [(False, 30), (True, 30), (False, 40), (False, 45)])
def test_slide_to_tip_straddles_the_grasper_tip(mirror: bool, tail_mm: int) -> None:
    proc: Any = load_procedure(
        ROOT / "procedures" / "knot-algorithm-2.yaml",
        params={"mirror": mirror, "tail": f"{tail_mm} mm", "stitch": False},
    )
    grab = proc.states["grab-tail"].params
    points = proc.scene.tissue.points
    assert proc.states["lift-tail"].params.relative_to == "grasper"
    tip2 = _lifted_tip(proc)
    o1, _ = _base(proc, "stitcher")
    o2, _ = _base(proc, "grasper")
    slide = proc.states["slide-to-tip"].params
    assert slide.relative_to == "grasper"
    goal = tip2 + np.asarray(slide.target) + np.asarray(slide.offset)
    up = (o2 - tip2) / np.linalg.norm(o2 - tip2)  # along the grasper stem, tip to RCM
    rel = goal - tip2
    lateral = float(np.linalg.norm(rel - (rel @ up) * up))
    # 10 mm beyond the grasper tip along its stem ...
    assert 8e-3 <= -(rel @ up) <= 12e-3
    # ... on its axis, so that the grasper's axis lies between the stitcher's jaws
    # even with the 2 mm arrival tolerance
    assert lateral + slide.tolerance < JAW_INNER
    # then 10 mm to the tail's side (away from the stitcher's RCM point), still 10 mm
    # beyond the tip: the needle's crossing passes outside the tail, which leaves the
    # jaws at ~34 deg to the stem, 6.8 mm out at 10 mm (on the stitcher's side it would
    # cross inside it; 6 mm out, the jaws closed on it)
    under = proc.states["under"].params
    assert under.relative_to == "grasper"
    below = tip2 + np.asarray(under.target) + np.asarray(under.offset)
    rel = below - tip2
    towards_stitcher = (o1 - tip2) - ((o1 - tip2) @ up) * up
    towards_stitcher /= np.linalg.norm(towards_stitcher)
    assert 8e-3 <= -(rel @ up) <= 12e-3
    assert -11e-3 <= rel @ towards_stitcher <= -9e-3
    # ... at least 3.5 mm (the closed jaws' half span and the thread) off the straight
    # tail from the jaws to the entry point
    entry = np.asarray(points[grab.target], dtype=float)
    tail_dir = (entry - tip2) / np.linalg.norm(entry - tip2)
    off = rel - (rel @ tail_dir) * tail_dir
    assert float(np.linalg.norm(off)) >= 3.5e-3
    for point in (goal, below):
        # above the tissue; the stitcher's shaft (collision cylinder from 6 mm behind its
        # tip) clears the grasper's shaft.
        assert point[2] > 5e-3
        u1 = (o1 - point) / np.linalg.norm(o1 - point)
        clearance = _segment_distance(point + JAW_REGION * u1, o1, tip2 + JAW_REGION * up, o2)
        assert clearance > 2.0 * SHAFT_RADIUS + 1e-3
    # slide, move under, pass the needle, retract the hook, draw the stitcher's end through
    # the loop while it still rests on the jaws, then back the grasper out and tighten
    assert proc.states["slide-to-tip"].on["done"] == "under"
    assert proc.states["under"].on["done"] == "pass-needle"
    assert proc.states["retract-hook"].on["done"] == "cinch"
    assert proc.states["cinch"].on["done"] == "release-hook"
    assert proc.states["release-hook"].on["done"] == "pull-through"
    # the single throw holds its loop on the hook through the cinch by default (the hook
    # is retracted after it, as on a mirrored second throw); the loose throw retracts it
    # before the cinch
    assert not proc.states["retract-hook"].enabled and proc.states["release-hook"].enabled
    loose: Any = load_procedure(
        ROOT / "procedures" / "knot-algorithm-2.yaml",
        params={"mirror": mirror, "stitch": False, "hold_loop": False},
    )
    assert loose.states["retract-hook"].enabled and not loose.states["release-hook"].enabled
    assert proc.states["pull-through"].on["done"] == "tighten"
    # the cinch and the tighten draw the stitcher away from the grasper, above the tissue
    cinch = proc.states["cinch"].params
    tighten = proc.states["tighten"].params
    assert cinch.relative_to == tighten.relative_to == "stitcher"
    drawn = below + np.asarray(cinch.target)
    assert float(np.linalg.norm(np.asarray(cinch.target))) >= 25e-3
    assert drawn[2] > 5e-3 and (drawn + np.asarray(tighten.target))[2] > 5e-3
    away = (o1 - o2) / np.linalg.norm(o1 - o2)
    assert np.asarray(cinch.target) @ away > 0.9 * np.linalg.norm(np.asarray(cinch.target))
    assert np.asarray(tighten.target) @ away > 0.9 * np.linalg.norm(np.asarray(tighten.target))
    # a first throw loops back to front (a mirrored second throw: see the next tests)
    assert proc.states["over-hook"].params.direction == "back-to-front"


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


def test_stitch_lay_and_lower_timeouts_cover_their_moves() -> None:
    """The strand is laid from where the pull ends (l_d along the normal from the exit)
    to its goal, then the needle comes back over the exit: each step's timeout covers
    its whole move (a guarded lay may stop earlier)."""
    proc: Any = load_procedure(ROOT / "procedures" / "stitch.yaml")
    exit_ = np.asarray(proc.scene.tissue.points["exit_2"], dtype=float)
    normal = np.asarray(proc.scene.tissue.normal, dtype=float)
    pulled = exit_ + normal * proc.states["bite"].params.pull_length
    lay, lower = proc.states["lay-strand"], proc.states["lower"]
    laid = exit_ + np.asarray(lay.params.offset)
    back = exit_ + np.asarray(lower.params.offset)
    for state, a, b in ((lay, pulled, laid), (lower, laid, back)):
        d = float(np.linalg.norm(b - a))
        assert state.timeout >= _min_jerk_duration(d, state.params.speed) + 1.0, state


def test_tighten_and_slide_timeouts_cover_their_moves() -> None:
    proc: Any = load_procedure(ROOT / "procedures" / "knot-algorithm-2.yaml")
    for name in ("cinch", "tighten"):
        state = proc.states[name]
        d = float(np.linalg.norm(state.params.target))
        assert state.timeout >= _min_jerk_duration(d, state.params.speed) + 1.0
    slide = proc.states["slide-to-tip"]
    # the slide starts where the take-up after the loop over the hook ends: a loop
    # radius off the stem, `height` up it, then moved by the take-up
    wrap = proc.states["over-hook"].params
    take_up = float(np.linalg.norm(np.asarray(proc.states["take-up"].params.target)))
    longest = float(np.linalg.norm(np.asarray(slide.params.target)))
    longest += wrap.radius + wrap.height + take_up
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
        ROOT / "procedures" / "square-knot.yaml", params={"algorithm": algorithm, "stitch": True}
    )
    first = proc.states["simple-knot"].use.states["stitch"]
    second = proc.states["mirrored-knot"].use.states["stitch"]
    assert "pass-needle" in _skills(first.use)
    # the second throw skips its stitch (when: false), or uses one that does nothing
    assert not second.enabled or _skills(second.use) == []
    assert first.enabled


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
        if policy is None or isinstance(policy, str) or before is None:
            continue  # no failure policy, or a plain transition (no retry)
        prev = proc.states[before]
        skills = _skills(prev.use) if prev.use is not None else [prev.skill]
        if NOT_REPEATABLE & set(skills):
            checked += 1
            assert policy.retry == 0, f"{name}: a retry would re-run {before} ({skills})"
    assert checked >= 2


HOOK_REACH = 2.5e-3
"""How far the extended hook passes the grasper's jaw centre along the stem [m]: the
shank's end, 1 mm beyond its offset (``Grasper.hook_reach``, 1.5 mm)."""


@pytest.mark.parametrize("tail_mm", [30, 40, 45])
def test_grab_tail_closes_near_the_tail_end_then_lifts_it_clear_of_the_tissue(
    tail_mm: int,
) -> None:
    proc: Any = load_procedure(
        ROOT / "procedures" / "knot-algorithm-2.yaml",
        params={"tail": f"{tail_mm} mm", "stitch": False},
    )
    tail = tail_mm * 1e-3
    grab = proc.states["grab-tail"].params
    points = proc.scene.tissue.points
    entry = np.asarray(points[grab.target], dtype=float)
    exit_ = np.asarray(points[proc.params["exit"]], dtype=float)
    along = (exit_ - entry) / np.linalg.norm(exit_ - entry)
    end = entry - tail * along  # the tail lies out of the entry, away from the exit
    jaws = entry + np.asarray(grab.offset)
    rel = jaws - end
    lateral = rel - (rel @ along) * along
    # on the tail, within one capsule (4-7.5 mm) of its end, on the tail's side of it ...
    assert float(np.linalg.norm(lateral[:2])) < 1e-3
    assert 0.0 < float(rel @ along) <= 5e-3
    # ... above the tail's axis (0.9 mm up) by less than the jaws' 3 mm reach, and high
    # enough that the tilted 5 mm shaft clears the surface (measured window 2.5-3.9 mm)
    assert 2.5e-3 <= jaws[2] <= 3.9e-3
    # the lift keeps the grasped length to the entry point (no pull through the stitch)
    lift = proc.states["lift-tail"].params
    lifted = jaws + np.asarray(lift.target)
    assert float(np.linalg.norm(lifted - entry)) <= float(np.linalg.norm(jaws - entry))
    # and the extended hook, 6 mm beyond the jaws along the stem, stays above the tissue
    o2, _ = _base(proc, "grasper")
    up = (o2 - lifted) / np.linalg.norm(o2 - lifted)
    assert (lifted - HOOK_REACH * up)[2] > 3e-3
    order = list(proc.states)
    assert order.index("lift-tail") < order.index("extend-hook")
    assert proc.states["grab-tail"].on["done"] == "lift-tail"
    assert proc.states["lift-tail"].on["done"] == "extend-hook"


def _run_on_thread(
    tmp_path: Path,
    procedure: str,
    seed: int,
    sets: list[str],
    max_time_s: float,
    backend: str = "pybullet-surgical-stitched",
) -> tuple[Any, Any]:
    """Run a bundled procedure with the thread (by default on the stitched start);
    (summary, knot entry)."""
    import json

    from suture_engine.runtime.run import run_procedure

    run_procedure(
        ROOT / "procedures" / procedure,
        backend=backend,
        seed=seed,
        sets=sets,
        out=tmp_path / "run",
        max_time_s=max_time_s,
    )
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    knot = summary["knot"][0] if isinstance(summary["knot"], list) else summary["knot"]
    return summary, knot


@pytest.mark.slow
def test_algorithm_2_ties_a_simple_knot_on_the_surgical_backend(tmp_path: Path) -> None:
    """One throw on the thread, tissue and mounted tools, from the stitched start (seed 3):
    the run succeeds and the ground-truth classifier finds a trefoil in the simulated
    thread, with the true tension under the derived limit all along. (Not every seed
    ties it: see the README for the rate over seeds.)"""
    summary, knot = _run_on_thread(tmp_path, "knot-algorithm-2.yaml", 3, ["stitch=false"], 90)
    assert summary["outcome"] == "succeeded"
    assert knot["type"] == "trefoil"
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


@pytest.mark.slow
def test_the_whole_chain_from_a_real_stitch_stays_under_the_tension_limit(
    tmp_path: Path,
) -> None:
    """The whole chain on the thread (seed 0): the stitch made on the tail-held start, then
    the first throw; 150 s simulated end it in the mirrored throw. The true tension stays
    under the derived limit all along: with a hook that pushed at 50 N, its retraction
    dragged the strand over the grasper's jaws to 9.88 N true here, unseen by the base
    estimates (1.19-1.88 N). Since the hook gives way at 5 N the first throw ties no knot
    from a real stitch on seeds 0 and 1 (see the README)."""
    summary, _ = _run_on_thread(
        tmp_path, "square-knot.yaml", 0, ["stitch=true"], 150, "pybullet-surgical"
    )
    assert summary["outcome"] != "locked"
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


@pytest.mark.slow
def test_a_second_throw_that_is_not_mirrored_ties_a_granny_knot(tmp_path: Path) -> None:
    """The thesis' failure (4.4.1), from a whole procedure: the second throw passes the
    needle the same way as the first (`mirror=false`), and the ground-truth classifier
    finds a granny knot (determinant 9) in the simulated thread, seed 3 (seeds 1, 2 and 5
    tie only the first trefoil: see the README)."""
    summary, knot = _run_on_thread(
        tmp_path, "square-knot.yaml", 3, ["stitch=false", "mirror=false"], 220
    )
    assert summary["outcome"] == "succeeded"
    assert knot["type"] == "granny" and knot["determinant"] == 9
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


@pytest.mark.slow
def test_algorithm_2_ties_a_square_knot_on_the_surgical_backend(tmp_path: Path) -> None:
    """The main job's procedure on the thread, from the stitched start, in the loose
    layout (``hold_loop=false``; seed 0 since the model's hook and hand-over fixes of
    2026-12-02, seed 4 before them): the first throw, then its mirror image, and the
    ground-truth classifier finds a square knot (determinant 9, v3 0: two trefoils of
    opposite handedness) that binds the stitch, with the true tension under the derived
    limit all along."""
    summary, knot = _run_on_thread(
        tmp_path, "square-knot.yaml", 0, ["stitch=false", "hold_loop=false"], 220
    )
    assert summary["outcome"] == "succeeded"
    assert knot["type"] == "square" and knot["determinant"] == 9 and knot["v3"] == 0
    assert knot["through_tissue"]
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seed", "sets", "check", "passed", "knot_type"),
    [
        (0, [], "tension 0.20 N not reached within 27.0 mm", True, "trefoil"),
        (1, ["hold_loop=false"], "tension 0.10 N not reached within 6.5 mm", False, "unknot"),
    ],
    ids=["held-loop-cinch", "loose-take-up"],
)
def test_a_missed_second_throw_is_caught_by_its_check_and_the_run_fails(
    tmp_path: Path, seed: int, sets: list[str], check: str, passed: bool, knot_type: str
) -> None:
    """The main job on a seed whose second throw misses. The held loop (33 mm up), seed 0:
    the needle's end does not go through the loop, and the cinch does not draw it taut
    within 27 mm (its branch drew taut after 27.8 mm and ended ``succeeded`` with one
    trefoil before the bound). The loose layout, seed 1 (2026-12-02, after the model's
    hook and hand-over fixes; seed 14 before them): the first throw tied nothing, the
    mirrored take-up does not draw taut within its window, and the hook is retracted
    before the needle is passed. Either way the throw ends in ``mirrored-knot.not-tied``
    and the robots lock for the surgeon (none here: the run stops ``failed``) instead of
    claiming a knot. The ground truth agrees: the first trefoil only, or no knot at all.
    The true tension stays under the limit."""
    summary, knot = _run_on_thread(tmp_path, "square-knot.yaml", seed, sets, 220)
    assert summary["outcome"] == "failed" and summary["final_state"] == "lock"
    assert summary["metrics"]["stopped"].startswith("locked")
    from suture_engine.trace.reader import TraceReader

    trace = TraceReader(tmp_path / "run" / "trace.mcap")
    details = [m.data["detail"] for m in trace.messages(["/events"])]
    assert "exhausted:mirrored-knot.not-tied" in details
    assert f"skill-failure:{check} of travel" in details
    entered = [m.data["dest"] for m in trace.messages(["/transitions"])]
    assert "autonomous/mirrored-knot.drop-loop" in entered
    assert any(d.endswith("mirrored-knot.pass-needle") for d in entered) is passed
    assert knot["type"] == knot_type
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


@pytest.mark.slow
def test_the_readme_seed_that_ties_the_square_knot(tmp_path: Path) -> None:
    """``suture run procedures/square-knot.yaml --seed 1``, as the README gives it: the
    procedure's own backend (the stitched start) and the held-loop layout (mirrored loop
    33 mm up). It ends ``succeeded`` with a square knot that binds the stitch and lies
    square (the second throw drawn along its securing direction, 7.1-7.3), the true
    tension under the limit all along. (The default seed 0 locks in the mirrored cinch's
    bound with the first trefoil only: the held-loop case of
    ``test_a_missed_second_throw_is_caught_by_its_check_and_the_run_fails``.)"""
    import json
    import subprocess
    import sys

    out = tmp_path / "main"
    cmd = [sys.executable, "-m", "suture_engine.cli", "run", "procedures/square-knot.yaml"]
    res = subprocess.run(
        [*cmd, "--seed", "1", "--out", str(out)], cwd=ROOT, capture_output=True, text=True
    )
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["backend"] == "pybullet-surgical-stitched" and summary["seed"] == 1
    knot = summary["knot"]
    assert summary["outcome"] == "succeeded"
    assert knot["type"] == "square" and knot["determinant"] == 9 and knot["v3"] == 0
    assert knot["through_tissue"] and knot["lay"] == "square" and knot["post_straight"]
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


def test_the_second_throw_keeps_the_tail_and_the_stitched_start_skips_the_stitch() -> None:
    proc: Any = load_procedure(
        ROOT / "procedures" / "square-knot.yaml", params={"algorithm": 2, "stitch": False}
    )
    first = proc.states["simple-knot"].use.states
    second = proc.states["mirrored-knot"].use.states
    # `stitch` reaches the first throw (the stitched start has the stitch made)
    assert not first["stitch"].enabled and not second["stitch"].enabled
    # the grasper holds the tail from the first throw on: no second grab and lift
    assert first["grab-tail"].enabled and first["lift-tail"].enabled
    assert not second["grab-tail"].enabled and not second["lift-tail"].enabled


@pytest.mark.parametrize(
    ("procedure", "params", "missed"),
    [
        ("square-knot.yaml", {"stitch": False}, True),
        ("square-knot.yaml", {"stitch": False, "check_throw": False}, False),
        ("square-knot.yaml", {"stitch": False, "mirror": False}, False),
        ("secure-knot.yaml", {}, False),
    ],
)
def test_a_mirrored_cinch_that_does_not_draw_taut_ends_the_run_failed(
    procedure: str, params: dict[str, Any], missed: bool
) -> None:
    """The square knot's second throw is checked by measurement: its cinch's 0.3 N guard
    (the stitcher's base estimate along the draw) not met means the loop never drew taut
    on the jaws and the needle's end is not through it: the hook is retracted, the throw
    ends failed, and the robots lock for the surgeon. The first throw's cinch, whose
    strand is slack, goes on as before; so do an unmirrored second throw and
    ``secure-knot.yaml``'s (where the guard does not tell a tied throw from a missed
    one)."""
    from suture_engine.runtime.automaton import Then
    from suture_engine.runtime.plan import compile_procedure

    proc = load_procedure(ROOT / "procedures" / procedure, params=params)
    plan = compile_procedure(proc)
    second = "mirrored-knot" if procedure == "square-knot.yaml" else "second-throw"
    first = "simple-knot" if procedure == "square-knot.yaml" else "first-throw"
    assert plan.steps[f"{first}.cinch"].policy.goto == f"{first}.release-hook"
    cinch = plan.steps[f"{second}.cinch"]
    assert cinch.on_done == f"{second}.release-hook"
    if missed:
        drop = plan.steps[f"{second}.drop-loop"]
        assert cinch.policy.goto == drop.name and drop.enabled
        assert drop.on_done == drop.policy.goto == f"{second}.not-tied"
        # the throw's failed end, under the square knot's policy: no retry, then a lock
        # for the surgeon
        end = plan.steps[f"{second}.not-tied"]
        assert (end.policy.retry, end.policy.then) == (0, Then.LOCK)
        assert f"{second}.not-tied" not in plan.terminals
    else:
        assert cinch.policy.goto == f"{second}.release-hook"
        assert not plan.steps[f"{second}.drop-loop"].enabled


@pytest.mark.parametrize(
    ("mirror", "second", "roll_deg"),
    [(False, False, -90), (True, True, -90), (False, True, 90), (True, False, 90)],
)
def test_the_needle_passes_back_on_a_mirrored_second_throw(
    mirror: bool, second: bool, roll_deg: int
) -> None:
    # The first throw passes the needle from one jaw to the other, so a second throw
    # starts with it in the other jaw: the same roll passes it back (the mirror image),
    # the stitcher turned 180 deg passes it the same way as the first (a granny knot).
    proc: Any = load_procedure(
        ROOT / "procedures" / "knot-algorithm-2.yaml",
        params={"mirror": mirror, "second": second, "stitch": False},
    )
    for name in ("slide-to-tip", "under"):
        assert math.degrees(proc.states[name].params.roll) == pytest.approx(roll_deg)
    # a second throw keeps the grasper's roll and the tail, brings the stitcher back over
    # the exit first and comes down beside the stem before the slide to its tip
    for name in ("hook-up", "grab-tail", "lift-tail"):
        assert proc.states[name].enabled is not second
    for name in ("hand-up", "clear-stem"):
        assert proc.states[name].enabled is second
    # only the mirrored second throw carries the tail over first; it keeps the hook out
    # through the cinch, as does a first throw (held loop, the default); the unmirrored
    # second throw retracts it before the cinch
    assert proc.states["cross-tail"].enabled is (second and mirror)
    assert proc.states["retract-hook"].enabled is (second and not mirror)
    assert proc.states["release-hook"].enabled is not (second and not mirror)


def test_the_second_throw_comes_down_clear_of_the_grasper_stem() -> None:
    proc: Any = load_procedure(
        ROOT / "procedures" / "knot-algorithm-2.yaml", params={"second": True, "stitch": False}
    )
    tip2 = _lifted_tip(proc)
    o1, _ = _base(proc, "stitcher")
    o2, _ = _base(proc, "grasper")
    up = (o2 - tip2) / np.linalg.norm(o2 - tip2)
    hand = proc.states["hand-up"].params
    assert hand.target == "exit_2" and hand.offset[2] >= 30e-3
    clear = proc.states["clear-stem"].params
    assert clear.relative_to == "grasper"
    rel = np.asarray(clear.target)
    # 25 mm or more off the grasper's stem (its jaws and hook span ~5 mm), above its tip
    # and the tissue, and the stitcher's shaft clears the grasper's
    assert float(np.linalg.norm(rel - (rel @ up) * up)) >= 25e-3
    assert rel @ up > 0.0 and (tip2 + rel)[2] > 5e-3
    point = tip2 + rel
    u1 = (o1 - point) / np.linalg.norm(o1 - point)
    gap = _segment_distance(point + JAW_REGION * u1, o1, tip2 + JAW_REGION * up, o2)
    assert gap > 2.0 * SHAFT_RADIUS + 1e-3


def _grasper_frame(tip: Any, o1: Any, o2: Any) -> tuple[Any, Any, Any]:
    """The grasper's shaft frame at ``tip``: along the shaft (tip to RCM), towards the
    stitcher's RCM point (orthogonal to the shaft), and sideways (shaft x towards)."""
    along = (o2 - tip) / np.linalg.norm(o2 - tip)
    towards = (o1 - tip) - ((o1 - tip) @ along) * along
    towards /= np.linalg.norm(towards)
    return along, towards, np.cross(along, towards)


def test_the_mirrored_second_throw_is_the_first_reflected_in_the_grasper_frame() -> None:
    # A square knot's second throw is the first one's mirror image. Here it is built by
    # reflecting the first throw in the grasper's frame (sideways reversed): the grasper
    # first carries the tail over so that the stitch lies on the other side of its shaft,
    # and every stitcher target relative to the grasper is reflected. The check rebuilds
    # both frames from the scene's base poses and the first throw's grab, lift and
    # back-out, not from the procedure's comments.
    first: Any = load_procedure(
        ROOT / "procedures" / "knot-algorithm-2.yaml", params={"stitch": False}
    )
    mirrored: Any = load_procedure(
        ROOT / "procedures" / "knot-algorithm-2.yaml",
        params={"stitch": False, "second": True, "mirror": True},
    )
    o1, _ = _base(first, "stitcher")
    o2, _ = _base(first, "grasper")
    points = first.scene.tissue.points
    stitch = 0.5 * (np.asarray(points["entry_2"], float) + np.asarray(points["exit_2"], float))
    # the first throw ends with the grasper backed out along its shaft (pull-through)
    tip1 = _lifted_tip(first) + np.asarray(first.states["pull-through"].params.target)
    cross = mirrored.states["cross-tail"]
    assert cross.enabled and not first.states["cross-tail"].enabled
    assert cross.params.relative_to == "grasper" and cross.params.robot == "grasper"
    tip2 = tip1 + np.asarray(cross.params.target)
    f1, f2 = _grasper_frame(tip1, o1, o2), _grasper_frame(tip2, o1, o2)
    k1 = np.array([(stitch - tip1) @ e for e in f1])
    k2 = np.array([(stitch - tip2) @ e for e in f2])
    # the stitch (the first knot) changes side and keeps its place along and across
    assert k1[2] < -5e-3 and k2[2] > 5e-3
    assert np.allclose(k2 * (1, 1, -1), k1, atol=2.5e-3)

    def frame_coords(proc: Any, state: str, tip: Any, frame: Any) -> Any:
        params = proc.states[state].params
        assert params.relative_to == "grasper"
        rel = np.asarray(params.target) + np.asarray(params.offset)
        return np.array([rel @ e for e in frame])

    # slide-to-tip: the reflection, 10 mm beyond the crossed tip on its axis
    a1 = frame_coords(first, "slide-to-tip", tip1, f1)
    a2 = frame_coords(mirrored, "slide-to-tip", tip2, f2)
    assert np.allclose(a2 * (1, 1, -1), a1, atol=0.5e-3)
    assert -12e-3 <= a2[0] <= -8e-3 and np.hypot(a2[1], a2[2]) < JAW_INNER
    # under: 10 mm beyond and 10 mm to the tail's side like the first throw's, moved 3-6 mm
    # further sideways, towards where the needle passes (its comment gives the measurement)
    b1 = frame_coords(first, "under", tip1, f1)
    b2 = frame_coords(mirrored, "under", tip2, f2)
    assert np.allclose(b2[:2], b1[:2], atol=1e-3)
    assert 3e-3 <= b2[2] - (-b1[2]) <= 6e-3
    # the loop goes the other way round the hook; the needle passes back (same roll)
    assert first.states["over-hook"].params.direction == "back-to-front"
    assert mirrored.states["over-hook"].params.direction == "front-to-back"
    assert mirrored.states["slide-to-tip"].params.roll == first.states["slide-to-tip"].params.roll
    # clear-stem: on the far side from the stitch, 20 mm or more off the stem, above the
    # crossed tip and the tissue, the stitcher's shaft clear of the grasper's
    c2 = frame_coords(mirrored, "clear-stem", tip2, f2)
    assert c2[2] * k2[2] < 0 and np.hypot(c2[1], c2[2]) >= 20e-3 and c2[0] > 0
    point = tip2 + np.asarray(mirrored.states["clear-stem"].params.target)
    assert point[2] > 5e-3
    u1 = (o1 - point) / np.linalg.norm(o1 - point)
    up = f2[0]
    gap = _segment_distance(point + JAW_REGION * u1, o1, tip2 + JAW_REGION * up, o2)
    assert gap > 2.0 * SHAFT_RADIUS + 1e-3
    # the grasper backs out along its (crossed) shaft
    back = np.asarray(mirrored.states["pull-through"].params.target)
    assert float(back @ f2[0]) == pytest.approx(6e-3, abs=0.3e-3)
    assert float(np.linalg.norm(back - (back @ f2[0]) * f2[0])) < 0.3e-3


SHIPPED_PASS_ESTIMATE_N = 0.30
"""Largest base estimate (either robot) in the mirrored ``under`` and ``pass-needle``
on the stitched start, seeds 6-19 [N] (docs/status.md)."""
FIRST_PASS_ESTIMATE_N = 1.8
"""Largest base estimate in the first throw's ``under`` and ``pass-needle`` there [N]:
the stitcher's jaws about the grasper's stem, the thread slack (0.15-0.58 N true)."""
SQUEEZED_PASS_ESTIMATE_N = 1.16
"""Smallest estimate seen while the tools squeezed the strand in the mirrored pass (the
loop 30 mm up the shaft, 6.3-7.6 N true) [N]."""


def test_the_mirrored_pass_locks_when_the_tools_squeeze_the_strand() -> None:
    """The mirrored throw's ``under`` and ``pass-needle`` carry a ``pass_tension``
    invariant that lies between what the shipped throws read and what a squeeze read; the
    first throw's bound is the scene's limit, above its contact readings."""
    from suture_engine.runtime.plan import compile_procedure

    proc = load_procedure(ROOT / "procedures" / "square-knot.yaml", params={"stitch": False})
    plan = compile_procedure(proc)
    limit = float(proc.scene.tension_limit)
    for step in ("under", "pass-needle"):
        mirrored = plan.steps[f"mirrored-knot.{step}"].invariant.max_tension_N
        assert SHIPPED_PASS_ESTIMATE_N < mirrored < SQUEEZED_PASS_ESTIMATE_N
        first = plan.steps[f"simple-knot.{step}"].invariant.max_tension_N
        assert first == pytest.approx(limit) and first > FIRST_PASS_ESTIMATE_N


TAKE_UP_TIED_MM = 5.08
"""Most travel of the mirrored ``take-up`` before its 0.1 N guard was met on the throws
that tied (stitched start, seeds 0-3, 5, 12, 14 and 16-19: 4.03-5.08 mm), from the
stitcher's joints in their traces [mm] (docs/status.md)."""
TAKE_UP_UNTIED_MM = 7.88
"""Least travel before the guard was met on throws that tied no second knot: seeds 4 and
7, whose loop slipped off the grasper's end (11.14-11.36 mm), and a perturbed run
(``benchmarks/knot_success.py`` run 0, 7.88 mm) [mm]."""
TAKE_UP_TIED_LEAST_MM = 4.03
"""Least travel before the guard was met on the throws that tied (as ``TAKE_UP_TIED_MM``)
[mm]."""
TAKE_UP_HELD_MM = 0.48
"""Travel before the guard was met on a perturbed run whose first throw had tied a
figure-eight (``benchmarks/knot_success.py --seeds 20``, run 2): the strand was taut at
once, and the cinch's guard was met all the same [mm]."""


@pytest.mark.parametrize(
    ("params", "checked"),
    [
        ({"stitch": False}, True),
        ({"stitch": False, "check_throw": False}, False),
        ({"stitch": False, "mirror": False}, False),
    ],
)
def test_the_mirrored_take_up_must_draw_taut_before_the_loop_could_have_slipped(
    params: dict[str, Any], checked: bool
) -> None:
    """With the check on, the mirrored throw's take-up is guarded within a travel that lies
    between where the tied throws' strand went taut and where the untied ones' did, and
    after a floor between where a strand held elsewhere went taut and where the tied ones'
    did; outside that window the hook is retracted and the throw ends failed (before the
    needle is passed). The first throw's take-up, an unmirrored second throw and the
    unchecked one keep the unbounded guarded move, which goes on slack."""
    from suture_engine.runtime.plan import compile_procedure

    proc: Any = load_procedure(ROOT / "procedures" / "square-knot.yaml", params=params)
    plan = compile_procedure(proc)
    first = proc.states["simple-knot"].use.states["take-up"].params
    assert first.taut_within is None and first.taut_after is None
    assert plan.steps["simple-knot.take-up"].policy.goto == "simple-knot.clear-stem"
    second = proc.states["mirrored-knot"].use.states["take-up"].params
    step = plan.steps["mirrored-knot.take-up"]
    assert step.on_done == "mirrored-knot.clear-stem"
    if checked:
        assert TAKE_UP_TIED_MM * 1e-3 < second.taut_within < TAKE_UP_UNTIED_MM * 1e-3
        assert TAKE_UP_HELD_MM * 1e-3 < second.taut_after < TAKE_UP_TIED_LEAST_MM * 1e-3
        assert second.until_tension is not None
        assert step.policy.goto == "mirrored-knot.drop-loop"
        assert plan.steps["mirrored-knot.drop-loop"].enabled
    else:
        assert second.taut_within is None and second.taut_after is None
        assert step.policy.goto == "mirrored-knot.clear-stem"


TUG_TIED_MOST_MM = 9.18
"""Most travel of a single throw's ``tug`` before its 0.3 N guard was met on throws that
tied a trefoil (stitched start, seeds 1-4: 7.67-9.18 mm; perturbed runs of
``benchmarks/knot_success.py --single``: 5.48-9.11 mm whole, 8.73-9.17 mm with friction
alone, 7.96 and 9.15 mm with base error alone), from the stitcher's joints in their traces
[mm] (docs/status.md). One tied throw went further, past the least untied one:
``TUG_TIED_OVER_MM``."""
TUG_TIED_OVER_MM = 10.74
"""Travel on a throw that tied a trefoil with base error alone (``--only base`` run 13, run
with a 30 mm bound): the groups overlap, and the bound locks this throw (a false alarm)
[mm]."""
TUG_UNTIED_LEAST_MM = 9.56
"""Least travel before the guard was met on single throws that tied nothing: with base
error alone (``--only base`` runs 5-7: 9.56-11.44 mm, which ended ``succeeded`` with the
former 11.5 mm bound) and whole perturbations (three runs: 14.18-32.45 mm) [mm]."""


@pytest.mark.parametrize(
    ("procedure", "params", "state", "tugs"),
    [
        ("knot-algorithm-2.yaml", {"stitch": False}, "tug", True),
        ("knot-algorithm-2.yaml", {"stitch": False, "tug": False}, "tug", True),
        (
            "knot-algorithm-2.yaml",
            {"stitch": False, "tug": False, "hold_loop": False},
            "tug",
            False,
        ),
        ("knot-algorithm-2.yaml", {"stitch": False, "second": True}, "tug", False),
        ("square-knot.yaml", {"hold_loop": False}, "simple-knot.tug", False),
        ("secure-knot.yaml", {}, "first-throw.tug", False),
        ("surgeons-knot.yaml", {}, "double-knot.tug", False),
    ],
)
def test_a_single_throw_is_tugged_and_must_draw_taut_soon(
    procedure: str, params: dict[str, Any], state: str, tugs: bool
) -> None:
    """A single first throw ends with a tug: the stitcher draws its end on, guarded, and
    the strand must go taut within a bound below where every throw that tied nothing went
    taut and above where all tied throws but one did (the groups overlap; that one is
    locked, on the safe side); past it the step fails and the robots lock.
    A second throw, and the first throw of a loose-layout square, secured or surgeon's
    knot (laid out for the knot as ``tighten`` leaves it), do not tug. (The held-loop
    square knot's tug has its own bound: see the held-loop layout test.)"""
    from suture_engine.runtime.plan import compile_procedure

    proc: Any = load_procedure(ROOT / "procedures" / procedure, params=params)
    plan = compile_procedure(proc)
    step = plan.steps[state]
    assert step.enabled is tugs
    if tugs:
        tug = proc.states["tug"].params
        assert tug.until_tension is not None and tug.taut_after is None
        assert TUG_TIED_MOST_MM * 1e-3 < tug.taut_within < TUG_UNTIED_LEAST_MM * 1e-3
        assert tug.taut_within < TUG_TIED_OVER_MM * 1e-3  # that tied throw is locked
        assert step.policy.retry == 0 and step.policy.then.value == "lock"
        assert step.policy.goto is None
        assert plan.steps["tighten"].on_done == "tug"


HELD_TUG_120_TIED_MOST_MM = 8.94
"""Most travel before the held-loop tug's guard was met on the 120 mm thread (the
single-throw procedure's bench, ``--set hold_loop=true``, stitched start, seeds 1-3 and
5-12 of 1-12, 2026-12-03: 6.90-8.94 mm), each throw a trefoil binding the stitch [mm]."""
HELD_TUG_120_UNTIED_MM = 14.67
"""The same on seed 4, which tied nothing; with the 140 mm thread's 28.6 mm bound it ended
``succeeded`` with no knot [mm]."""
HELD_TUG_140_TIED_MOST_MM = 28.0
"""Most travel before the held-loop tug's guard on the square knot's 140 mm thread, on
first throws that tied (22.3-28.0 mm) [mm]."""
HELD_TUG_140_UNTIED_LEAST_MM = 29.28
"""Least travel on a first throw that tied nothing there (seed 8, 2026-12-02) [mm]."""


@pytest.mark.parametrize(
    ("procedure", "throw", "tied_most", "untied_least"),
    [
        ("knot-algorithm-2.yaml", None, HELD_TUG_120_TIED_MOST_MM, HELD_TUG_120_UNTIED_MM),
        (
            "square-knot.yaml",
            "simple-knot",
            HELD_TUG_140_TIED_MOST_MM,
            HELD_TUG_140_UNTIED_LEAST_MM,
        ),
    ],
)
def test_the_held_loop_tug_bound_follows_the_thread_it_was_measured_on(
    procedure: str, throw: str | None, tied_most: float, untied_least: float
) -> None:
    """The held-loop first throw's tug bound lies between the tied and the untied throws
    measured on the thread the procedure runs with: 120 mm for the single throw on its
    own bench, 140 mm for the square knot. (One bound for both passed seed 4's untied
    single throw as tied.)"""
    from suture_engine.runtime.plan import compile_procedure

    params: dict[str, Any] = {"stitch": False, "hold_loop": True}
    proc: Any = load_procedure(ROOT / "procedures" / procedure, params=params)
    assert compile_procedure(proc).steps[f"{throw}.tug" if throw else "tug"].enabled
    sub = proc.states[throw].use if throw else proc
    bound = sub.states["tug"].params.taut_within
    assert tied_most * 1e-3 < bound < untied_least * 1e-3


@pytest.mark.slow
def test_a_first_throw_that_tied_nothing_is_caught_by_its_tug(tmp_path: Path) -> None:
    """The main job, seed 15 (2026-12-02, the held loop 33 mm up): the first throw ties
    nothing, and its tug does not draw the strand taut within 28.6 mm; the step fails and
    the robots lock (the run stops ``failed``) before the mirrored throw. The ground truth
    agrees: no knot. The true tension stays under the limit. (This test ran a perturbed
    single throw that tied nothing, `knot_success.py --single` run 5; the model's hook and
    hand-over fixes re-dealt it, and it now ties its trefoil.)"""
    from suture_engine.trace.reader import TraceReader

    summary, knot = _run_on_thread(tmp_path, "square-knot.yaml", 15, [], 220)
    assert summary["outcome"] == "failed" and summary["final_state"] == "lock"
    faults = [
        m.data
        for m in TraceReader(tmp_path / "run" / "trace.mcap").messages(["/events"])
        if m.data["kind"] == "unpredictable"
    ]
    assert faults[-1]["state"] == "autonomous/simple-knot.tug", faults
    assert (
        faults[-1]["detail"] == "skill-failure:tension 0.30 N not reached within 28.6 mm of travel"
    )
    assert knot["type"] == "unknot"
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


HELD_TUG_TIED_MOST_MM = 28.0
"""Held-loop variant: the most tug travel before the strand went taut on a first throw
that tied (one seed of each distinct run of the main job: 22.3-28.0 mm) [mm]."""
HELD_TUG_UNTIED_LEAST_MM = 29.28
"""... and the throws that tied nothing: on the stitched start they did not go taut within
40 mm (seeds 2, 12, 14); from a real stitch (seed 0, the strand laid 12 mm further, a
variant) one went taut after 31.06 mm; with the hook fix of 2026-12-02, on the stitched
start, after 29.28 mm (seed 8; seed 3's was not taut within 29.5 mm) [mm]. The tied
throws with the fix: 25.1-27.5 mm (seeds 1, 2, 4-7)."""
HELD_TAKE_UP_TIED_MM = 5.4
"""Held loop, 29 mm up (branched at the mirrored throw from one seed of each distinct
run): the mirrored take-up drew taut after 4.7-5.4 mm on the four throws that tied the
square (seeds 0, 1, 4, 8); with the needle hand-over fix, 33 mm up (the layout since),
after 4.3-4.7 mm on the throws that tied the square (seeds 1, 2, 3, 5, 7) [mm] ..."""
HELD_TAKE_UP_MISSED_MM = 8.4
"""... and after 8.4 mm or more where it missed: seed 5, whose cinch drew taut with no
second knot, and seed 13 (8.6 mm, in a branch whose window was widened to 10 mm) [mm]."""
HELD_CINCH_TIED_MOST_MM = 25.7
"""Held loop 33 mm up, with the needle hand-over fix (branched at the mirrored throw,
seeds 0-9): the mirrored cinch drew the loop taut after 22.0-25.7 mm on the throws that
tied the square (seeds 1, 2, 3, 5, 7) [mm] ..."""
HELD_CINCH_MISSED_MM = 27.8
"""... and after 27.8 mm on seed 0, whose loop had not caught the needle's end (one
trefoil, ``succeeded`` without the bound) [mm]."""
HELD_CINCH_TIED_PEAK_N = 0.28
"""The stitcher's estimate peaked at 0.28 N in the cinch that tied the square (seed 4),
under the 0.3 N guard of the loose variant [N]."""


def test_the_square_knot_and_the_single_throw_hold_the_loop_by_default() -> None:
    """The main job's square knot is tied in the held-loop layout unless told otherwise,
    and so is the single throw (since 2026-12-03: 11 of seeds 1-12 held, 3 of 1-6 loose);
    the placed and secured knot and the surgeon's knot keep the loose layout they were
    laid out for."""
    from suture_engine.runtime.plan import compile_procedure

    square: Any = load_procedure(ROOT / "procedures" / "square-knot.yaml")
    plan = compile_procedure(square)
    assert plan.steps["simple-knot.tug"].enabled
    assert square.states["mirrored-knot"].use.states["over-hook"].params.height == (
        pytest.approx(33e-3)
    )
    single: Any = load_procedure(ROOT / "procedures" / "knot-algorithm-2.yaml")
    single_plan = compile_procedure(single)
    assert single_plan.steps["release-hook"].enabled
    assert not single_plan.steps["retract-hook"].enabled
    for name, first, second in (
        ("secure-knot.yaml", "first-throw", "second-throw"),
        ("surgeons-knot.yaml", "double-knot", "mirrored-knot"),
    ):
        proc: Any = load_procedure(ROOT / "procedures" / name)
        loose = compile_procedure(proc)
        assert loose.steps[f"{first}.retract-hook"].enabled
        assert not loose.steps[f"{first}.release-hook"].enabled
        # the loose first throw's cinch is guarded (the held loop's is not)
        cinch = proc.states[first].use.states["cinch"].params
        assert cinch.until_tension == pytest.approx(0.3)
        assert proc.states[second].use.states["over-hook"].params.height == pytest.approx(25e-3)
    # the tug is a check: with the checks off (no strand to draw on the robots-only
    # backend) it is left out
    tug = square.states["simple-knot"].use.states["tug"].params
    assert tug.taut_within == pytest.approx(28.6e-3)
    unchecked: Any = load_procedure(
        ROOT / "procedures" / "square-knot.yaml", params={"check_throw": False}
    )
    assert not compile_procedure(unchecked).steps["simple-knot.tug"].enabled


@pytest.mark.parametrize("hold", [False, True])
def test_the_held_loop_layout_is_laid_out_from_its_measurements(hold: bool) -> None:
    """``hold_loop`` (the square knot's default): the first throw keeps the hook out
    through its cinch (unguarded: the strand rests on the hook) and retracts it after, then
    tugs the knot down with a bound between the tied and untied throws' travel; the
    mirrored loop lies 33 mm up the stem, its take-up window and cinch guard lie between
    what the tied and the missed throws measured. Off, the layout is the one the loose
    first knot was measured with."""
    from suture_engine.runtime.plan import compile_procedure

    proc: Any = load_procedure(
        ROOT / "procedures" / "square-knot.yaml", params={"stitch": False, "hold_loop": hold}
    )
    plan = compile_procedure(proc)
    first = proc.states["simple-knot"].use
    second = proc.states["mirrored-knot"].use
    assert plan.steps["simple-knot.retract-hook"].enabled is not hold
    assert plan.steps["simple-knot.release-hook"].enabled is hold
    assert plan.steps["simple-knot.tug"].enabled is hold
    cinch = first.states["cinch"].params
    assert (cinch.until_tension is None) is hold
    mirrored_cinch = second.states["cinch"].params
    take_up = second.states["take-up"].params
    height = second.states["over-hook"].params.height
    if hold:
        tug = first.states["tug"].params
        assert HELD_TUG_TIED_MOST_MM * 1e-3 < tug.taut_within < HELD_TUG_UNTIED_LEAST_MM * 1e-3
        assert height == pytest.approx(33e-3)
        assert HELD_TAKE_UP_TIED_MM * 1e-3 < take_up.taut_within < HELD_TAKE_UP_MISSED_MM * 1e-3
        assert mirrored_cinch.until_tension < HELD_CINCH_TIED_PEAK_N
        assert HELD_CINCH_TIED_MOST_MM * 1e-3 < mirrored_cinch.taut_within
        assert mirrored_cinch.taut_within < HELD_CINCH_MISSED_MM * 1e-3
        assert first.states["cinch"].params.taut_within is None
    else:
        assert height == pytest.approx(25e-3)
        assert take_up.taut_within == pytest.approx(6.5e-3)
        assert mirrored_cinch.until_tension == pytest.approx(0.3)
        assert mirrored_cinch.taut_within is None


@pytest.mark.slow
def test_the_held_loop_layout_ties_a_square_on_seed_7(tmp_path: Path) -> None:
    """The held loop (the default) on seed 7: the first throw ties a trefoil, the tug draws
    it down, and the mirrored throw (loop 33 mm up, 0.2 N cinch guard) ties a square that
    binds the stitch and lies square, the true tension under the limit (with the needle
    hand-over fix, run straight with the loop 29 mm up: 713 s wall with another run beside
    it, ``succeeded`` at 168.7 s simulated, 2.6 mm above the tissue, true peak 0.75 N;
    branched at 33 mm: ``succeeded``, square, 168.7 s, 0.75 N). Seed 4, which tied here
    before that fix, now ties nothing in its first throw and the tug stops it."""
    summary, knot = _run_on_thread(tmp_path, "square-knot.yaml", 7, ["stitch=false"], 220)
    assert summary["outcome"] == "succeeded"
    assert knot["type"] == "square" and knot["determinant"] == 9 and knot["v3"] == 0
    assert knot["through_tissue"] and knot["lay"] == "square" and knot["post_straight"]
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


def test_the_main_jobs_mirrored_cinch_must_go_taut_neither_too_late_nor_too_soon() -> None:
    proc = load_procedure(ROOT / "procedures" / "square-knot.yaml")
    first = proc.states["simple-knot"].use.states["cinch"].params  # type: ignore[union-attr]
    mirrored = proc.states["mirrored-knot"].use  # type: ignore[union-attr]
    cinch = mirrored.states["cinch"].params  # type: ignore[union-attr]
    assert first.taut_within is None and first.taut_after is None  # type: ignore[union-attr]
    assert cinch.taut_within == pytest.approx(0.027)  # type: ignore[union-attr]
    assert cinch.taut_after == pytest.approx(0.003)  # type: ignore[union-attr]
    # either bound missed ends the throw in drop-loop, then not-tied (outcome failed)
    assert mirrored.states["cinch"].on["failed"] == "drop-loop"  # type: ignore[union-attr]
    # without the checks (the robots alone) neither applies
    off = load_procedure(ROOT / "procedures" / "square-knot.yaml", params={"check_throw": False})
    params = off.states["mirrored-knot"].use.states["cinch"].params  # type: ignore[union-attr]
    assert params.taut_within is None and params.taut_after is None  # type: ignore[union-attr]


def test_the_mirrored_loop_height_and_pull_through_tolerance_reach_the_second_throw() -> None:
    """``held_loop_height`` and ``pull_through_tolerance`` (the damped thread's settings)
    reach the square knot's mirrored throw alone: its over-hook and its pull-through; the
    first throw keeps its 40 mm loop and its 2 mm tolerance, and the defaults stay the
    default thread's (33 mm, 2 mm)."""
    for params, height, tolerance in (
        ({}, 33e-3, 2e-3),
        ({"held_loop_height": "28 mm", "pull_through_tolerance": "3 mm"}, 28e-3, 3e-3),
    ):
        square: Any = load_procedure(ROOT / "procedures" / "square-knot.yaml", params=params)
        first, second = (square.states[s].use.states for s in ("simple-knot", "mirrored-knot"))
        assert second["over-hook"].params.height == pytest.approx(height)
        assert second["pull-through"].params.tolerance == pytest.approx(tolerance)
        assert first["over-hook"].params.height == pytest.approx(40e-3)
        assert first["pull-through"].params.tolerance == pytest.approx(2e-3)
    # without the held loop the mirrored loop lies 25 mm up, whatever the held height
    loose: Any = load_procedure(
        ROOT / "procedures" / "square-knot.yaml",
        params={"hold_loop": False, "held_loop_height": "28 mm"},
    )
    assert loose.states["mirrored-knot"].use.states["over-hook"].params.height == (
        pytest.approx(25e-3)
    )
