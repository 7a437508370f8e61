"""Scene assembly: from the scene model (robots, mounted tools, tissue, suture) and from dicts."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from backends.pybullet.scene import SceneError, build_scene, needle_path, stitch_points
from backends.pybullet.tools import BentTipGrasper, Grasper, Stitcher
from suture_engine.language.scene import Scene as SceneModel
from suture_engine.language.scene_file import load_scene, read_scene

ROOT = Path(__file__).resolve().parent.parent


def _model(name: str) -> SceneModel:
    return load_scene(ROOT / "procedures/scenes" / name)


def test_model_scene_robots_at_base_poses_with_tools_on_their_tool_links() -> None:
    import pybullet as p

    model = _model("bench.yaml")
    scene = build_scene(model, seed=3)
    try:
        assert sorted(scene.robots) == sorted(model.robots)
        for name, spec in model.robots.items():
            robot = scene.robots[name]
            base, _ = p.getBasePositionAndOrientation(robot.body_id, physicsClientId=scene.client)
            assert np.allclose(base, spec.base.position, atol=1e-9)
        assert isinstance(scene.tools["endobot_1"], Stitcher)
        hook = scene.tools["endobot_2"]
        assert isinstance(hook, Grasper) and hook.hook_body >= 0
        assert scene.suture.params.length == pytest.approx(model.suture.length)
        assert scene.suture.params.n_segments >= 40
        # The stitch runs between the named bite nearest the wound's middle (entry_2 at
        # x = 0 on the bench, the wound running from x = -15 mm to 15 mm).
        assert scene.tissue is not None
        assert np.allclose(scene.tissue.entry, model.tissue.points["entry_2"])
        assert np.allclose(scene.tissue.exit, model.tissue.points["exit_2"])
        for _ in range(500):
            scene.step()
        # Robots hold their start joints; each tool tip sits on its robot's tool link.
        for name, robot in scene.robots.items():
            assert np.allclose(robot.true_state().q, scene.hold[name], atol=5e-3)
            link, _ = robot.true_tool_pose()
            tip, _ = scene.tools[name].pose()
            assert np.linalg.norm(np.asarray(tip) - link) < 1e-3
        # Moving a robot moves its tool.
        before = np.asarray(scene.tools["endobot_2"].pose()[0])
        q = scene.hold["endobot_2"]
        # out, away from the pad (its jaws hold the tail end on it in the tail-held start)
        scene.hold["endobot_2"] = (q[0], q[1], q[2], q[3] - 0.02)
        for _ in range(1000):
            scene.step()
        after = np.asarray(scene.tools["endobot_2"].pose()[0])
        link, _ = scene.robots["endobot_2"].true_tool_pose()
        assert np.linalg.norm(after - link) < 1e-3
        assert np.linalg.norm(after - before) > 0.015
        # The needle is locked in the stitcher's jaw.
        stitcher = scene.tools["endobot_1"]
        assert isinstance(stitcher, Stitcher)
        jaw, _ = p.getBasePositionAndOrientation(stitcher.jaws[0], physicsClientId=scene.client)
        needle, _ = p.getBasePositionAndOrientation(
            scene.suture.needle_body, physicsClientId=scene.client
        )
        assert np.linalg.norm(np.asarray(jaw) - needle) < 1e-3
    finally:
        scene.close()


def test_model_scene_without_stitcher_starts_stitched_through_the_tissue() -> None:
    model = _model("bench-bent-tip.yaml")
    scene = build_scene(model)
    try:
        kinds = {type(t) for t in scene.tools.values()}
        assert BentTipGrasper in kinds or Stitcher in kinds
        if not any(isinstance(t, Stitcher) for t in scene.tools.values()):
            assert scene.tissue is not None and scene.tissue.suture is scene.suture
            for _ in range(200):
                scene.step()
            # A 7.5 mm capsule in an 8 mm bite: at least one lies in the channel, below the
            # surface (the channel is 0.5 mm deep, channel_depth), and the thread stays
            # threaded.
            assert len(scene.tissue.inside) >= 1
            assert scene.suture.centerline()[:, 2].min() < -0.1e-3
    finally:
        scene.close()


def test_model_scene_graspers_grip_the_thread_with_the_scene_grip_force() -> None:
    """A scene's graspers let the thread slide above its grip force (by default 0.9 times
    the tension limit, 6.35 N on the bench); a plain dict's hold it at any force."""
    data = read_scene(ROOT / "procedures/scenes/bench-bent-tip.yaml").data
    for own, expected in ((None, 0.9 * 0.75 * 0.96 * 9.80665), (2.5, 2.5)):
        if own is not None:
            data["robots"]["endobot_2"]["grip_force"] = own
        model = SceneModel.model_validate(data)
        scene = build_scene(model, start="stitched")
        try:
            assert model.tension_limit == pytest.approx(7.06, abs=0.005)
            holder, bent = scene.tools["endobot_1"], scene.tools["endobot_2"]
            assert isinstance(holder, Grasper) and isinstance(bent, BentTipGrasper)
            assert holder.grip_limit == pytest.approx(0.9 * model.tension_limit)
            assert bent.grip_limit == pytest.approx(expected)
        finally:
            scene.close()
    plain = build_scene({"tissue": {}})
    try:
        assert all(t.grip_limit == float("inf") for t in plain.tools.values())
        assert plain.tools
    finally:
        plain.close()


def test_same_seed_same_run() -> None:
    def run() -> np.ndarray:
        scene = build_scene({"suture": {"knot": "overhand", "segments": 60}}, seed=7)
        try:
            left, right = scene.tools["left"], scene.tools["right"]
            assert isinstance(left, Grasper) and isinstance(right, Grasper)
            left.close()
            right.close()
            for k in range(400):
                x = right.pose()[0]
                if k > 120:
                    right.set_pose((x[0] + 1e-5, x[1], x[2]))
                scene.step()
            return scene.suture.centerline()
        finally:
            scene.close()

    assert np.array_equal(run(), run())


@pytest.mark.parametrize(
    ("config", "field"),
    [
        ({"robots": {}}, "robots"),
        ({"suture": {"knot": "bowline"}}, "suture.knot"),
        ({"tools": {"left": "scalpel"}}, "tools.left"),
        ({"tissue": {"entry": [0, 0]}}, "tissue.entry"),
        ({"tools": {"a": "grasper", "b": "grasper", "c": "grasper"}}, "tools"),
    ],
)
def test_bad_dict_scenes_are_typed_errors(config: dict, field: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(SceneError) as err:
        build_scene(config)
    assert err.value.field == field


def _segment_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance of each point to the polyline ``line`` [m] (point-to-segment, by hand)."""
    out = []
    for x in points:
        best = np.inf
        for a, b in itertools.pairwise(line):
            u = b - a
            t = min(max(float((x - a) @ u) / float(u @ u), 0.0), 1.0)
            best = min(best, float(np.linalg.norm(a + t * u - x)))
        out.append(best)
    return np.array(out)


def _arc_length_to(line: np.ndarray, x: np.ndarray) -> float:
    """Length along ``line`` from its start to the point of it nearest ``x`` [m]."""
    best, at = np.inf, 0.0
    run = 0.0
    for a, b in itertools.pairwise(line):
        u = b - a
        t = min(max(float((x - a) @ u) / float(u @ u), 0.0), 1.0)
        d = float(np.linalg.norm(a + t * u - x))
        if d < best:
            best, at = d, run + t * float(np.linalg.norm(u))
        run += float(np.linalg.norm(u))
    return at


@pytest.mark.parametrize("tail", [0.03, 0.05])
def test_stitched_start_runs_the_thread_through_the_channel(tail: float) -> None:
    """The stitched start: the thread passes within 1 mm of the whole channel, ``tail`` lies
    out of the entry point, the needle is in the stitcher's jaw, and nothing moves much
    over 1 s of settling (stretch < 3 %)."""
    import pybullet as p

    model = _model("bench.yaml")
    scene = build_scene(model, seed=0, start="stitched", tail=tail)
    try:
        tissue = scene.tissue
        assert tissue is not None and tissue.suture is scene.suture
        entry = np.asarray(tissue.entry)
        for settled in (False, True):
            line = scene.suture.centerline()
            assert _segment_distance(tissue.channel, line).max() < 1e-3, settled
            assert _arc_length_to(line, entry) == pytest.approx(tail, abs=1.5e-3), settled
            # The tail lies on the surface (the pad's top is z = 0): its axis within a
            # capsule radius and a half millimetre of it, outside the tissue.
            out = line[: int(tail / scene.suture.params.segment_length)]
            assert np.all(np.abs(out[:, 2]) < 1.5e-3), settled
            stitcher = scene.tools["endobot_1"]
            assert isinstance(stitcher, Stitcher) and stitcher.needle_holder == 0
            jaw, _ = p.getBasePositionAndOrientation(stitcher.jaws[0], physicsClientId=scene.client)
            assert np.linalg.norm(line[-1] - np.asarray(jaw)) < 1e-3, settled
            for _ in range(1000 if not settled else 0):
                scene.step()
                assert scene.suture.stretch() < 0.03
        assert len(tissue.inside) >= 1
    finally:
        scene.close()


def test_tail_held_start_holds_the_tail_end_out_of_the_entry_point_and_the_needle() -> None:
    """The tail-held start: the needle sits in the stitcher's jaw 0, the hook grasper's jaws
    hold the thread's free end 30 mm out of the entry point (away from the exit), and the
    thread lies on the surface from there towards the entry point, then to below the
    needle and up to it, as long as the route. 1 s of settling moves nothing much."""
    import pybullet as p

    model = _model("bench-square.yaml")
    scene = build_scene(model, seed=0, start="tail-held")
    try:
        tissue = scene.tissue
        assert tissue is not None
        entry, exit_ = np.asarray(tissue.entry), np.asarray(tissue.exit)
        out = (entry - exit_) / np.linalg.norm(entry - exit_)
        stitcher, grasper = scene.tools["endobot_1"], scene.tools["endobot_2"]
        assert isinstance(stitcher, Stitcher) and isinstance(grasper, Grasper)
        assert grasper.held_segment == 0
        for settled in (False, True):
            line = scene.suture.centerline()
            jaw, _ = p.getBasePositionAndOrientation(stitcher.jaws[0], physicsClientId=scene.client)
            assert np.linalg.norm(line[-1] - np.asarray(jaw)) < 1e-3, settled
            # the free end lies 30 mm out of the entry point, on the surface (laid from the
            # needle's end, the capsules cut the route's corners: within one capsule)
            seg = scene.suture.params.segment_length
            assert np.linalg.norm(line[0] - (entry + 0.03 * out)) < seg, settled
            jaws, _ = grasper.pose()
            assert np.linalg.norm(np.asarray(jaws) - (line[0] + line[1]) / 2) < 2e-3, settled
            # capsules tip to tip: the route is the thread's length
            assert np.linalg.norm(np.diff(line, axis=0), axis=1).sum() == pytest.approx(
                model.suture.length, rel=0.03
            )
            # from the free end towards the entry point, the thread lies on the tail's line
            first = line[:3]
            along = (first - entry) @ out
            assert np.all(np.diff(along) < 0) and along.min() > 0.009, settled
            assert np.abs((first - entry - np.outer(along, out))[:, :2]).max() < 1.5e-3
            assert np.all(np.abs(line[: len(line) // 2, 2]) < 1.5e-3), settled
            for _ in range(1000 if not settled else 0):
                scene.step()
                assert scene.suture.stretch() < 0.03
    finally:
        scene.close()


@pytest.mark.parametrize("length", [0.10, 0.12, 0.14, 0.15, 0.16, 0.30])
@pytest.mark.parametrize("jaw_mm", [(-72.0, -51.0, 37.5), (-74.0, -50.0, 37.0)])
def test_needle_path_lays_any_thread_from_the_held_end_to_the_jaw(
    length: float, jaw_mm: tuple[float, float, float]
) -> None:
    """Short threads rise to the needle from the surface, long ones lie on it (with the
    bend moved sideways when longer than the surface route): each capsule chain is the
    thread's length, ends in the jaw, starts on the surface near the held point 30 mm out
    of the entry point, away from the exit, and never dips below the surface."""
    entry, exit_, normal = (
        np.array([0, -4e-3, 0.0]),
        np.array([0, 4e-3, 0.0]),
        np.array([0, 0, 1.0]),
    )
    jaw, seg, lift = np.asarray(jaw_mm) * 1e-3, 3e-3, 1.4e-3
    path = needle_path(entry, exit_, normal, lift, 0.03, jaw, np.array([-6e-3, 0, 0]), length, seg)
    chords = np.linalg.norm(np.diff(path, axis=0), axis=1)
    assert np.allclose(chords, seg, rtol=1e-6)
    assert len(chords) * seg == pytest.approx(length, abs=seg / 2)
    assert np.linalg.norm(path[-1] - jaw) < 1e-9
    held = entry + np.array([0, -0.03, lift])
    assert np.linalg.norm(path[0] - held) < 5e-3
    assert path[0][2] == pytest.approx(lift) and path[:, 2].min() > lift - 1e-9


def test_needle_path_refuses_a_thread_too_short_to_reach_the_jaw() -> None:
    entry, exit_, normal = (
        np.array([0, -4e-3, 0.0]),
        np.array([0, 4e-3, 0.0]),
        np.array([0, 0, 1.0]),
    )
    with pytest.raises(SceneError) as err:
        needle_path(
            entry,
            exit_,
            normal,
            1.4e-3,
            0.03,
            np.array([-0.072, -0.051, 0.0375]),
            np.array([-6e-3, 0, 0]),
            0.05,
            3e-3,
        )
    assert err.value.field == "suture.length"


def test_stitched_start_refuses_what_it_cannot_lay() -> None:
    model = _model("bench.yaml")
    with pytest.raises(SceneError) as err:
        build_scene(model, start="knotted")
    assert err.value.field == "suture.start" and "stitched" in err.value.valid
    with pytest.raises(SceneError) as err:
        build_scene(model, start="stitched", tail=0.29)  # longer than the thread allows
    assert err.value.field == "tail"
    with pytest.raises(SceneError) as err:
        build_scene(model, start="stitched", stitch=("entry_9", "exit_2"))
    assert err.value.field == "tissue.points.entry" and err.value.value == "entry_9"


def test_stitch_points_named_or_nearest_the_wound_middle() -> None:
    model = _model("bench.yaml")
    entry, exit_ = stitch_points(model.tissue, ("entry_3", "exit_3"))
    assert np.allclose(entry, [0.005, -0.004, 0.0]) and np.allclose(exit_, [0.005, 0.004, 0.0])
    entry, exit_ = stitch_points(model.tissue)
    assert np.allclose(entry, [0.0, -0.004, 0.0]) and np.allclose(exit_, [0.0, 0.004, 0.0])


def test_scene_field_suture_start_selects_the_stitched_start() -> None:
    model = _model("bench.yaml")
    stitched = model.model_copy(
        update={"suture": model.suture.model_copy(update={"start": "stitched"})}
    )
    for m, threaded in ((model, False), (stitched, True)):
        scene = build_scene(m)
        try:
            assert scene.tissue is not None
            assert (scene.tissue.suture is scene.suture) is threaded
        finally:
            scene.close()


def test_stitched_start_without_stitcher_holds_the_thread_in_the_needle_holder() -> None:
    """Algorithm 3's scene (a plain grasper as needle holder, a bent-tip grasper): the
    stitched start runs the thread through the channel with its tail out of the entry and
    ends it, needle and all, closed in the needle holder's jaws."""
    import pybullet as p

    model = _model("bench-bent-tip.yaml")
    scene = build_scene(model, seed=0, start="stitched")
    try:
        holder = scene.tools["endobot_1"]
        assert isinstance(holder, Grasper) and not isinstance(holder, BentTipGrasper)
        assert holder.holding and holder.held_segment == len(scene.suture.bodies) - 1
        assert scene.tissue is not None and scene.tissue.suture is scene.suture
        for _ in range(500):
            scene.step()
        line = scene.suture.centerline()
        jaw, _ = holder.pose()
        assert np.linalg.norm(line[-1] - np.asarray(jaw)) < 1e-3
        needle, _ = p.getBasePositionAndOrientation(
            scene.suture.needle_body, physicsClientId=scene.client
        )
        assert np.linalg.norm(np.asarray(needle) - np.asarray(jaw)) < 1e-3
        assert _segment_distance(scene.tissue.channel, line).max() < 1e-3
        assert _arc_length_to(line, np.asarray(scene.tissue.entry)) == pytest.approx(
            0.03, abs=1.5e-3
        )
        assert scene.suture.stretch() < 0.03
    finally:
        scene.close()


def _reach(scene, name: str, point: np.ndarray, seconds: float = 1.5) -> None:  # type: ignore[no-untyped-def]
    """Move robot ``name`` smoothly over ``seconds`` (then 0.5 s more) to the joints
    PyBullet's own IK gives for its tool tip at ``point`` [m]."""
    import pybullet as p

    robot = scene.robots[name]
    sol = p.calculateInverseKinematics(
        robot.body_id,
        robot.tool_link,
        point.tolist(),
        maxNumIterations=200,
        residualThreshold=1e-6,
        physicsClientId=scene.client,
    )
    start = np.asarray(scene.hold[name], dtype=float)
    goal = np.asarray(sol[:4], dtype=float)
    ticks = round(seconds * 1000)
    for k in range(ticks + 500):  # a joint ramp (no step: the hold PD would overshoot)
        s = min(1.0, k / ticks)
        q = start + (goal - start) * (3 * s * s - 2 * s * s * s)
        scene.hold[name] = (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
        scene.step()


@pytest.mark.slow
def test_mounted_grasper_holds_the_thread_it_closes_on_and_releases_it() -> None:
    """On the robot: the hook grasper's jaws closed 2 mm above the stitched start's tail
    hold it (it rises with the jaws); opened, they let go (it does not follow them up)."""
    model = _model("bench.yaml")
    scene = build_scene(model, seed=0, start="stitched")
    try:
        grasper = scene.tools["endobot_2"]
        assert isinstance(grasper, Grasper)
        tail = scene.suture.centerline()[1].copy()  # 7.5 mm from the tail's end
        _reach(scene, "endobot_2", tail + np.array([0.0, 0.0, 2e-3]))
        jaw, _ = grasper.pose()
        assert np.linalg.norm(np.asarray(jaw) - tail - np.array([0.0, 0.0, 2e-3])) < 1.5e-3
        grasper.close()
        for _ in range(200):
            scene.step()
        assert grasper.holding and grasper.held_segment in (0, 1)
        _reach(scene, "endobot_2", tail + np.array([0.0, 0.0, 0.02]))
        lifted = scene.suture.centerline()[grasper.held_segment]
        assert lifted[2] > 0.012
        grasper.open()
        for _ in range(200):
            scene.step()
        assert not grasper.holding
        dropped = scene.suture.centerline()[1].copy()
        _reach(scene, "endobot_2", tail + np.array([0.0, 0.0, 0.04]))
        # Released, the thread does not rise with the jaws (it relaxes back down).
        after = scene.suture.centerline()[1]
        assert after[2] <= dropped[2] + 1e-3
        assert np.asarray(grasper.pose()[0])[2] - after[2] > 0.02
    finally:
        scene.close()


def test_removed_posts_leave_the_world_once() -> None:
    """The backend's ``remove_posts`` (:func:`remove_posts` under it) parks the calibration
    posts far from the bench: nothing of the robots, tools or thread is near them any more,
    the body count is unchanged (ids kept), and a second removal is refused with its
    reason."""
    import pybullet as p

    from backends.base import BackendError
    from backends.pybullet.backend import StitchedSurgicalPyBulletBackend
    from suture_engine.language.loader import load_procedure

    square = ROOT / "procedures" / "square-knot.yaml"
    posts_model = load_procedure(square, params={"register": True}).scene
    be = StitchedSurgicalPyBulletBackend()
    try:
        be.reset(posts_model, 0)
        assert be.scene is not None
        bodies = dict(be.scene.posts)
        assert sorted(bodies) == sorted(posts_model.posts)
        count = p.getNumBodies(physicsClientId=be.client)
        for name, body in bodies.items():
            pos, _ = p.getBasePositionAndOrientation(body, physicsClientId=be.client)
            declared = np.asarray(posts_model.posts[name].position, float)
            assert np.linalg.norm(np.asarray(pos)[:2] - declared[:2]) < 1e-6
        assert be.remove_posts() == sorted(bodies)
        assert be.scene.posts == {}
        assert p.getNumBodies(physicsClientId=be.client) == count
        others = [
            b for b in range(p.getNumBodies(physicsClientId=be.client)) if b not in bodies.values()
        ]
        for body in bodies.values():
            pos, _ = p.getBasePositionAndOrientation(body, physicsClientId=be.client)
            assert np.linalg.norm(pos) > 40.0
            for other in others:
                near = p.getClosestPoints(body, other, 0.5, physicsClientId=be.client)
                assert not near, (body, other)
        for _ in range(20):
            be.step()
        with pytest.raises(BackendError, match="posts"):
            be.remove_posts()
    finally:
        be.close()


@pytest.mark.parametrize(
    ("gap", "depth", "scene_gap", "expected"),
    [
        (None, None, None, None),
        (0.0, None, None, 0.0),
        (1e-3, 0.4e-3, None, 1e-3),
        # the scene's tissue.wound.gap, unless the backend is given its own
        (None, None, 0.0, 0.0),
        (None, None, 0.5e-3, 0.5e-3),
        (1e-3, None, 0.0, 1e-3),
    ],
)
def test_the_backends_wound_parts_the_pads_halves(
    gap: float | None, depth: float | None, scene_gap: float | None, expected: float | None
) -> None:
    """The backend's ``wound_gap`` and ``wound_depth`` reach the pad: its two halves stand
    that far apart across the wound (PyBullet's own bounding boxes), 1 mm by default, and
    a floor fills the wound from that depth down. Without the backend's ``wound_gap``,
    the scene's ``tissue.wound.gap`` sets it."""
    import pybullet as p

    from backends.pybullet.backend import StitchedSurgicalPyBulletBackend
    from backends.pybullet.scene import PAD_SIZE
    from backends.pybullet.tissue import WOUND_GAP
    from suture_engine.language.loader import load_procedure

    model = load_procedure(ROOT / "procedures" / "square-knot.yaml").scene
    assert model.tissue.wound.gap is None  # the bundled scene leaves it to the pad
    if scene_gap is not None:
        wound = model.tissue.wound.model_copy(update={"gap": scene_gap})
        tissue = model.tissue.model_copy(update={"wound": wound})
        model = model.model_copy(update={"tissue": tissue})
    be = StitchedSurgicalPyBulletBackend(wound_gap=gap, wound_depth=depth)
    try:
        be.reset(model, 0)
        assert be.scene is not None and be.scene.tissue is not None
        boxes = [p.getAABB(b, physicsClientId=be.client) for b in be.scene.tissue.bodies]
        # the wound runs along x: the halves face each other across y
        halves = sorted((b for b in boxes if b[1][2] > -1e-6), key=lambda box: box[0][1])
        assert len(halves) == 2
        width = halves[1][0][1] - halves[0][1][1]
        assert width == pytest.approx(WOUND_GAP if expected is None else expected, abs=1e-6)
        floors = [b for b in boxes if b[1][2] <= -1e-6]
        if depth is None:
            assert floors == []
        else:
            (floor,) = floors
            assert floor[1][2] == pytest.approx(-depth, abs=1e-6)
            assert floor[0][2] == pytest.approx(-PAD_SIZE[2], abs=1e-6)
            assert floor[0][1] == pytest.approx(halves[0][1][1], abs=1e-6)
            assert floor[1][1] == pytest.approx(halves[1][0][1], abs=1e-6)
    finally:
        be.close()


@pytest.mark.parametrize("depth", [None, 1e-4])
def test_the_backends_pad_clear_depth_reaches_the_pad(depth: float | None) -> None:
    """The backend's ``pad_clear_depth`` is the tissue pad's ``clear_depth``, None (no
    wait) by default."""
    from backends.pybullet.backend import StitchedSurgicalPyBulletBackend
    from suture_engine.language.loader import load_procedure

    model = load_procedure(ROOT / "procedures" / "square-knot.yaml").scene
    be = StitchedSurgicalPyBulletBackend(pad_clear_depth=depth)
    try:
        be.reset(model, 0)
        assert be.scene is not None and be.scene.tissue is not None
        assert be.scene.tissue.clear_depth == depth
    finally:
        be.close()


def test_the_backend_refuses_a_negative_pad_clear_depth() -> None:
    from backends.base import BackendError
    from backends.pybullet.backend import StitchedSurgicalPyBulletBackend

    with pytest.raises(BackendError, match="pad_clear_depth"):
        StitchedSurgicalPyBulletBackend(pad_clear_depth=-1e-4)
