"""Ligation algorithm 3's procedure (thesis 4.4.3): the loop about the grasper, planned.

The loop is a full turn of the needle holder about the grasper. About a straight
stem the holder's shaft must cross the grasper's; ``wrap`` with
``shaft_clearance`` refuses that before moving. The procedure therefore bends the
grasper's universal joint and loops around the bent arm (``around_segment: tip``).
The shaft distances are checked against dense sampling and scipy's bounded
minimisation, not the skill's own closed form.
"""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from backends.pybullet.suture import SutureParams
from skills.tool_path import ik_world, tip_world
from skills.wrap import Wrap, WrapParams, segment_gap
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
SQUARE_ALG3_PROC = ROOT / "procedures" / "square-knot.yaml"


def sampled_gap(p1: Any, q1: Any, p2: Any, q2: Any, n: int = 801) -> float:
    s = np.linspace(0.0, 1.0, n)[:, None]
    a = p1 + s * (q1 - p1)
    b = p2 + s * (q2 - p2)
    return float(np.min(np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)))


def test_segment_gap_matches_a_bounded_minimisation() -> None:
    rng = np.random.default_rng(5)
    cases = [tuple(rng.normal(size=(4, 3))) for _ in range(12)]
    # parallel, collinear-overlapping and crossing segments
    cases.append((np.zeros(3), np.array((1.0, 0, 0)), np.array((0.5, 1, 0)), np.array((2, 1, 0))))
    cases.append((np.zeros(3), np.array((1.0, 0, 0)), np.array((0.5, 0, 0)), np.array((2, 0, 0))))
    cases.append(
        (
            np.array((-1.0, 0, 0)),
            np.array((1.0, 0, 0)),
            np.array((0, -1, 0.3)),
            np.array((0, 1, 0.3)),
        )
    )
    for p1, q1, p2, q2 in cases:
        best = min(
            minimize(
                lambda v, p1=p1, q1=q1, p2=p2, q2=q2: float(
                    np.linalg.norm(p1 + v[0] * (q1 - p1) - p2 - v[1] * (q2 - p2))
                ),
                x0,
                bounds=[(0.0, 1.0), (0.0, 1.0)],
                method="L-BFGS-B",
            ).fun
            for x0 in ((0.5, 0.5), (0.0, 1.0), (1.0, 0.0))
        )
        got = segment_gap(p1, q1, p2, q2)
        assert got == pytest.approx(best, abs=1e-6)
        assert got == pytest.approx(sampled_gap(p1, q1, p2, q2, n=201), abs=3e-2)


def test_states_follow_the_thesis_steps() -> None:
    proc: Any = load_procedure(PROC)
    order = []
    state = proc.initial
    while proc.states[state].on:
        order.append(state)
        state = proc.states[state].on["done"]
    assert order == [
        "register",  # with register=true only
        "stitch",
        "pick-strand",
        "cross-tail",  # mirrored second throw only
        "lower-tail",  # mirrored second throw only
        "early-clear-post",  # mirrored, with hand_up_first and calibration posts only
        "early-hand-up",  # mirrored second throw with hand_up_first only
        "lay-tail",  # mirrored second throw only
        "present",
        "bend",
        "clear-post",  # mirrored second throw on a scene with calibration posts only
        "hand-up",  # second throw only
        "loop",
        "lower-holder",  # first throw only
        "lower-holder-taut",  # second throw only, not the mirror image
        "hold-back",  # mirrored second throw only
        "point-down",
        "carry-tail",  # second throw only, not mirrored: the jaws still hold the tail
        "grab-tail",  # first throw, and the mirrored second throw
        "lift-end",  # with lift_end: two turns, and the mirrored throw with align_mirror
        "align-arm",  # two turns, and the mirrored second throw with align_mirror
        "align-jaws",  # two turns, and the mirrored second throw with align_mirror
        "draw-tail",
        "clear-jaws",  # mirrored second throw only
        "slide-off-free",  # first throw, retry_slide_off (default; taut-early: free-ease, reslide)
        "slide-off",  # the other throws, and the first without retry_slide_off
        "tighten",
    ]


@pytest.mark.parametrize("retry", [False, True])
def test_a_first_slide_off_caught_on_the_arm_is_retried_once_only_with_retry_slide_off(
    retry: bool,
) -> None:
    """retry_slide_off: the first throw's slide-off routes ``taut-early`` (the loop caught on
    the arm) to free-ease (the holder gives back some of its draw) and one reslide;
    ``not-taut`` (nothing tied) and any other failure still lock, as does the reslide's.
    Off, the same move runs as ``slide-off`` and every failure locks. The mirrored throw
    never retries this way."""
    from suture_engine.runtime.automaton import Then
    from suture_engine.runtime.run import load_plan

    _, plan = load_plan(SQUARE_ALG3_PROC, ["algorithm=3", f"retry_slide_off={str(retry).lower()}"])
    first, mirrored = "simple-knot.", "mirrored-knot."
    runs, skipped = ("slide-off-free", "slide-off") if retry else ("slide-off", "slide-off-free")
    assert plan.steps[first + runs].enabled and not plan.steps[first + skipped].enabled
    assert plan.steps[mirrored + "slide-off"].enabled
    assert not plan.steps[mirrored + "slide-off-free"].enabled
    # the same move either way, and again in the reslide: 80 mm along the holder's -x
    # (5 mm down) at 5 mm/s to 0.5 N, taut not before 24 mm nor after 74 mm of travel
    for step in ("slide-off-free", "slide-off", "reslide"):
        p = plan.steps[first + step].make_skill().params
        assert p.target == pytest.approx((-80e-3, 0.0, -5e-3)) and p.relative_to == "stitcher"
        assert (p.speed, p.until_tension) == pytest.approx((5e-3, 0.5))
        assert (p.taut_after, p.taut_within) == pytest.approx((24e-3, 74e-3))
    free = plan.steps[first + "slide-off-free"]
    assert dict(free.on_event) == {"taut-early": first + "free-ease"}
    assert free.policy.retry == 0 and free.policy.then is Then.LOCK and free.policy.goto is None
    chain, name = [], first + "free-ease"
    while name.startswith(first) and not name.endswith("tighten"):
        chain.append(name.removeprefix(first))
        assert plan.steps[name].policy.then is Then.LOCK and not plan.steps[name].on_event
        name = plan.steps[name].on_done
    assert chain == ["free-ease", "reslide"]
    assert name == first + "tighten"
    ease = plan.steps[first + "free-ease"].make_skill().params
    assert ease.target == pytest.approx((15e-3, 0.0, 5e-3)) and ease.relative_to == "stitcher"


def test_the_bent_jaws_close_on_the_tail_end() -> None:
    """grab-tail places the tool tip so that the bent jaws' centre (not the tool tip), with
    the arm pointed down (``point-down``), is at entry + (0, -tail, 3 mm): over the
    tail's end, ahead of the loop on the arm. Re-derived from scipy's rotations."""
    from skills.wrap import BENT_ARM

    proc: Any = load_procedure(PROC)
    spec = proc.scene.robots["endobot_2"]
    rot = Rotation.from_euler("xyz", spec.base.rpy)
    base = (tuple(spec.base.position), tuple(rot.as_matrix().reshape(-1)))
    grab = proc.states["grab-tail"].params
    tail = proc.params["tail"]
    entry = np.asarray(proc.scene.tissue.points[grab.target])
    tip = entry + np.asarray(grab.offset)
    q = ik_world(tip, 0.0, base)
    # the tool frame from positions: z from the RCM point through the tip, the roll's x
    # from scipy (yaw about x, pitch about y, roll about z, in the rotated base frame)
    frame = rot * Rotation.from_euler("XYZ", q[:3])
    z = frame.as_matrix()[:, 2]
    assert z == pytest.approx((tip - base[0]) / np.linalg.norm(tip - base[0]), abs=1e-9)
    arm = (frame * Rotation.from_euler("XY", proc.states["point-down"].params.angles)).apply(
        [0, 0, 1]
    )
    jaws = tip - BENT_ARM * z + BENT_ARM * arm
    assert np.linalg.norm(jaws - (entry + np.array([0.0, -tail, 3e-3]))) < 0.1e-3
    # the arm points down (the jaws are its lowest point) and along -x, away from the
    # grasper's side: backing out along +x draws the tail towards the grasper
    assert arm[2] < -0.1 and arm[0] < -0.95
    assert proc.states["tied"].outcome == "succeeded"


def _bent_jaws(proc: Any, tip: Any, angles: Any) -> tuple[Any, Any]:
    """The bent jaws' centre and the arm's direction for the grasper's tool tip at ``tip``
    (roll 0) and the universal joint at ``angles``, rebuilt with scipy's rotations."""
    from skills.wrap import BENT_ARM

    spec = proc.scene.robots["endobot_2"]
    rot = Rotation.from_euler("xyz", spec.base.rpy)
    base = (tuple(spec.base.position), tuple(rot.as_matrix().reshape(-1)))
    q = ik_world(np.asarray(tip), 0.0, base)
    frame = rot * Rotation.from_euler("XYZ", q[:3])
    z = frame.as_matrix()[:, 2]
    arm = (frame * Rotation.from_euler("XY", angles)).apply([0, 0, 1])
    return np.asarray(tip) - BENT_ARM * z + BENT_ARM * arm, arm


def test_two_turns_turn_the_arm_along_the_tail_after_the_grasp() -> None:
    """The double throw (``turns=2``): after the grasp the arm is turned to point along the
    tail towards the entry point and the jaws brought back over the tail's line, so that
    the tail leaves the jaws straight ahead of the coil; the end is then drawn back along
    the arm, the holder draws along it the other way, and the grasper tightens back along
    it. One turn keeps its layout (the new steps are left out)."""
    from suture_engine.runtime.plan import compile_procedure

    one: Any = load_procedure(PROC)
    two: Any = load_procedure(PROC, params={"turns": 2})
    one_plan, two_plan = compile_procedure(one), compile_procedure(two)
    for step in ("align-arm", "align-jaws"):
        assert two_plan.steps[step].enabled and not one_plan.steps[step].enabled
    assert one.states["draw-tail"].params.target == pytest.approx([20e-3, 0.0, 3e-3])
    assert one.states["slide-off"].params.target == pytest.approx([-80e-3, 0.0, -5e-3])
    assert one.states["tighten"].params.target == pytest.approx([25e-3, 0.0, 4e-3])
    assert one.states["tighten"].params.until_tension == pytest.approx(0.5)
    assert two.states["loop"].params.sweep == pytest.approx(2 * math.tau)

    grab = two.states["grab-tail"].params
    entry = np.asarray(two.scene.tissue.points[grab.target])
    tail = two.params["tail"]
    tip = entry + np.asarray(grab.offset)
    jaws, arm = _bent_jaws(two, tip, two.states["point-down"].params.angles)
    # at the grasp the arm is square to the tail (which lies along +y from its end)
    assert abs(arm[1]) < 0.05
    tip = tip + np.asarray(two.states["align-jaws"].params.target)
    jaws, arm = _bent_jaws(two, tip, two.states["align-arm"].params.angles)
    level = np.array([arm[0], arm[1], 0.0]) / np.hypot(arm[0], arm[1])
    assert math.degrees(math.acos(level[1])) < 4.0  # along the tail, towards the entry
    assert abs(jaws[0] - entry[0]) < 1e-3  # over the tail's line
    assert entry[1] - tail < jaws[1] < entry[1]  # between the tail's end and the entry
    assert 1e-3 < jaws[2] < 5e-3
    # drawn back along the arm; the holder draws the other way, the grasper back again
    for state, sign in (("draw-tail", -1.0), ("slide-off", 1.0), ("tighten", -1.0)):
        move = np.asarray(two.states[state].params.target)
        move = move / np.linalg.norm(move)
        assert sign * (move @ arm) > 0.95, state


def test_the_mirrored_throw_turns_the_arm_along_the_tail_to_the_first_knot() -> None:
    """The mirrored second throw with ``align_mirror``: the jaws take the tail's end where
    cross-tail laid it, across the wound, with the arm square to the tail (which runs from
    the end towards the first knot, world -y). After the grasp the arm is turned to point
    along the tail towards the knot, about 10 deg down, and the jaws are brought back to the
    end's distance from the wound, on the stitch's line. The first throw and the unmirrored
    second throw keep their layout, and so does the mirrored throw by default (the two
    steps are left out)."""
    from suture_engine.runtime.plan import compile_procedure

    second = {"second": True, "mirror": True, "stitch": False}
    mirrored: Any = load_procedure(PROC, params={**second, "align_mirror": True})
    plan = compile_procedure(mirrored)
    for params in ({}, {"second": True, "stitch": False}, second):
        other = compile_procedure(load_procedure(PROC, params=params))
        for step in ("align-arm", "align-jaws"):
            assert plan.steps[step].enabled and not other.steps[step].enabled, (params, step)

    points = mirrored.scene.tissue.points
    grab = mirrored.states["grab-tail"].params
    entry, exit_ = np.asarray(points[grab.target]), np.asarray(points["exit_2"])
    tip = entry + np.asarray(grab.offset)
    jaws0, arm = _bent_jaws(mirrored, tip, mirrored.states["point-down"].params.angles)
    # at the grasp the jaws lie across the wound, past the exit, the arm square to the
    # stitch's line (along which the tail runs back to the knot)
    assert jaws0[1] > exit_[1] + 5e-3 and abs(arm[1]) < 0.1
    tip = tip + np.asarray(mirrored.states["align-jaws"].params.target)
    jaws, arm = _bent_jaws(mirrored, tip, mirrored.states["align-arm"].params.angles)
    level = np.array([arm[0], arm[1], 0.0]) / np.hypot(arm[0], arm[1])
    assert math.degrees(math.acos(-level[1])) < 2.0  # along the tail, towards the knot
    # 5.7 deg down at the grasp's tool pose; 10.2 deg once the tool tip has moved (the
    # shaft turns about its port): down towards the pad, not into it
    assert 8.0 < math.degrees(math.asin(-arm[2])) < 12.0
    assert abs(jaws[0] - entry[0]) < 0.5e-3  # on the stitch's line
    assert abs(jaws[1] - jaws0[1]) < 1e-3  # as far out as the end was taken
    assert abs(jaws[2] - jaws0[2]) < 1e-3


def test_retract_mirror_draws_the_loop_off_along_the_turned_arm() -> None:
    """``retract_mirror``: the aligned mirrored throw's ``draw-tail`` backs the jaws out
    along the turned arm (the thesis' step 4) instead of across it, ``clear-jaws`` is left
    out (its retry is reached from it alone), and the slide-off draws the holder along
    the arm's line, beyond its end, with a floor of its own. The arm's
    direction is rebuilt with scipy's rotations (``_bent_jaws``). Without it, or
    unaligned, the throw is as before."""
    from suture_engine.runtime.plan import compile_procedure

    second = {"second": True, "mirror": True, "stitch": False, "align_mirror": True}
    retract: Any = load_procedure(PROC, params={**second, "retract_mirror": True})
    points = retract.scene.tissue.points
    grab = retract.states["grab-tail"].params
    tip = np.asarray(points[grab.target]) + np.asarray(grab.offset)
    tip = tip + np.asarray(retract.states["align-jaws"].params.target)
    _, arm = _bent_jaws(retract, tip, retract.states["align-arm"].params.angles)

    def angle_deg(a: Any, b: Any) -> float:
        a, b = np.asarray(a, float), np.asarray(b, float)
        return math.degrees(math.acos(a @ b / np.linalg.norm(a) / np.linalg.norm(b)))

    draw = retract.states["draw-tail"].params
    assert draw.relative_to == "grasper"
    assert angle_deg(draw.target, -arm) < 5.0  # back along the arm, towards its joint
    slide = retract.states["slide-off"].params
    assert slide.relative_to == "stitcher"
    assert angle_deg(slide.target, arm) < 8.0  # on along the arm's line (5.4 deg: z -5 mm)
    # its floor lies between the take-ups measured on the damped thread: squares after
    # 12.6-17.7 mm, the lost second throw after 9.0 mm (seed 1; docs/status.md)
    assert 9.0e-3 < slide.taut_after < 12.6e-3
    assert slide.until_tension == pytest.approx(1.0)
    unchecked = {**second, "retract_mirror": True, "check_throw": False}
    assert load_procedure(PROC, params=unchecked).states["slide-off"].params.taut_after is None
    plan = compile_procedure(retract)
    assert not plan.steps["clear-jaws"].enabled  # its retry is reached from it alone
    for params in (second, {**second, "align_mirror": False, "retract_mirror": True}):
        proc: Any = load_procedure(PROC, params=params)
        assert compile_procedure(proc).steps["clear-jaws"].enabled, params
        assert proc.states["draw-tail"].params.target == pytest.approx([20e-3, 0.0, 3e-3])
        assert proc.states["slide-off"].params.target == pytest.approx([-80e-3, 0.0, -5e-3])
    first: Any = load_procedure(PROC, params={"stitch": False, "retract_mirror": True})
    assert first.states["draw-tail"].params.target == pytest.approx([20e-3, 0.0, 3e-3])


def test_the_square_knot_passes_retract_mirror_to_its_mirrored_throw() -> None:
    from suture_engine.runtime.run import load_plan

    for sets, target in [
        (["algorithm=3"], (0.0, 20e-3, 3e-3)),  # the default since 2026-12-07
        (["algorithm=3", "retract_mirror=false"], (20e-3, 0.0, 3e-3)),
    ]:
        _, plan = load_plan(PROC.parent / "square-knot.yaml", sets)
        mirrored: Any = plan.steps["mirrored-knot.draw-tail"].make_skill().params
        first: Any = plan.steps["simple-knot.draw-tail"].make_skill().params
        assert mirrored.target == pytest.approx(target), sets
        assert first.target == pytest.approx((20e-3, 0.0, 3e-3)), sets


def robot_bases(scene: Any) -> dict[str, tuple[Any, Any]]:
    """Each robot's base (position, row-major rotation), from the scene's declared pose."""
    bases = {}
    for name, spec in scene.robots.items():
        rot = Rotation.from_euler("xyz", spec.base.rpy).as_matrix()
        bases[name] = (tuple(spec.base.position), tuple(rot.reshape(-1)))
    return bases


def plan_loop(sweep: float | None = None, mirror: bool = False, segment: str = "shaft") -> Wrap:
    """The ``loop`` state's wrap, planned with both tools where the earlier states leave
    them; ``segment="shaft"`` plans it about the straight stem instead of the bent arm."""
    proc: Any = load_procedure(PROC, params={"mirror": mirror, "pick_strand": True})
    scene = proc.scene
    points = scene.tissue.points
    bases = robot_bases(scene)
    pick = proc.states["pick-strand"].params
    present = proc.states["present"].params
    holder_tip = np.asarray(points[pick.target]) + np.asarray(pick.offset)
    grasper_tip = np.asarray(points[present.target]) + np.asarray(present.offset)
    qs = {
        "endobot_1": ik_world(holder_tip, 0.0, bases["endobot_1"]),
        "endobot_2": ik_world(grasper_tip, 0.0, bases["endobot_2"]),
    }
    bend = tuple(proc.states["bend"].params.angles) if segment == "tip" else (0.0, 0.0)
    tools = {
        "endobot_1": ToolState("grasper", True),
        "endobot_2": ToolState("bent-tip-grasper", bend=bend),  # type: ignore[arg-type]
    }
    obs = Observation(
        0,
        0.0,
        {n: RobotObservation(q, np.zeros(4), np.zeros(6), tools[n]) for n, q in qs.items()},
        SceneGeometry(),
    )
    ctx = SkillContext("loop", dict(proc.roles), 1e-3, obs, scene, {}, bases)
    params = proc.states["loop"].params.model_dump()
    if segment == "shaft":
        params.update(around_segment="shaft", height=None, radius=8e-3)
    if sweep is not None:
        params["sweep"] = sweep
    skill = Wrap(WrapParams.model_validate(params))
    skill.start(ctx)
    skill.bases = bases  # type: ignore[attr-defined]
    skill.qs = qs  # type: ignore[attr-defined]
    return skill


def independent_gap(skill: Any) -> float:
    """Smallest shaft-to-shaft distance along the planned paths, by dense sampling."""
    o1 = np.asarray(skill.bases["endobot_1"][0])
    o2 = np.asarray(skill.bases["endobot_2"][0])
    t2 = tip_world(skill.qs["endobot_2"], skill.bases["endobot_2"])
    return min(
        sampled_gap(o1, tip_world(q, skill.bases["endobot_1"]), o2, t2, n=151)
        for path in skill._paths
        for q in path.table[::40]
    )


@pytest.mark.parametrize("mirror", [False, True])
def test_a_full_turn_about_the_straight_stem_is_refused_before_moving(mirror: bool) -> None:
    skill = plan_loop(mirror=mirror)
    # one turn, either way round
    assert skill.sweep == pytest.approx(2 * math.pi)
    assert skill.shaft_gap < 1e-3
    assert independent_gap(skill) < 3e-3  # sampled: within its 1 mm spacing
    obs_q = skill.qs["endobot_1"]  # type: ignore[attr-defined]
    tools = {"endobot_1": ToolState("grasper", True), "endobot_2": ToolState("bent-tip-grasper")}
    obs = Observation(
        0,
        0.0,
        {
            n: RobotObservation(q, np.zeros(4), np.zeros(6), tools[n])
            for n, q in skill.qs.items()  # type: ignore[attr-defined]
        },
        SceneGeometry(),
    )
    result = skill.step(None, obs)
    assert result.status is SkillStatus.FAILURE
    assert "would cross the other shaft" in result.message
    assert np.allclose(result.command.robots["endobot_1"].q, obs_q)  # held, not moved


def test_the_half_turn_keeps_the_shafts_apart() -> None:
    # the half turn (algorithm 2's loop over the hook) stays on the holder's side
    skill = plan_loop(sweep=math.pi)
    assert skill.shaft_gap > 5e-3
    assert independent_gap(skill) == pytest.approx(skill.shaft_gap, abs=1.5e-3)
    assert skill._failure == ""


SPRINGING_OPTIONS = {
    "thread_damping": SutureParams.linear_damping,
    "thread_weight": SutureParams.real_mass_per_length,
}
"""The thread model algorithm 3's runs before 2026-12-07 were made on, as backend options
[1/s, kg/m]: the simulated thread's defaults (0.5 /s keeping 0.1 g/m), which a scene
without ``suture.damping`` and ``suture.weight`` gets; its benches now declare the
damped thread. The slow runs below that check those throws keep it."""
SPRINGING = tuple(
    arg
    for flag, option in (
        ("--thread-damping", "thread_damping"),
        ("--thread-weight", "thread_weight"),
    )
    for arg in (flag, repr(SPRINGING_OPTIONS[option]))
)
""":data:`SPRINGING_OPTIONS` as ``suture run`` flags (bare numbers are SI)."""
EARLIER = ("register=false", "lift_end=false", "lower_end=true", "retract_mirror=false")
"""Algorithm 3's square-knot defaults before 2026-12-07."""


def run_cli(tmp_path: Path, *args: str) -> tuple[dict[str, Any], Any]:
    """Run ``suture run`` in a subprocess; (summary, trace reader)."""
    import json
    import subprocess
    import sys

    from suture_engine.trace.reader import TraceReader

    out = tmp_path / "run"
    res = subprocess.run(
        [
            sys.executable,
            "-c",
            "from suture_engine.cli import main; main()",
            "run",
            *args,
            "--out",
            str(out),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=1200,
        check=False,
    )
    assert res.returncode in (0, 1), res.stdout + res.stderr
    summary = json.loads((out / "summary.json").read_text())
    return summary, TraceReader(out / "trace.mcap")


@pytest.mark.slow
def test_algorithm_3_ties_a_simple_knot_on_pybullet(tmp_path: Path) -> None:
    """The stitched start, seed 1: the grasper bends (measured by its encoders, in the
    trace), the holder loops the strand around the bent arm, the bent jaws take the
    tail's end, the holder draws the loop off the arm over the closed jaws, and the
    thread's true centerline then holds a trefoil (one throw, 4.4.3) that binds the stitch
    (the thread still runs through the tissue), with the true tension under 3 N."""
    summary, trace = run_cli(
        tmp_path,
        str(PROC),
        "--set",
        "stitch=false",
        "--seed",
        "1",
        "--backend",
        "pybullet-surgical-stitched",
        "--max-time",
        "100",
    )
    events = [m.data for m in trace.messages(["/events"])]
    done = [e["detail"] for e in events if e["kind"] == "planned"]
    # the first slide-off runs as slide-off-free (retry_slide_off, the default)
    for step in ("bend", "loop", "grab-tail", "slide-off-free", "tighten"):
        assert f"done:{step}" in done
    bends = [m.data["bend"] for m in trace.messages(["/tool_state/endobot_2"])]
    assert min(b[1] for b in bends) == pytest.approx(-math.pi / 2, abs=math.radians(1.0))
    assert summary["outcome"] == "succeeded"
    assert summary["knot"]["type"] == "trefoil"
    assert summary["knot"]["through_tissue"] is True
    assert summary["metrics"]["stitches"]["count"] == 1
    assert summary["metrics"]["peak_true_tension_N"] < 3.0


def _arm_frame(proc: Any) -> dict[str, Any]:
    """The bent arm where ``present`` and ``bend`` leave it, and the loop's frame about it,
    rebuilt from the scene with scipy's rotations: the joint U, the arm's direction, the
    loop's centre (``height`` along the arm), ``over`` (towards the holder's RCM point,
    square to the arm) and ``front`` (arm x over), and both RCM points."""
    from skills.wrap import BENT_ARM

    points = proc.scene.tissue.points
    spec2 = proc.scene.robots["endobot_2"]
    rot2 = Rotation.from_euler("xyz", spec2.base.rpy)
    base2 = (tuple(spec2.base.position), tuple(rot2.as_matrix().reshape(-1)))
    present = proc.states["present"].params
    tip = np.asarray(points[present.target]) + np.asarray(present.offset)
    q = ik_world(tip, 0.0, base2)
    frame = rot2 * Rotation.from_euler("XYZ", q[:3])
    z = frame.as_matrix()[:, 2]
    arm = (frame * Rotation.from_euler("XY", proc.states["bend"].params.angles)).apply([0, 0, 1])
    joint = tip - BENT_ARM * z
    centre = joint + proc.states["loop"].params.height * arm
    holder_rcm = np.asarray(proc.scene.robots["endobot_1"].base.position)
    over = holder_rcm - centre
    over -= (over @ arm) * arm
    over /= np.linalg.norm(over)
    return {
        "joint": joint,
        "arm": arm,
        "centre": centre,
        "over": over,
        "front": np.cross(arm, over),
        "holder_rcm": holder_rcm,
        "grasper_rcm": np.asarray(spec2.base.position),
    }


def _grasper_frame(proc: Any, state: str) -> tuple[Any, Any]:
    """The grasper's tool tip where ``state`` puts it, and its frame there: along its shaft
    (towards its RCM point), towards the holder's RCM point (square to the shaft), and
    sideways (their cross product)."""
    points = proc.scene.tissue.points
    params = proc.states[state].params
    tip = np.asarray(points[params.target]) + np.asarray(params.offset)
    shaft = np.asarray(proc.scene.robots["endobot_2"].base.position) - tip
    shaft /= np.linalg.norm(shaft)
    towards = np.asarray(proc.scene.robots["endobot_1"].base.position) - tip
    towards -= (towards @ shaft) * shaft
    towards /= np.linalg.norm(towards)
    return tip, np.array([shaft, towards, np.cross(shaft, towards)])


def test_the_mirrored_second_throw_is_the_first_reflected_in_the_grasper_frame() -> None:
    """A square knot's second throw (algorithm 3) is the first one's mirror image: every
    point of the first throw, taken in the grasper's frame at its ``present`` pose, is
    reflected (the sideways component reversed) into the frame of the mirrored throw's
    ``present`` pose. That pose carries the arm over the first knot, so that the knot
    lies behind and below the loop (the first throw's strand comes from in front and
    below). Rebuilt from the scene: the holder's start (the stitched start's pull, 40 mm
    over the exit), where lower-holder leaves it, and where the jaws take the tail."""
    first: Any = load_procedure(PROC, params={"stitch": False})
    granny: Any = load_procedure(PROC, params={"second": True, "stitch": False})
    mirrored: Any = load_procedure(PROC, params={"mirror": True, "second": True, "stitch": False})
    points = first.scene.tissue.points
    tip1, frame1 = _grasper_frame(first, "present")
    tip2, frame2 = _grasper_frame(mirrored, "present")

    def reflected(point: Any) -> Any:
        c = frame1 @ (point - tip1)
        return tip2 + frame2.T @ (c * (1.0, 1.0, -1.0))

    def target(proc: Any, state: str) -> Any:
        params = proc.states[state].params
        return np.asarray(points[params.target]) + np.asarray(params.offset)

    f1 = _arm_frame(first)
    start = np.asarray(points[first.params["exit"]]) + np.array([0.0, 0.0, 40e-3])
    lowered = (
        f1["centre"]
        + first.states["loop"].params.radius * f1["front"]
        + np.asarray(first.states["lower-holder"].params.target)
    )
    pairs = (("hand-up", start), ("hold-back", lowered))
    for state, point in pairs:
        assert np.linalg.norm(target(mirrored, state) - reflected(point)) < 0.1e-3, state
    # where the tail's end is laid and taken again (grab-tail): the first throw's
    # grab-tail reflected, then 10 mm further from the knot (along +y, so that the tail
    # is laid straight) and as high as puts the bent jaws 3 mm over the pad, as in the
    # first throw (their centre from scipy's rotations, as above); carried across 25 mm
    # over the reflected place first (not through the first knot)
    from skills.wrap import BENT_ARM

    place = reflected(target(first, "grab-tail")) - np.array([0.0, 0.0, 4e-3])
    above = place + np.array([0.0, 0.0, 25e-3])
    assert np.allclose(target(mirrored, "cross-tail"), above, atol=0.1e-3)
    grab = target(mirrored, "grab-tail")
    assert np.allclose(grab[:2], place[:2] + np.array([0.0, 10e-3]), atol=0.1e-3)
    assert abs(grab[2] - place[2]) < 0.5e-3
    assert np.allclose(target(mirrored, "lower-tail"), grab)
    spec = mirrored.scene.robots["endobot_2"]
    rot = Rotation.from_euler("xyz", spec.base.rpy)
    base = (tuple(spec.base.position), tuple(rot.as_matrix().reshape(-1)))
    q = ik_world(grab, 0.0, base)
    frame = rot * Rotation.from_euler("XYZ", q[:3])
    z = frame.as_matrix()[:, 2]
    arm = (frame * Rotation.from_euler("XY", mirrored.states["point-down"].params.angles)).apply(
        [0, 0, 1]
    )
    jaws = grab - BENT_ARM * z + BENT_ARM * arm
    assert jaws[2] == pytest.approx(3e-3, abs=0.3e-3)
    # across the wound: beyond the exit, on the other side from the entry's tail
    assert jaws[1] > np.asarray(points["exit_2"])[1] > 0.0 > np.asarray(points["entry_2"])[1]
    # the first throw's points lie well to one side of the grasper's frame
    assert (frame1 @ (start - tip1))[2] < -20e-3 and (frame1 @ (lowered - tip1))[2] < -5e-3
    # the stitch lies in front of the first throw's loop; the first knot (tied round the
    # tail, on the entry's side: measured at entry + (0, -3, 3) mm, seed 1) behind the
    # mirrored one's, below it, 20-30 mm from its centre
    f2 = _arm_frame(mirrored)
    assert (np.asarray(points["knot_2"]) - f1["centre"]) @ f1["front"] > 20e-3
    rel = np.asarray(points["entry_2"]) + np.array([0.0, -3e-3, 3e-3]) - f2["centre"]
    assert rel @ f2["front"] < 0 and rel @ f2["over"] < -15e-3
    assert 20e-3 < np.linalg.norm(rel) < 30e-3
    # the loop the other way, one turn; the second throw without the mirror is the first
    assert mirrored.states["loop"].params.direction == "back-to-front"
    assert granny.states["loop"].params.direction == "front-to-back"
    assert np.allclose(target(granny, "present"), target(first, "present"))
    assert np.allclose(target(granny, "carry-tail"), target(first, "grab-tail"))
    for name in ("cross-tail", "lower-tail", "lay-tail", "hold-back", "clear-jaws", "grab-tail"):
        assert mirrored.states[name].enabled and not granny.states[name].enabled, name
    assert granny.states["carry-tail"].enabled and not mirrored.states["carry-tail"].enabled
    assert not mirrored.states["lower-holder-taut"].enabled
    assert granny.states["lower-holder-taut"].enabled


def test_the_mirrored_loop_keeps_the_shafts_apart() -> None:
    """The mirrored loop, planned from the crossed present pose and the reflected
    hand-up: the shafts stay 5 mm apart (sampled, not the skill's own figure)."""
    proc: Any = load_procedure(PROC, params={"mirror": True, "second": True, "stitch": False})
    scene = proc.scene
    points = scene.tissue.points
    bases = robot_bases(scene)
    hand = proc.states["hand-up"].params
    present = proc.states["present"].params
    qs = {
        "endobot_1": ik_world(
            np.asarray(points[hand.target]) + np.asarray(hand.offset), 0.0, bases["endobot_1"]
        ),
        "endobot_2": ik_world(
            np.asarray(points[present.target]) + np.asarray(present.offset),
            0.0,
            bases["endobot_2"],
        ),
    }
    tools = {
        "endobot_1": ToolState("grasper", True),
        "endobot_2": ToolState(
            "bent-tip-grasper",
            bend=tuple(proc.states["bend"].params.angles),  # type: ignore[arg-type]
        ),
    }
    obs = Observation(
        0,
        0.0,
        {n: RobotObservation(q, np.zeros(4), np.zeros(6), tools[n]) for n, q in qs.items()},
        SceneGeometry(),
    )
    ctx = SkillContext("loop", dict(proc.roles), 1e-3, obs, scene, {}, bases)
    skill = Wrap(WrapParams.model_validate(proc.states["loop"].params.model_dump()))
    skill.start(ctx)
    assert skill._failure == ""
    o1 = np.asarray(bases["endobot_1"][0])
    f = _arm_frame(proc)
    from skills.wrap import BENT_JAW_END

    arm_end = f["joint"] + BENT_JAW_END * f["arm"]
    gap = min(
        min(
            sampled_gap(o1, tip_world(q, bases["endobot_1"]), f["grasper_rcm"], f["joint"], n=151),
            sampled_gap(o1, tip_world(q, bases["endobot_1"]), f["joint"], arm_end, n=151),
        )
        for path in skill._paths
        for q in path.table[::20]
    )
    assert gap > 5e-3


# The holder's tool tip where the first throw leaves it, at the mirrored hand-up's first tick
# (world, from its joints in the traces of knot_success's registered runs 0 and 5, square
# knot, algorithm 3): the ends of the range the eight runs 0-7 span.
FIRST_THROW_END_MM = ((-54.0, -17.2, 1.4), (-68.5, -17.9, 2.4))


def _post_clearance(proc: Any, points_mm: list[Any]) -> float:
    """Smallest clearance [m] between the holder's shaft and the stitcher's near post over
    min-jerk moves through ``points_mm`` (world, as move-to plans them: straight in the
    joints), beyond the touch: the shaft's axis (tip to its RCM point) against the post's
    axis, less the post's radius and the distance at which the simulated shaft's axis
    touches a post (``register-bases.yaml``'s ``shaft_radius``, measured by its touches);
    sampled, not a skill's own figure."""
    touch = load_procedure(ROOT / "procedures" / "register-bases.yaml").states["stitcher"]
    bases = robot_bases(proc.scene)
    base = bases["endobot_1"]
    o1 = np.asarray(base[0])
    post = proc.scene.posts["stitcher_near"]
    bottom = np.asarray(post.position, dtype=float)
    top = bottom + np.array([0.0, 0.0, post.height])
    qs = [ik_world(np.asarray(pt) * 1e-3, 0.0, base) for pt in points_mm]
    gap = min(
        sampled_gap(o1, tip_world(a + s * (b - a), base), bottom, top, n=201)
        for a, b in itertools.pairwise(qs)
        for s in np.linspace(0.0, 1.0, 101)
    )
    return gap - post.radius - touch.params.shaft_radius


def test_with_registration_the_mirrored_holder_goes_round_the_near_post() -> None:
    """With registration (the scene's calibration posts), the square knot's mirrored
    throw (algorithm 3) sends the holder through ``clear-post`` before hand-up: the
    straight move from where the first throw leaves it swept its shaft into the
    stitcher's near post (registered runs 5 and 7 locked there at 4.5 N on the holder's
    base estimate); the move through clear-post's point keeps it more than 2.5 mm clear.
    Without the posts, and on the first throw, the step is left out."""
    from suture_engine.runtime.plan import compile_procedure

    square = ROOT / "procedures" / "square-knot.yaml"
    proc: Any = load_procedure(
        square, params={"algorithm": 3, "register": True, "remove_posts": False}
    )
    steps = compile_procedure(proc).steps
    assert steps["mirrored-knot.clear-post"].enabled
    assert not steps["simple-knot.clear-post"].enabled
    plain = compile_procedure(load_procedure(square, params={"algorithm": 3})).steps
    assert not plain["mirrored-knot.clear-post"].enabled
    # with the posts taken away after the registration (algorithm 3's default once it
    # registers) the holder goes straight
    for params in ({"algorithm": 3, "register": True, "remove_posts": True},
                   {"algorithm": 3, "register": True}):  # fmt: skip
        lifted = compile_procedure(load_procedure(square, params=params)).steps
        assert not lifted["mirrored-knot.clear-post"].enabled, params
        assert lifted["register.remove-posts"].enabled, params
    # algorithm 2 keeps the jig by default
    kept = compile_procedure(load_procedure(square, params={"algorithm": 2, "register": True}))
    assert not kept.steps["register.remove-posts"].enabled
    assert not steps["register.remove-posts"].enabled
    mirrored = proc.states["mirrored-knot"].use
    points = proc.scene.tissue.points

    def place(state: str) -> Any:
        prm = mirrored.states[state].params
        return (np.asarray(points[prm.target]) + np.asarray(prm.offset)) * 1e3

    hand, via = place("hand-up"), place("clear-post")
    for start in FIRST_THROW_END_MM:
        assert _post_clearance(proc, [start, hand]) < 0.5e-3, start
        assert _post_clearance(proc, [start, via, hand]) > 2.5e-3, start


def test_hand_up_first_moves_the_mirrored_holder_while_the_jaws_still_hold_the_tail() -> None:
    """``hand_up_first``: the mirrored throw's holder goes to hand-up's place (through
    clear-post's, with the posts) between lower-tail and lay-tail, while the grasper still
    holds the tail's end, and not again after bend; the moves are the same ones. Off (the
    default), and on the first throw, the plan is unchanged."""
    from suture_engine.runtime.run import load_plan

    square = ROOT / "procedures" / "square-knot.yaml"
    posts = ["algorithm=3", "register=true", "remove_posts=false"]

    def mirrored(sets: list[str]) -> dict[str, Any]:
        _, plan = load_plan(square, sets)
        return {
            name.removeprefix("mirrored-knot."): step.make_skill().params
            for name, step in plan.steps.items()
            if step.enabled and name.startswith("mirrored-knot.")
        }

    before, after = mirrored(posts), mirrored([*posts, "hand_up_first=true"])
    order = list(after)
    assert order.index("lower-tail") < order.index("early-clear-post")
    assert order.index("early-clear-post") < order.index("early-hand-up") < order.index("lay-tail")
    assert "hand-up" not in after and "clear-post" not in after
    assert "early-hand-up" not in before and "early-clear-post" not in before
    assert after["early-hand-up"] == before["hand-up"]
    assert after["early-clear-post"] == before["clear-post"]
    # the jaws hold the tail through the holder's moves: nothing opens them before lay-tail
    between = order[order.index("lower-tail") + 1 : order.index("lay-tail")]
    assert all(after[name].robot == "stitcher" for name in between), between
    lifted = mirrored(["algorithm=3", "register=true", "hand_up_first=true"])
    assert "early-clear-post" not in lifted and "early-hand-up" in lifted
    _, first = load_plan(square, ["algorithm=3", "hand_up_first=true"])
    assert not first.steps["simple-knot.early-hand-up"].enabled
    assert first.steps["simple-knot.hand-up"].enabled is False  # a first throw has none


def test_reload_cuts_the_thread_after_registration_and_loads_one_where_the_start_does() -> None:
    """``reload`` (with ``register``): once the bases are registered the start's thread is
    cut, the stitcher (algorithm 3: the needle holder) goes where the stitched start puts
    it (``STITCHED_PULL`` over the exit, roll 0), and a thread is loaded for the same
    stitch. Without ``register``, or by default, the three steps are left out."""
    from backends.pybullet.scene import STITCHED_PULL
    from suture_engine.runtime.plan import compile_procedure

    square = ROOT / "procedures" / "square-knot.yaml"
    names = ("reload-cut", "reload-over", "reload-load")
    for params, on in (
        ({"algorithm": 3, "register": True, "reload": True}, True),
        ({"algorithm": 2, "register": True, "reload": True}, True),
        ({"algorithm": 3, "register": False, "reload": True}, False),
        ({"algorithm": 3, "reload": True}, True),  # algorithm 3 registers by default
        ({"algorithm": 3, "register": True}, False),
        ({}, False),
    ):
        steps = compile_procedure(load_procedure(square, params=params)).steps
        assert [steps[n].enabled for n in names] == [on] * 3, params
    proc: Any = load_procedure(square, params={"algorithm": 3, "register": True, "reload": True})
    over = proc.states["reload-over"].params
    load = proc.states["reload-load"].params
    assert (over.target, load.entry, load.exit) == ("exit_2", "entry_2", "exit_2")
    np.testing.assert_allclose(over.offset, [0.0, 0.0, STITCHED_PULL])
    assert over.roll == 0.0
    order = [proc.states[n].on["done"] for n in ("register", *names)]
    assert order == [*names, "simple-knot"]
    # reload_over=false: the thread is loaded where the registration left the stitcher
    steps = compile_procedure(
        load_procedure(square, params={"register": True, "reload": True, "reload_over": False})
    ).steps
    assert [steps[n].enabled for n in names] == [True, False, True]
    # the skipped move completes at once (runtime.plan), so the cut leads on to the load
    assert [steps[n].on_done for n in names[:2]] == ["reload-over", "reload-load"]


SLIDE_OFF_TIED_LEAST_MM = 29.7
"""Least travel of the first throw's ``slide-off`` before its 0.5 N guard was met on the
throws that tied a trefoil (one turn, stitched start: seeds 1-3, 66.19-66.29 mm; the
perturbed runs of ``benchmarks/knot_success.py --single --seeds 20`` that tied,
47.48-71.07 mm, and run 12, 29.7 mm, which with the check off ended ``succeeded`` with a
trefoil binding the stitch), from the holder's joints in their traces [mm]
(docs/status.md)."""
SLIDE_OFF_TIED_MOST_MM = 71.07
"""Most travel of the first throw's ``slide-off`` before its guard on the throws that tied a
trefoil (the perturbed runs of ``knot_success --single --seeds 20``: 47.48-71.07 mm;
unperturbed seeds 1-3: 66.19-66.29 mm; registered square-knot runs 0-7: 61.5-65.9 mm) [mm]."""
SLIDE_OFF_SLIPPED_LEAST_MM = 76.5
"""Least such travel on a throw that tied nothing (registered square-knot run 5: 76.5 mm,
after which every later check passed and the run ended ``succeeded`` with no knot; the
perturbed runs 0, 3, 4, 6, 10 and 19 did not draw taut within the 80 mm move) [mm]."""
SLIDE_OFF_GRIPPED_MM = 18.9
"""Most travel before the guard was met on throws that must not pass: two turns round the
arm (seeds 1 and 2: 4.82 and 4.80 mm at the 0.5 N guard; seed 1 at 1.5 and 2.5 N: 7.10 and
8.72 mm), no knot; perturbed run 18 (16.8 mm), which with the check off ended
``succeeded`` with no knot; and perturbed run 9 (18.9 mm), which with the check off locked
later [mm]."""
MIRRORED_SLIDE_OFF_STAYED_MOST_MM = 10.5
"""Most tool-tip travel of the mirrored slide-off before its guard (1.5 N) was met where
the loop had not come off the arm by then, since ``clear-jaws`` swings the strand across
the arm's end (seeds 0-9, 2026-12-03: 7-11 mm; 10.5 mm on seed 4, which tied the first
trefoil alone, and ended ``succeeded`` with it at a 5 mm floor) [mm]."""
MIRRORED_SLIDE_OFF_CAME_OFF_LEAST_MM = 22.4
"""Least tool-tip travel before that guard where the loop came off the arm in the
slide-off (seeds 2 and 3, squares: 22.4 mm on seed 2) [mm]."""
ALIGNED_MISSED_MOST_MM = 3.6
"""With the arm turned along the tail (``align_mirror``, the slide-off at 3 mm/s to 1 N):
most tool-tip travel of the mirrored slide-off before its guard where the loop stayed on
the arm and no second knot formed (perturbed runs of ``knot_success --seeds 20``,
2026-12-04: runs 8 and 5, 1.2 and 2.7 mm; with registration first, run 6, 3.6 mm) [mm]."""
ALIGNED_SQUARE_LEAST_MM = 4.5
"""Least such travel where the thread held the square (perturbed runs 1, 9, 16, 15, 13:
6.9-21.4 mm; with registration first, runs 0, 3, 4: 11.1-16.6 mm, and run 1, 4.5 mm;
unperturbed seeds 0-9: 9.3-19.6 mm) [mm]."""

ALIGNED_CLEAR_SQUARE_MOST_N = 1.12
"""With ``align_mirror``: the largest base estimate (either robot) in the mirrored
``clear-jaws`` where the square followed (registered run 3 of ``knot_success``'s draws:
holder 0.70 N, grasper 1.12 N; the other squares, perturbed runs 1, 9, 13, 15, 16 and
registered runs 0, 1, 4: at most 0.54 N; unperturbed seeds 1, 2, 8: at most 0.22 N). One
registered run since then held a square when the 1.4 N bound locked it (run 6 with the
first way round the post: holder 1.32 N, grasper 1.41 N; docs/status.md) [N]."""
ALIGNED_CLEAR_CAUGHT_LEAST_N = 2.47
"""The least, over the throws whose loop caught on the arm in ``clear-jaws`` (perturbed
runs 5 and 8, registered run 6: the strand taut before the slide-off, which then missed,
run 6 at 8.15 N true), of the largest estimate either robot read there (grasper 2.72,
2.65, 2.47 N; holder 1.81, 1.92, 1.58 N) [N]."""


@pytest.mark.parametrize("align", [True, False])
def test_the_turned_throws_clear_jaws_locks_once_the_loop_catches_on_the_arm(align: bool) -> None:
    """With the arm turned along the tail, the mirrored ``clear-jaws`` is bounded between
    the estimates it read where the square followed and where the loop caught on the arm
    (then the slide-off started on a taut strand and pinched it); without the turn it
    keeps the throw's ``max_tension``."""
    from suture_engine.runtime.plan import compile_procedure

    params = {"algorithm": 3, "align_mirror": align, "retract_mirror": False}
    proc: Any = load_procedure(ROOT / "procedures" / "square-knot.yaml", params=params)
    step = compile_procedure(proc).steps["mirrored-knot.clear-jaws"]
    assert step.enabled
    bound = step.invariant.max_tension_N
    if align:
        assert ALIGNED_CLEAR_SQUARE_MOST_N < bound < ALIGNED_CLEAR_CAUGHT_LEAST_N
    else:
        assert bound == proc.states["mirrored-knot"].use.params["max_tension"]


@pytest.mark.parametrize("align", [True, False])
def test_a_loop_caught_in_clear_jaws_is_retried_once_with_the_throws_own_moves(
    align: bool,
) -> None:
    """A catch in the mirrored ``clear-jaws`` (its bound crossed) leads, once, to a retry:
    the holder back to ``hold-back``'s place, the arm forward by ``draw-tail``'s own move
    undone, then ``draw-tail`` and ``clear-jaws`` again with their own targets, speeds and
    bound (the moves whose checks were measured), and on to ``slide-off``. A second catch
    locks the robots. The first throw and the unmirrored second throw have no retry."""
    from suture_engine.runtime.automaton import Then
    from suture_engine.runtime.plan import compile_procedure

    params = {"algorithm": 3, "align_mirror": align, "retract_mirror": False}
    proc: Any = load_procedure(ROOT / "procedures" / "square-knot.yaml", params=params)
    steps = compile_procedure(proc).steps
    sub = proc.states["mirrored-knot"].use.states
    chain = ["slacken", "ease-arm", "redraw-tail", "reclear-jaws"]
    caught = steps["mirrored-knot.clear-jaws"].policy
    assert caught.retry == 0 and caught.goto == "mirrored-knot.slacken"
    for a, b in itertools.pairwise(chain):
        assert steps[f"mirrored-knot.{a}"].on_done == f"mirrored-knot.{b}"
        assert steps[f"mirrored-knot.{a}"].enabled
    again = steps["mirrored-knot.reclear-jaws"]
    assert again.on_done == "mirrored-knot.slide-off"
    assert again.policy.goto is None and again.policy.retry == 0
    assert again.policy.then is Then.LOCK
    bound = steps["mirrored-knot.clear-jaws"].invariant.max_tension_N
    assert again.invariant.max_tension_N == bound
    # the throw's own moves, with nothing changed
    assert sub["reclear-jaws"].params == sub["clear-jaws"].params
    assert sub["redraw-tail"].params == sub["draw-tail"].params
    hold, back = sub["hold-back"].params, sub["slacken"].params
    assert (back.target, back.offset, back.robot) == (hold.target, hold.offset, hold.robot)
    assert back.until_tension is None  # all the way back, whatever the strand reads
    ease, draw = sub["ease-arm"].params, sub["draw-tail"].params
    assert ease.relative_to == draw.relative_to == "grasper"
    assert np.allclose(np.asarray(draw.target), [20e-3, 0.0, 3e-3])  # one turn's draw
    assert np.allclose(np.asarray(ease.target), -np.asarray(draw.target))
    # no retry where there is no mirrored clear-jaws
    first: Any = load_procedure(PROC, params={"stitch": False})
    granny: Any = load_procedure(PROC, params={"second": True, "stitch": False})
    for proc_ in (first, granny):
        assert not any(proc_.states[name].enabled for name in chain)


@pytest.mark.parametrize(
    ("procedure", "params", "checked"),
    [
        ("knot-algorithm-3.yaml", {"stitch": False}, True),
        ("knot-algorithm-3.yaml", {"stitch": False, "check_throw": False}, False),
        ("square-knot.yaml", {"algorithm": 3, "retract_mirror": False}, True),
        ("square-knot.yaml", {"algorithm": 3, "align_mirror": False}, True),
        ("square-knot.yaml", {"algorithm": 3, "check_throw": False}, False),
    ],
)
def test_the_slide_off_must_not_draw_taut_while_the_loop_grips_the_arm(
    procedure: str, params: dict[str, Any], checked: bool
) -> None:
    """With the check on, the first throw's slide-off is guarded after a floor that lies
    between where the strand went taut with the loops still on the arm and where it went
    taut on the throws that tied, and within a bound between where it went taut on the
    throws that tied and on one that slipped off with nothing tied; a guard met before
    the floor, or none within the bound, fails the step, and its policy locks the robots
    (no retry: the loop is still on the arm). The mirrored second throw's floor lies
    above where a loop that gripped the arm went taut and below where every swept throw
    did; with the arm turned along the tail (``align_mirror``, the square
    knot's default) its own floor lies above where a throw that missed went taut and below
    where the squares did (an unmirrored second throw is not checked).
    ``square-knot.yaml`` passes its ``check_throw`` to both throws."""
    from suture_engine.runtime.plan import compile_procedure

    proc: Any = load_procedure(ROOT / "procedures" / procedure, params=params)
    plan = compile_procedure(proc)
    if procedure == "square-knot.yaml":
        first = proc.states["simple-knot"].use.states["slide-off"].params
        second = proc.states["mirrored-knot"].use.states["slide-off"].params
        assert second.taut_within is None
        if checked and plan.steps["mirrored-knot.align-arm"].enabled:  # the turned throw
            floor = second.taut_after
            assert ALIGNED_MISSED_MOST_MM * 1e-3 < floor < ALIGNED_SQUARE_LEAST_MM * 1e-3
        elif checked:
            floor = second.taut_after
            assert MIRRORED_SLIDE_OFF_STAYED_MOST_MM * 1e-3 < floor
            assert floor < MIRRORED_SLIDE_OFF_CAME_OFF_LEAST_MM * 1e-3
        else:
            assert second.taut_after is None
        step = plan.steps["simple-knot.slide-off"]
    else:
        first = proc.states["slide-off"].params
        step = plan.steps["slide-off"]
    assert first.until_tension is not None
    if checked:
        assert SLIDE_OFF_GRIPPED_MM * 1e-3 < first.taut_after < SLIDE_OFF_TIED_LEAST_MM * 1e-3
        assert SLIDE_OFF_TIED_MOST_MM * 1e-3 < first.taut_within
        assert first.taut_within < SLIDE_OFF_SLIPPED_LEAST_MM * 1e-3
    else:
        assert first.taut_after is None and first.taut_within is None
    assert step.policy.retry == 0 and step.policy.then.value == "lock"
    assert step.policy.goto is None


@pytest.mark.slow
def test_two_turns_round_the_arm_tie_a_double_overhand(tmp_path: Path) -> None:
    """Two turns round the bent arm (``turns=2``, seed 1), the arm turned along the tail
    after the grasp: the end is drawn through the coil and the thread holds a double
    overhand (the surgeon's first throw: the cinquefoil, determinant 5) that binds the
    stitch. The slide-off passes its check; the true tension stays under the limit."""
    summary, trace = run_cli(
        tmp_path,
        str(PROC),
        "--set",
        "stitch=false",
        "--set",
        "turns=2",
        "--seed",
        "1",
        "--backend",
        "pybullet-surgical-stitched",
        "--max-time",
        "110",
        *SPRINGING,
    )
    entered = [m.data["dest"] for m in trace.messages(["/transitions"])]
    for step in ("align-arm", "align-jaws", "draw-tail", "slide-off", "tighten"):
        assert f"autonomous/{step}" in entered
    bends = [m.data["bend"] for m in trace.messages(["/tool_state/endobot_2"])]
    assert bends[-1][0] == pytest.approx(math.radians(80.0), abs=math.radians(1.0))
    assert summary["outcome"] == "succeeded"
    assert summary["knot"]["type"] == "double-overhand"
    assert summary["knot"]["determinant"] == 5
    assert summary["knot"]["through_tissue"] is True
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


@pytest.mark.slow
def test_a_perturbed_trefoil_that_draws_taut_early_passes_the_floor(tmp_path: Path) -> None:
    """Perturbed run 12 (base errors 2.8 and 1.8 mm, joint friction x1.03): its slide-off
    went taut after 29.7 mm, below the former 35 mm floor, which stopped a throw that ties.
    With the floor between the throws that must not pass (by 18.9 mm) and it, the run ends
    ``succeeded`` with a trefoil that binds the stitch, the true tension under the limit."""
    import json

    from suture_engine.runtime.run import run_procedure

    out = tmp_path / "run"
    run_procedure(  # benchmarks/knot_success.py --single --seeds 20, algorithm 3, run 12
        PROC,
        backend="pybullet-surgical-stitched",
        seed=64663193,
        sets=["stitch=false"],
        out=out,
        max_time_s=100,
        backend_options={
            "base_error": {
                "endobot_1": (
                    -0.0016334009149484147,
                    -0.00021342158745423488,
                    -0.0022955871942597086,
                ),
                "endobot_2": (
                    -0.00037654214444794064,
                    0.0011304234045460709,
                    -0.0013272083500834842,
                ),
            },
            "friction_scale": 1.031461775152532,
            "suture_stiffness_scale": 1.1336340109914094,
            **SPRINGING_OPTIONS,
        },
    )
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "succeeded"
    assert summary["knot"]["type"] == "trefoil" and summary["knot"]["through_tissue"] is True
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


def _alg3_square_knot(tmp_path: Path, seed: int, *sets: str) -> tuple[dict[str, Any], Any]:
    """``suture run procedures/square-knot.yaml --set algorithm=3 --seed SEED [--set ...]``
    as before 2026-12-07: on the springing thread, with that day's defaults
    (:data:`SPRINGING`, :data:`EARLIER`)."""
    square_knot = str(ROOT / "procedures" / "square-knot.yaml")
    args = ["--set", "algorithm=3", "--seed", str(seed), "--max-time", "215", *SPRINGING]
    for item in (*EARLIER, *sets):
        args += ["--set", item]
    return run_cli(tmp_path, square_knot, *args)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seed", "step", "check"),
    [(4, "slide-off", "skill-failure:tension 1.50 N reached after only")],
    ids=["loop-left-on-the-arm"],
)
def test_the_square_knots_mirrored_throw_that_ties_nothing_stops_the_run(
    tmp_path: Path, seed: int, step: str, check: str
) -> None:
    """Algorithm 3's square knot: the first throw ties its trefoil and the mirrored throw
    ties nothing; a check fails the step and the robots lock (the run stops ``failed``)
    instead of claiming a square knot. Seed 4 (2026-12-03, since clear-jaws swings the
    strand across the arm's end): the loop stays on the arm, and the slide-off goes taut
    after about 10 mm, under its floor. The ground truth agrees: the first trefoil only.
    (At a 5 mm floor this run ends ``succeeded`` with that trefoil.) The arm square to the
    tail (``align_mirror=false``, the default before 2026-12-04)."""
    summary, trace = _alg3_square_knot(tmp_path, seed, "align_mirror=false")
    assert summary["outcome"] == "failed" and summary["final_state"] == "lock"
    events = [m.data for m in trace.messages(["/events"])]
    faults = [e for e in events if e["kind"] == "unpredictable"]
    assert faults[-1]["state"] == f"autonomous/mirrored-knot.{step}", faults
    assert faults[-1]["detail"].startswith(check)
    details = [e["detail"] for e in events]
    assert "done:simple-knot.slide-off-free" in details  # retry_slide_off: not needed
    assert ("done:mirrored-knot.slide-off" in details) is (step == "tighten")
    assert summary["knot"]["type"] == "trefoil"
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


@pytest.mark.slow
def test_a_caught_mirrored_loop_is_freed_by_the_retry_on_friction_draw_14(tmp_path: Path) -> None:
    """Friction draw 14 of ``knot_success.py --seeds 20 --only friction`` (algorithm 3):
    the mirrored loop catches on the jaws in ``clear-jaws`` (the grasper's estimate over
    its 1.4 N bound), where the robots used to lock with the first trefoil alone. The
    retry slackens the strand, the square forms as the arm eases forward, and the throw
    goes on through ``draw-tail`` and ``clear-jaws`` again to a square that the ground
    truth confirms (docs/status.md, "The caught loop, retried")."""
    from benchmark_modules import load_benchmark

    from suture_engine.runtime.run import run_procedure
    from suture_engine.trace.reader import TraceReader

    backend = "pybullet-surgical-stitched"
    seed, options = load_benchmark("branch_sensitivity").sweep_run("3:14", backend, 0, "friction")
    result = run_procedure(
        str(ROOT / "procedures" / "square-knot.yaml"),
        backend=backend,
        seed=seed,
        sets=["algorithm=3", *EARLIER],
        out=tmp_path / "run",
        max_time_s=260.0,
        backend_options={**options, **SPRINGING_OPTIONS},
    )
    trace = TraceReader(tmp_path / "run" / "trace.mcap")
    events = [m.data for m in trace.messages(["/events"])]
    # hold-back's guard reports its place reached with the strand slack (by design)
    faults = [e for e in events if e["kind"] == "unpredictable"]
    assert [e["state"] for e in faults] == [
        "autonomous/mirrored-knot.hold-back",
        "autonomous/mirrored-knot.clear-jaws",
    ], faults
    assert faults[1]["detail"].startswith("invariant:tension:endobot_2")
    details = [e["detail"] for e in events]
    for step in ("slacken", "ease-arm", "redraw-tail", "reclear-jaws", "slide-off", "tighten"):
        assert f"done:mirrored-knot.{step}" in details, step
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == result.summary.outcome
    _assert_square(summary)


def _assert_square(summary: dict[str, Any]) -> None:
    assert summary["outcome"] == "succeeded" and summary["final_state"] == "tied"
    knot = summary["knot"]
    assert knot["type"] == "square" and knot["determinant"] == 9 and knot["v3"] == 0
    assert knot["through_tissue"] is True
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]


@pytest.mark.slow
def test_algorithm_3_ties_a_square_knot_on_seed_2(tmp_path: Path) -> None:
    """Algorithm 3's square knot, seed 2 (2026-12-03, since clear-jaws swings the strand
    across the arm's end): the loop comes off the arm in the slide-off, which goes taut
    past its floor; the run ends ``succeeded`` and the simulated thread holds a square
    knot (determinant 9, v3 0) that binds the stitch, under the tension limit. The arm
    square to the tail (``align_mirror=false``)."""
    summary, _ = _alg3_square_knot(tmp_path, 2, "align_mirror=false")
    _assert_square(summary)


@pytest.mark.slow
def test_algorithm_3_ties_a_square_knot_on_seed_1_at_the_low_floor(tmp_path: Path) -> None:
    """Seed 1 with the mirrored slide-off's floor at 5 mm: its second knot forms loosely
    while clear-jaws sweeps the strand, the slide-off goes taut after about 10 mm with the
    loop's strand still on the arm, and the tightening leaves a square knot (determinant 9,
    v3 0) that binds the stitch. At the default floor the slide-off stops it. The arm
    square to the tail (``align_mirror=false``)."""
    summary, _ = _alg3_square_knot(
        tmp_path, 1, "align_mirror=false", "mirrored_slide_off_after=5mm"
    )
    _assert_square(summary)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 8])
def test_algorithm_3_ties_a_square_knot_with_the_arm_turned_along_the_tail(
    tmp_path: Path, seed: int
) -> None:
    """The square knot's default for algorithm 3 from 2026-12-04 to 2026-12-07, on the
    springing thread (:func:`_alg3_square_knot`): the mirrored throw turns the
    bent arm along the tail after the grasp (``align_mirror``), and its slide-off draws at
    3 mm/s to a 1 N guard. Seed 1 ends ``succeeded`` with a square knot (determinant 9,
    v3 0) that binds the stitch. Seed 8 drew 8.84 N true at the end of the slide-off when it
    ran at 5 mm/s to 1.5 N, over the limit and unseen by the base sensors; now it too ties
    the square, under the tension limit (read from the trace's ground truth)."""
    summary, _ = _alg3_square_knot(tmp_path, seed)
    _assert_square(summary)


@pytest.mark.slow
def test_algorithm_3s_defaults_tie_a_square_knot_on_seed_1(tmp_path: Path) -> None:
    """The square knot's defaults for algorithm 3 since 2026-12-07 (about 700 s wall):
    the damped thread its benches declare, the bases registered on the posts and the jig
    lifted, the held end kept up, and the mirrored loop drawn off by backing the jaws out
    along the turned arm (no ``clear-jaws``). Seed 1 ends ``succeeded`` with a square
    (ground truth) that binds the stitch, under the tension limit, and the summary names
    the damped thread."""
    square_knot = str(ROOT / "procedures" / "square-knot.yaml")
    summary, trace = run_cli(
        tmp_path, square_knot, "--set", "algorithm=3", "--seed", "1", "--max-time", "460"
    )
    _assert_square(summary)
    thread = summary["metrics"]["thread"]
    assert (thread["damping_per_s"], thread["weight_g_per_m"]) == (20.0, 4.0)
    details = {m.data["detail"] for m in trace.messages(["/events"])}
    registered = ("register.stitcher", "register.grasper", "register.remove-posts")
    retracted = ("mirrored-knot.lift-end", "mirrored-knot.draw-tail", "mirrored-knot.slide-off")
    for step in (*registered, *retracted):
        assert f"done:{step}" in details, step
    assert "skipped:mirrored-knot.clear-jaws (when: false)" in details


def test_the_aligned_mirrored_tighten_stops_at_a_lower_guard() -> None:
    """The mirrored throw with ``align_mirror`` tightens to 0.3 N (0.5 N drew a pinch of
    17.09 N true on a registered perturbed run, docs/status.md); the first throw, the
    unaligned mirrored throw, the unmirrored second throw and the double throw keep theirs."""
    from suture_engine.runtime.plan import compile_procedure

    second = {"second": True, "mirror": True, "stitch": False}
    cases = [
        ({**second, "align_mirror": True}, 0.3),
        ({**second, "align_mirror": False}, 0.5),
        ({"second": True, "stitch": False, "align_mirror": True}, 0.5),
        ({"stitch": False}, 0.5),
        ({"stitch": False, "turns": 2}, 1.5),
    ]
    for params, guard in cases:
        proc: Any = load_procedure(PROC, params=params)
        assert compile_procedure(proc).steps["tighten"].enabled
        assert proc.states["tighten"].params.until_tension == pytest.approx(guard), params


TIGHTEN_SQUARES_LEAST_N = 0.071
"""Least reading of the check itself (the grasper's base force averaged over the tighten's
first 50 ms, against the run's rest) on a square with the held end kept up: the issue's
draw 2, registered with ``hand_up_first`` (registered seed 0 read 0.092 N and the former
0.1 N stopped it; 2026-12-06, later; docs/status.md) [N]."""
TIGHTEN_FALSE_CLAIMS_MOST_N = 0.041
"""Most reading of the check on the throws it stopped with no second knot: registered
seeds 1 (0.027 N), 2 (0.041 N) and 8 (0.037 N), the issue's draw 11 registered (0.032 N)
[N]."""


def test_the_kept_up_mirrored_tighten_needs_the_tail_already_pulling() -> None:
    """The mirrored throw with ``align_mirror``, the held end kept up and ``check_throw``
    starts its tighten only if the grasper's tail already pulls (``held_at_start``,
    between the stored false claims and squares); lowered (the throw's default: there the tail
    lies slack on squares too, 0.042 N on unperturbed seed 1's), the first throw, the
    unaligned throw, the lay pull and the unchecked throw do not check it. The square knot
    passes it on with ``check_held``, off by default there since 2026-12-07."""
    from suture_engine.runtime.run import load_plan

    kept = {"second": True, "mirror": True, "stitch": False, "align_mirror": True,
            "lift_end": True, "lower_end": False}  # fmt: skip
    cases = [
        (kept, 0.055),
        ({**kept, "lower_end": True}, None),
        ({**kept, "lift_end": False, "lower_end": True}, None),
        ({**kept, "check_throw": False}, None),
        ({**kept, "check_held": False}, None),
        ({**kept, "lay_pull": True}, None),
        ({**kept, "align_mirror": False}, None),
        ({"stitch": False, "lift_end": True, "lower_end": False}, None),
    ]
    for params, held in cases:
        proc: Any = load_procedure(PROC, params=params)
        got = proc.states["tighten"].params.held_at_start
        assert got == (None if held is None else pytest.approx(held)), params
    held = load_procedure(PROC, params=kept).states["tighten"].params.held_at_start
    assert TIGHTEN_FALSE_CLAIMS_MOST_N < held < TIGHTEN_SQUARES_LEAST_N
    up = ["algorithm=3", "lift_end=true", "lower_end=false"]
    down = ["algorithm=3", "lift_end=false", "lower_end=true"]  # the defaults before 2026-12-07
    held_on = [*up, "check_held=true"]  # off by default since 2026-12-07 (square-knot.yaml)
    cases = [
        (held_on, True),
        (up, False),
        (["algorithm=3"], False),
        ([*down, "check_held=true"], False),
        ([*held_on, "check_throw=false"], False),
    ]
    for sets, on in cases:
        _, plan = load_plan(PROC.parent / "square-knot.yaml", sets)
        mirrored = plan.steps["mirrored-knot.tighten"].make_skill().params.held_at_start
        first = plan.steps["simple-knot.tighten"].make_skill().params.held_at_start
        assert (mirrored is not None, first) == (on, None), sets


def test_the_lay_pull_draws_the_mirrored_tail_towards_the_entrys_side() -> None:
    """``lay_pull`` turns only the aligned mirrored tighten into the square's securing pull:
    40 mm along world -y (the entry lies at -y from the exit) to 0.6 N. Every other throw,
    and that one without it, keeps its own move."""
    second = {"second": True, "mirror": True, "stitch": False, "align_mirror": True}
    cases = [
        ({**second, "lay_pull": True}, (0.0, -0.040, 0.004), 0.6),
        (second, (0.025, 0.0, 0.004), 0.3),
        ({**second, "align_mirror": False, "lay_pull": True}, (0.025, 0.0, 0.004), 0.5),
        ({"stitch": False, "lay_pull": True}, (0.025, 0.0, 0.004), 0.5),
        ({"stitch": False, "turns": 2, "lay_pull": True}, (0.0, -0.020, 0.004), 1.5),
    ]
    for params, target, guard in cases:
        proc: Any = load_procedure(PROC, params=params)
        move = proc.states["tighten"].params
        assert move.relative_to == "grasper"
        assert move.target == pytest.approx(target), params
        assert move.until_tension == pytest.approx(guard), params
    # the scene's entry and exit of the default stitch: the pull runs from exit to entry
    scene = load_procedure(PROC).scene
    entry, exit_ = scene.tissue.points["entry_2"], scene.tissue.points["exit_2"]
    assert entry[1] < exit_[1] and entry[0] == exit_[0]


def test_the_square_knot_passes_the_lay_pull_to_its_mirrored_throw() -> None:
    from suture_engine.runtime.run import load_plan

    for sets, target in [
        (["algorithm=3", "lay_pull=true"], (0.0, -0.040, 0.004)),
        (["algorithm=3"], (0.025, 0.0, 0.004)),
    ]:
        _, plan = load_plan(PROC.parent / "square-knot.yaml", sets)
        mirrored: Any = plan.steps["mirrored-knot.tighten"].make_skill().params
        first: Any = plan.steps["simple-knot.tighten"].make_skill().params
        assert mirrored.target == pytest.approx(target), sets
        assert first.target == pytest.approx((0.025, 0.0, 0.004)), sets


@pytest.mark.parametrize(
    ("procedure", "params", "step"),
    [
        ("square-knot.yaml", {"algorithm": 3}, "mirrored-knot.align-jaws"),
        ("knot-algorithm-3.yaml", {"stitch": False, "turns": 2}, "align-jaws"),
    ],
)
def test_align_jaws_off_its_goal_locks(procedure: str, params: dict[str, Any], step: str) -> None:
    """``align-jaws`` off its goal locks the robots. Routed on to ``draw-tail`` it gained
    squares (registered calibration draw 19; eight misses with ``lift_end``) but one
    unperturbed run with ``lift_end`` went on with the end not through the loop and ended
    ``succeeded`` with the first trefoil alone (docs/status.md): a lock is never a false
    claim. No retry either (a retry would move the arm with the loop on it again)."""
    from suture_engine.runtime.automaton import Then
    from suture_engine.runtime.plan import compile_procedure

    proc: Any = load_procedure(ROOT / "procedures" / procedure, params=params)
    steps = compile_procedure(proc).steps
    prefix = step.rsplit("align-jaws", 1)[0]
    align = steps[step]
    assert align.enabled
    assert align.on_done == f"{prefix}draw-tail"
    assert align.policy.goto is None and align.policy.retry == 0
    assert align.policy.then is Then.LOCK


@pytest.mark.parametrize(
    ("params", "lifted"),
    [
        ({"second": True, "mirror": True, "stitch": False, "align_mirror": True}, True),
        ({"stitch": False, "turns": 2}, True),
        ({"second": True, "mirror": True, "stitch": False, "align_mirror": False}, False),
        ({"stitch": False}, False),
        ({"second": True, "stitch": False}, False),
    ],
)
def test_lift_end_lifts_the_held_end_before_the_turn_and_align_jaws_lowers_it(
    params: dict[str, Any], lifted: bool
) -> None:
    """``lift_end``: where the arm is turned with the end held (two turns, and the aligned
    mirrored throw), the grasper first lifts straight up by ``lift_height`` (world frame,
    from its own tool tip) and ``align-jaws`` comes down by as much, so the jaws end where
    they did without it. Every other throw, and every throw without it, is unchanged."""
    from suture_engine.runtime.plan import compile_procedure

    without: Any = load_procedure(PROC, params=params)
    lift: Any = load_procedure(PROC, params={**params, "lift_end": True, "lift_height": "6 mm"})
    plan, plain = compile_procedure(lift), compile_procedure(without)
    assert not plain.steps["lift-end"].enabled
    assert plan.steps["lift-end"].enabled is lifted
    assert plan.steps["grab-tail"].on_done == "lift-end"
    assert plan.steps["lift-end"].on_done == plan.steps["lift-end"].policy.goto == "align-arm"
    if not lifted:
        return
    up = plan.steps["lift-end"].make_skill().params
    assert up.relative_to == "grasper" and up.robot == "grasper"
    assert np.allclose(up.target, [0.0, 0.0, 6e-3]) and np.allclose(up.offset, 0.0)
    down = np.asarray(plan.steps["align-jaws"].make_skill().params.target)
    plain_down = np.asarray(plain.steps["align-jaws"].make_skill().params.target)
    assert np.allclose(np.asarray(up.target) + down, plain_down)
    kept: Any = load_procedure(
        PROC, params={**params, "lift_end": True, "lift_height": "6 mm", "lower_end": False}
    )
    kept_down = compile_procedure(kept).steps["align-jaws"].make_skill().params.target
    assert np.allclose(kept_down, plain_down)  # ``lower_end: false``: the end stays up


def test_the_square_knot_passes_lift_end_to_its_mirrored_throw() -> None:
    from suture_engine.runtime.run import load_plan

    for sets, lifted in [(["algorithm=3"], True), (["algorithm=3", "lift_end=false"], False)]:
        _, plan = load_plan(PROC.parent / "square-knot.yaml", sets)
        assert plan.steps["mirrored-knot.lift-end"].enabled is lifted, sets
        assert not plan.steps["simple-knot.lift-end"].enabled, sets
    for sets, lowered in [
        (["algorithm=3", "lower_end=true"], True),
        (["algorithm=3"], False),  # kept up by default since 2026-12-07
    ]:
        _, plan = load_plan(PROC.parent / "square-knot.yaml", sets)
        down = plan.steps["mirrored-knot.align-jaws"].make_skill().params.target
        assert np.isclose(down[2], -4e-3 if lowered else 0.0), sets


def _align_arm_lift_N(trace: Any) -> float:
    """How far the grasper's base sensor's vertical force rises above its reading at the
    start of the mirrored ``align-arm`` while it runs [N] (the sensor reads minus the
    robot's weight, so a push up on the tool raises it)."""
    window: list[float] = []
    state = ""
    for m in trace.messages(["/transitions", "/base_wrench/endobot_2"]):
        if m.topic == "/transitions":
            state = str(m.data["dest"]).rsplit("/", 1)[-1]
        elif state == "mirrored-knot.align-arm":
            window.append(float(m.data["force"][2]))
    assert window, "the run never turned the mirrored arm"
    return max(window) - window[0]


@pytest.mark.slow
def test_lift_end_keeps_the_turn_from_pressing_the_held_end_into_the_pad(tmp_path: Path) -> None:
    """Algorithm 3's square knot, seed 1, run to just after the mirrored arm's turn. As
    committed, the turn swings the held end's capsule down onto the pad and drags it there:
    the grasper's base sensor reads the pad's push up (PyBullet's contact force on the
    capsule was 4.8 N on this seed) while the thread is slack. With ``lift_end`` the end is
    lifted clear first, and the push falls to a fraction of that."""
    square_knot = str(ROOT / "procedures" / "square-knot.yaml")
    runs = {}
    for lift, max_time in (("false", "142"), ("true", "146")):
        (tmp_path / lift).mkdir()
        runs[lift] = run_cli(
            tmp_path / lift, square_knot, "--set", "algorithm=3", "--set", f"lift_end={lift}",
            "--set", "lower_end=true", "--set", "register=false", "--set", "retract_mirror=false",
            "--seed", "1", "--max-time", max_time, *SPRINGING,
        )  # fmt: skip
    assert _align_arm_lift_N(runs["false"][1]) > 3.0
    assert _align_arm_lift_N(runs["true"][1]) < 2.0


def test_grab_dwell_reaches_both_throws_tail_grasps_for_every_algorithm() -> None:
    """``grab_dwell`` (square-knot.yaml) becomes the ``dwell`` of each throw's tail grasp,
    the algorithm's ``grab-tail``; by default it is 0 (the skill ends as the jaw reports
    closed). Algorithm 2's mirrored throw keeps the first throw's grasp (its step is off)."""
    from suture_engine.runtime.plan import compile_procedure

    square = ROOT / "procedures" / "square-knot.yaml"
    both = ("simple-knot", "mirrored-knot")
    for algorithm, throws in ((1, both), (2, ("simple-knot",)), (3, both)):
        for params, dwell in (({}, 0.0), ({"grab_dwell": "0.2 s"}, 0.2)):
            plan = compile_procedure(
                load_procedure(square, params={"algorithm": algorithm, **params})
            )
            grabs = {
                name: step.make_skill().params.dwell
                for name, step in plan.steps.items()
                if name.endswith(".grab-tail") and step.enabled
            }
            assert set(grabs) == {f"{t}.grab-tail" for t in throws}, algorithm
            assert sorted(grabs.values()) == pytest.approx([dwell] * len(throws)), params
