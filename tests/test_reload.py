"""Cutting a suture and loading the next stitch's (an interrupted suture, one at a time):
in the backend (``cut_suture``, ``load_suture``), through the skills ``cut-suture`` and
``load-suture`` in a run, and the evaluation of the threads cut on the way."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from backends.base import BackendError
from backends.pybullet.backend import StitchedSurgicalPyBulletBackend, SurgicalPyBulletBackend
from backends.pybullet.tools import BentTipGrasper, Grasper, Stitcher
from suture_engine.language.loader import load_procedure
from suture_engine.robot.endobot import gravity_vector
from suture_engine.runtime.evaluation import evaluate_trace, find_bites
from suture_engine.runtime.observation import Command, RobotCommand, ToolCommand
from suture_engine.runtime.run import run_procedure

ROOT = Path(__file__).resolve().parent.parent
SQUARE = ROOT / "procedures" / "square-knot.yaml"
RELOAD = ROOT / "tests" / "procedures" / "reload-stitch.yaml"
MM = 1e-3


@pytest.fixture(scope="module")
def model():  # type: ignore[no-untyped-def]
    return load_procedure(SQUARE).scene  # bench-square: 140 mm thread, hook grasper


def _hold(be: StitchedSurgicalPyBulletBackend, ticks: int, tools=None) -> None:  # type: ignore[no-untyped-def]
    for _ in range(ticks):
        obs = be.observe()
        be.apply(
            Command(
                {
                    k: RobotCommand.torque(
                        gravity_vector(np.asarray(obs.robots[k].q), s.model_params),
                        (tools or {}).get(k),
                    )
                    for k, s in be.robots.items()
                }
            )
        )
        be.step()


def _site(model, k: int) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    pts = model.tissue.points
    return np.asarray(pts[f"entry_{k}"], float), np.asarray(pts[f"exit_{k}"], float)


def _stitched_at(line: np.ndarray, model, k: int) -> list:  # type: ignore[no-untyped-def]
    """Assert that the centerline ``line`` [m] makes one bite, within 0.5 mm of stitch
    ``k``'s declared entry and exit points; return the bites."""
    bites = find_bites(line, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    entry, exit_ = _site(model, k)
    assert len(bites) == 1
    assert np.linalg.norm(np.asarray(bites[0].entry) - entry) < 0.5 * MM
    assert np.linalg.norm(np.asarray(bites[0].exit) - exit_) < 0.5 * MM
    return bites


def test_a_cut_thread_leaves_the_world_and_a_loaded_one_is_stitched_at_its_site(model) -> None:  # type: ignore[no-untyped-def]
    be = StitchedSurgicalPyBulletBackend()
    try:
        be.reset(model, 0)
        assert be.scene is not None
        grasper, stitcher = be.scene.tools["endobot_2"], be.scene.tools["endobot_1"]
        assert isinstance(grasper, Grasper) and isinstance(stitcher, Stitcher)
        _hold(be, 50)
        import pybullet as p

        old_bodies = list(be.scene.suture.bodies)
        suture_radius = be.scene.suture.params.collision_radius
        count = p.getNumBodies(physicsClientId=be.client)
        before = np.asarray(be.ground_truth()["centerline"])
        cut = be.cut_suture()
        np.testing.assert_allclose(cut.centerline, before, atol=1e-4)
        assert be.scene.suture is None and be.scene.tissue is None
        assert not stitcher.holds_needle and grasper.suture is None
        # the capsules and the needle are parked far away, static and touching nothing
        assert p.getNumBodies(physicsClientId=be.client) == count
        for body in old_bodies:
            pos, _ = p.getBasePositionAndOrientation(body, physicsClientId=be.client)
            assert np.linalg.norm(pos) > 40.0
            assert p.getDynamicsInfo(body, -1, physicsClientId=be.client)[0] == 0.0
        truth = be.ground_truth()
        assert "centerline" not in truth and "tension_N" not in truth
        assert len(truth["cut_centerlines"]) == 1
        # the cut threads' lay is still judged with the thread's contact diameter
        assert truth["contact_diameter"] == pytest.approx(2 * suture_radius)
        _hold(be, 100)  # the world steps without a thread
        with pytest.raises(BackendError, match="cut once per load"):
            be.cut_suture()
        be.load_suture("entry_1", "exit_1")
        _hold(be, 1500)
        suture = be.scene.suture
        assert suture is not None and len(suture.bodies) == len(old_bodies)
        line = np.asarray(be.ground_truth()["centerline"])
        bites = _stitched_at(line, model, 1)
        # the needle is locked in the jaw that held the old one, the thread at rest in it
        assert stitcher.holds_needle and stitcher.needle_body == suture.needle_body
        jaw, _ = stitcher.needle_jaw()
        assert np.linalg.norm(line[-1] - np.asarray(jaw)) < 1.5 * MM
        assert be.ground_truth()["tension_N"] < 0.1
        # the tail lies on the new pad (a new body given a parked-away id's collision
        # pairs let it fall through: see Suture.park)
        tail = line[: bites[0].first]
        assert np.all(np.abs(tail[:-2, 2] - 0.9 * MM) < 0.3 * MM)
        speeds = [
            np.linalg.norm(p.getBaseVelocity(b, physicsClientId=be.client)[0])
            for b in suture.bodies
        ]
        assert max(speeds) < 0.01
    finally:
        be.close()


def test_on_algorithm_3s_bench_the_needle_holder_takes_the_loaded_thread() -> None:
    """Algorithm 3's bench has no stitcher: the stitched start puts the needle's end in
    the needle holder's jaws (a plain grasper), and its bent-tip grasper filters the
    thread per capsule. A thread loaded in place, after the same settling, lies where
    the start laid the first one; loaded at stitch 1, it is stitched there, its end held
    by the holder. (The bent grasper's filters for a new thread:
    ``tests/test_suture_physics.py``.)"""
    alg3 = load_procedure(ROOT / "procedures" / "knot-algorithm-3.yaml").scene
    be = StitchedSurgicalPyBulletBackend()
    try:
        be.reset(alg3, 0)
        assert be.scene is not None
        holder, bent = be.scene.tools["endobot_1"], be.scene.tools["endobot_2"]
        assert type(holder) is Grasper and isinstance(bent, BentTipGrasper)
        _hold(be, 300)
        first = np.asarray(be.ground_truth()["centerline"])
        be.cut_suture()
        assert holder.held_segment == -1 and bent.suture is None
        be.load_suture("entry_2", "exit_2")
        _hold(be, 300 + round(be.SETTLE_S / be.dt))  # the reset settled the first one too
        again = np.asarray(be.ground_truth()["centerline"])
        assert np.abs(again - first).max() < 0.2 * MM
        be.cut_suture()
        be.load_suture("entry_1", "exit_1")
        _hold(be, 1500)
        suture = be.scene.suture
        line = np.asarray(be.ground_truth()["centerline"])
        _stitched_at(line, alg3, 1)
        assert holder.held_segment == len(suture.bodies) - 1
        tip, _ = be.scene.robots["endobot_1"].true_tool_pose()
        assert np.linalg.norm(line[-1] - np.asarray(tip)) < 1.0 * MM
        assert be.ground_truth()["tension_N"] < 0.1
    finally:
        be.close()
    hanging = SurgicalPyBulletBackend(start="needle")  # no needle to hang a thread from
    try:
        hanging.reset(alg3, 0)
        hanging.cut_suture()
        with pytest.raises(BackendError, match="a needle holder holds the thread's end"):
            hanging.load_suture("entry_1", "exit_1")
        assert hanging.scene.suture is None and hanging.scene.tissue is None
    finally:
        hanging.close()


def test_a_withdrawn_thread_leaves_the_world_and_is_not_kept(model) -> None:  # type: ignore[no-untyped-def]
    """The backend's side of ``cut-suture`` with ``withdraw``: the thread goes as a cut
    one does, but nothing is returned or kept, so the ground truth has no cut centerline;
    a new thread loads after it."""
    be = StitchedSurgicalPyBulletBackend()
    try:
        be.reset(model, 0)
        _hold(be, 50)
        built = be.thread_model()
        assert built is not None and built["damping_per_s"] == 0.5
        assert be.cut_suture(withdraw=True) is None
        assert be.scene.suture is None and be.cut_threads == []
        assert be.run_metrics()["thread"] == built  # the run still names its model
        truth = be.ground_truth()
        assert "centerline" not in truth and not truth.get("cut_centerlines")
        be.load_suture("entry_1", "exit_1")
        assert be.scene.suture is not None
    finally:
        be.close()


@pytest.mark.slow
def test_a_withdrawn_suture_is_not_a_stitch_of_the_result(tmp_path: Path) -> None:
    """``cut-suture`` with ``withdraw``: the thread leaves the world as a cut one does, but
    it is not kept (no cut centerline in the ground truth or the trace), so the run's
    ``knot`` is the loaded thread's alone; a plain cut keeps it (the test below). About
    40 s: the whole reload procedure, as the default suite's run of it is."""
    from suture_engine.trace import channels
    from suture_engine.trace.reader import TraceReader

    text = RELOAD.read_text()
    assert text.count("skill: cut-suture\n") == 1
    replaced = tmp_path / "replace-stitch.yaml"
    replaced.write_text(
        text.replace("procedure: reload-stitch", "procedure: replace-stitch")
        .replace("skill: cut-suture\n", "skill: cut-suture\n    with: {withdraw: true}\n")
        .replace("../../procedures/", str(ROOT / "procedures") + "/")
    )
    out = tmp_path / "run"
    summary = run_procedure(replaced, out=out, seed=0, max_time_s=60.0).summary
    assert summary.outcome == "succeeded", summary.metrics.get("stopped")
    knot = summary.knot
    assert isinstance(knot, dict) and knot["type"] == "unknot" and knot["through_tissue"]
    assert summary.metrics["stitches"]["site"] == ["1"]
    trace = out / "trace.mcap"
    assert not list(TraceReader(trace).messages([channels.GROUND_TRUTH_SUTURE_CUT]))
    cuts = [
        m.data["detail"]
        for m in TraceReader(trace).messages([channels.EVENTS])
        if m.data["name"] == "cut-suture"
    ]
    assert cuts == ['{"withdraw":true}']


def test_the_stitcher_hands_the_loaded_needle_over(model) -> None:  # type: ignore[no-untyped-def]
    be = StitchedSurgicalPyBulletBackend()
    try:
        be.reset(model, 0)
        be.cut_suture()
        be.load_suture("entry_3", "exit_3")
        stitcher = be.scene.tools["endobot_1"]
        _hold(be, 200, {"endobot_1": ToolCommand(jaw_closed=True, jaw2_closed=False)})
        _hold(be, 400, {"endobot_1": ToolCommand(jaw_closed=True, jaw2_closed=True)})
        assert stitcher.needle_holder == 1 and not stitcher.stalls
    finally:
        be.close()


def test_bad_loads_are_refused_with_their_reason(model) -> None:  # type: ignore[no-untyped-def]
    be = StitchedSurgicalPyBulletBackend()
    try:
        be.reset(model, 0)
        with pytest.raises(BackendError, match="cut the thread first"):
            be.load_suture("entry_1", "exit_1")
        be.cut_suture()
        with pytest.raises(BackendError, match="entry_9"):
            be.load_suture("entry_9", "exit_1")
        assert be.scene.suture is None and be.scene.tissue is None  # nothing half-built
    finally:
        be.close()


def test_a_load_that_fails_half_way_leaves_no_pad_in_the_scene(model, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    import pybullet as p

    from backends.pybullet import reload
    from backends.pybullet.scene import SceneError

    def too_short(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise SceneError("tail", 0.2, ["<= 0.1 m"])

    be = StitchedSurgicalPyBulletBackend()
    try:
        be.reset(model, 0)
        be.cut_suture()
        monkeypatch.setattr(reload, "stitched_path", too_short)
        with pytest.raises(BackendError, match="tail"):
            be.load_suture("entry_1", "exit_1")
        assert be.scene.suture is None and be.scene.tissue is None
        # the new pad was built, then parked: nothing but the robots' parts near the wound
        near = [
            i
            for i in range(p.getNumBodies(physicsClientId=be.client))
            if np.linalg.norm(p.getBasePositionAndOrientation(i, physicsClientId=be.client)[0])
            < 1.0
            and p.getDynamicsInfo(i, -1, physicsClientId=be.client)[0] == 0.0
            and i not in {r.body_id for r in be.robots.values()}
        ]
        assert near == []
        monkeypatch.undo()
        be.load_suture("entry_1", "exit_1")  # and a load after it works
        assert be.scene.suture is not None
    finally:
        be.close()
    tail_held = SurgicalPyBulletBackend(start="tail-held")
    try:
        tail_held.reset(model, 0)
        tail_held.cut_suture()
        with pytest.raises(BackendError, match="tail-held"):
            tail_held.load_suture("entry_1", "exit_1")
    finally:
        tail_held.close()


def test_on_the_needle_start_the_loaded_thread_hangs_from_the_needle(model) -> None:  # type: ignore[no-untyped-def]
    be = SurgicalPyBulletBackend(start="needle")
    try:
        be.reset(model, 0)
        be.cut_suture()
        be.load_suture("entry_1", "exit_1")
        _hold(be, 300)
        stitcher = be.scene.tools["endobot_1"]
        line = np.asarray(be.ground_truth()["centerline"])
        assert stitcher.holds_needle
        assert np.linalg.norm(line[-1] - np.asarray(stitcher.needle_jaw()[0])) < 1.5 * MM
        # not stitched: no bite, and the pad is not threaded
        assert find_bites(line, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)) == []
        assert be.scene.tissue.suture is None
    finally:
        be.close()


def test_a_run_cuts_and_loads_and_evaluates_both_stitches(tmp_path: Path) -> None:
    summary = run_procedure(RELOAD, out=tmp_path, seed=0, max_time_s=60.0).summary
    assert summary.outcome == "succeeded", summary.metrics.get("stopped")
    knots = summary.knot
    assert isinstance(knots, list) and len(knots) == 2
    # along the wound: stitch 1 (x = -5 mm), loaded second; stitch 2, cut
    assert [(k["stitch"], k["thread"], k["cut"]) for k in knots] == [(1, 2, False), (2, 1, True)]
    assert all(k["type"] == "unknot" and k["through_tissue"] for k in knots)
    stitches = summary.metrics["stitches"]
    assert stitches["site"] == ["1", "2"]
    assert stitches["spacing_mean_mm"] == pytest.approx(5.0, abs=0.5)
    assert max(stitches["entry_error_mm"] + stitches["exit_error_mm"]) < 0.5
    # the trace has the cut, and evaluating it gives what the summary says
    from suture_engine.trace import channels
    from suture_engine.trace.reader import TraceReader

    trace = tmp_path / "trace.mcap"
    cuts = list(TraceReader(trace).messages([channels.GROUND_TRUTH_SUTURE_CUT]))
    assert len(cuts) == 1
    events = [m.data["name"] for m in TraceReader(trace).messages([channels.EVENTS])]
    assert "cut-suture" in events and "load-suture" in events
    ev = evaluate_trace(
        trace, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), wound=((-0.015, 0, 0), (0.015, 0, 0))
    )
    assert isinstance(ev.knot, list)
    assert [(k["stitch"], k["thread"], k["cut"]) for k in ev.knot] == [(1, 2, False), (2, 1, True)]
    saved = json.loads((tmp_path / "summary.json").read_text())
    assert [k["cut"] for k in saved["knot"]] == [False, True]
    # replayed on its own measurements, the engine cuts and loads at the same ticks
    from suture_engine.runtime.run import replay_trace

    check = replay_trace(trace, check=True)
    assert check.ok, check.diff


def test_a_backend_without_threads_fails_the_cut_step(tmp_path: Path) -> None:
    result = run_procedure(RELOAD, out=tmp_path, seed=0, max_time_s=30.0, backend="pybullet")
    summary = result.summary
    assert summary.outcome == "failed"
    assert summary.last_fault is not None
    assert summary.last_fault["step"] == "cut-2"
    assert "no surgical scene" in summary.last_fault["reason"]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("sets", "seed", "max_time_s", "lies_square", "spacing_mm"),
    [
        (["algorithm=2"], 12, 700.0, True, 0.25),
        (["algorithm=2"], 2, 700.0, False, 0.25),
        ([], 2, 800.0, False, 0.5),
        ([], 3, 800.0, False, 0.5),
    ],
    ids=["algorithm-2-seed-12", "algorithm-2-seed-2", "algorithm-3-seed-2", "algorithm-3-seed-3"],
)
def test_the_interrupted_suture_ties_three_square_knots(
    tmp_path: Path,
    sets: list[str],
    seed: int,
    max_time_s: float,
    lies_square: bool,
    spacing_mm: float,
) -> None:
    """The bundled interrupted suture: three stitches 5 mm apart, each tied with a square
    knot that binds its own stitch, each suture cut; the true tension stays far under the
    limit. Algorithm 2, seed 12 (about 16 min): every square lies square; seed 2 (about
    23 min; stitch 1's square lies as two half hitches). Algorithm 3 (the default), seeds
    2 and 3 (about 30 min each; the bases registered once, the damped thread its bench
    declares, the tail grasps held until the jaws are shut: without that, seed 3's third
    grasp held nothing). (Algorithm 2's seeds 0, 1, 3, 5 and 13 and algorithm 3's seeds 1,
    5 and 7 do not tie all three: docs/status.md, "Interrupted suture".)"""
    summary = run_procedure(
        ROOT / "procedures" / "interrupted-suture.yaml",
        out=tmp_path,
        seed=seed,
        max_time_s=max_time_s,
        sets=sets,
    ).summary
    assert summary.outcome == "succeeded", summary.last_fault
    knots = summary.knot
    assert isinstance(knots, list) and len(knots) == 3
    for k in knots:
        assert (k["type"], k["determinant"], k["v3"]) == ("square", 9, 0)
        assert k["through_tissue"] and k["cut"]
        assert k["post_straight"] is True or not lies_square
    assert [k["thread"] for k in knots] == [2, 1, 3]  # the middle stitch first
    stitches = summary.metrics["stitches"]
    assert stitches["site"] == ["1", "2", "3"]
    assert stitches["spacing_mean_mm"] == pytest.approx(5.0, abs=spacing_mm)
    assert summary.metrics["peak_true_tension_N"] < 0.5 * summary.tension_limit_N


@pytest.mark.parametrize("stiffness", [None, 2e4])
def test_the_backends_thread_contact_stiffness_reaches_every_thread_it_loads(
    model, stiffness: float | None
) -> None:  # type: ignore[no-untyped-def]
    """PyBullet's own dynamics info of each capsule: the backend's option softens the
    built thread's contacts and a reloaded one's; unset, the contacts stay rigid."""
    import pybullet as p

    be = StitchedSurgicalPyBulletBackend(thread_contact_stiffness=stiffness)

    def contact_parameters() -> set[tuple[float, float]]:
        assert be.scene is not None and be.scene.suture is not None
        infos = [
            p.getDynamicsInfo(b, -1, physicsClientId=be.client) for b in be.scene.suture.bodies
        ]
        return {(float(i[9]), float(i[8])) for i in infos}  # (stiffness, damping)

    try:
        be.reset(model, 0)
        expected = {(stiffness, 5.0)} if stiffness is not None else {(-1.0, -1.0)}
        assert contact_parameters() == expected
        be.cut_suture()
        be.load_suture("entry_1", "exit_1")
        assert contact_parameters() == expected
    finally:
        be.close()


@pytest.mark.parametrize(
    "bad", [{"thread_contact_stiffness": 0.0}, {"thread_contact_damping": -1.0}]
)
def test_the_backend_refuses_a_thread_contact_it_cannot_build(bad: dict[str, float]) -> None:
    with pytest.raises(BackendError, match=next(iter(bad))):
        StitchedSurgicalPyBulletBackend(**bad)


def test_a_scenes_thread_contact_stiffness_reaches_the_thread_and_the_option_wins(
    model,
) -> None:  # type: ignore[no-untyped-def]
    """The scene's ``suture.contact_stiffness`` and ``contact_damping`` soften the thread
    (PyBullet's dynamics info); the backend's option, when given, wins."""
    import pybullet as p

    suture = model.suture.model_copy(update={"contact_stiffness": 3e4, "contact_damping": 2.0})
    scene = model.model_copy(update={"suture": suture})
    for options, expected in (({}, (3e4, 2.0)), ({"thread_contact_stiffness": 1e4}, (1e4, 5.0))):
        be = StitchedSurgicalPyBulletBackend(**options)
        try:
            be.reset(scene, 0)
            assert be.scene is not None and be.scene.suture is not None
            infos = {
                p.getDynamicsInfo(b, -1, physicsClientId=be.client)[8:10]
                for b in be.scene.suture.bodies
            }
            assert infos == {(expected[1], expected[0])}
        finally:
            be.close()


def _capsule_reach(be: StitchedSurgicalPyBulletBackend) -> set[float]:
    """Each capsule's cylinder, between its end spheres' centres, less the distance from
    its centre to the next capsule's (the joint spacing), in PyBullet's own numbers [m]:
    0 when the spheres sit on the joints, minus two radii when the capsules meet tip to
    tip."""
    import pybullet as p

    assert be.scene is not None and be.scene.suture is not None
    bodies = be.scene.suture.bodies
    centres = [np.array(p.getBasePositionAndOrientation(b, be.client)[0]) for b in bodies]
    spacing = float(np.median(np.linalg.norm(np.diff(centres, axis=0), axis=1)))
    heights = {p.getCollisionShapeData(b, -1, be.client)[0][3][0] for b in bodies}
    return {round((h - spacing) / MM, 1) for h in heights}


@pytest.mark.parametrize(
    ("declared", "option", "smooth"),
    [(False, None, False), (False, True, True), (True, None, True), (True, False, False)],
)
def test_smooth_joints_reach_every_thread_from_the_scene_or_the_option_which_wins(
    model, declared: bool, option: bool | None, smooth: bool
) -> None:  # type: ignore[no-untyped-def]
    """The thread built and the thread reloaded after a cut: with smooth joints each
    capsule's cylinder spans the joint spacing measured from the capsules' positions;
    without, it is two collision radii (1.8 mm) shorter."""
    suture = model.suture.model_copy(update={"smooth_joints": declared})
    scene = model.model_copy(update={"suture": suture})
    be = StitchedSurgicalPyBulletBackend(thread_smooth_joints=option)
    expected = {0.0} if smooth else {-1.8}
    try:
        be.reset(scene, 0)
        assert _capsule_reach(be) == expected
        be.cut_suture()
        be.load_suture("entry_1", "exit_1")
        assert _capsule_reach(be) == expected
    finally:
        be.close()


@pytest.mark.parametrize(
    ("declared", "option", "expected"),
    [
        ((None, None), (None, None), (0.5, 1e-4)),
        ((None, None), (20.0, 4e-3), (20.0, 4e-3)),
        ((5.0, 2e-3), (None, None), (5.0, 2e-3)),
        ((5.0, 2e-3), (20.0, 4e-3), (20.0, 4e-3)),
    ],
)
def test_the_threads_damping_and_weight_reach_every_thread_from_the_scene_or_the_option(
    model,
    declared: tuple[float | None, float | None],
    option: tuple[float | None, float | None],
    expected: tuple[float, float],
) -> None:  # type: ignore[no-untyped-def]
    """The thread built and the thread reloaded after a cut get the scene's
    ``suture.damping`` and ``suture.weight``, or the backend's ``thread_damping`` and
    ``thread_weight`` over them, or the thread's defaults."""
    update = {"damping": declared[0], "weight": declared[1]}
    scene = model.model_copy(update={"suture": model.suture.model_copy(update=update)})
    be = StitchedSurgicalPyBulletBackend(thread_damping=option[0], thread_weight=option[1])
    rate, weight = expected
    try:
        be.reset(scene, 0)
        for reload in (False, True):
            if reload:
                be.cut_suture()
                be.load_suture("entry_1", "exit_1")
            params = be.scene.suture.params
            assert (params.linear_damping, params.angular_damping) == (rate, rate)
            assert params.real_mass_per_length == weight
    finally:
        be.close()


def test_the_backend_refuses_a_negative_damping_or_a_weight_not_positive() -> None:
    with pytest.raises(BackendError, match="thread_damping"):
        StitchedSurgicalPyBulletBackend(thread_damping=-1.0)
    with pytest.raises(BackendError, match="thread_weight"):
        StitchedSurgicalPyBulletBackend(thread_weight=0.0)


def test_the_backend_refuses_a_joint_shape_that_is_not_a_boolean() -> None:
    with pytest.raises(BackendError, match="thread_smooth_joints"):
        StitchedSurgicalPyBulletBackend(thread_smooth_joints="yes")  # type: ignore[arg-type]
