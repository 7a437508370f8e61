"""The PyBullet backend with the surgical scene: tools driven by tool commands, ground truth
of the thread in the trace, the knot entry of the summary, nothing of it in observations."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from backends.pybullet.backend import (
    PyBulletBackend,
    StitchedSurgicalPyBulletBackend,
    SurgicalPyBulletBackend,
)
from backends.pybullet.tools import Grasper, JawState, Stitcher
from suture_engine.language.loader import load_procedure
from suture_engine.robot.endobot import gravity_vector
from suture_engine.runtime.observation import Command, RobotCommand, ToolCommand
from suture_engine.runtime.run import run_procedure

PROCS = Path(__file__).resolve().parent / "procedures"
BENCH = PROCS.parent.parent / "procedures" / "shared-control-line.yaml"  # hook grasper


@pytest.fixture(scope="module")
def scene_model():  # type: ignore[no-untyped-def]
    return load_procedure(PROCS / "reach.yaml").scene


def _hold(be: PyBulletBackend, tools: dict[str, ToolCommand], ticks: int) -> None:
    """Gravity-compensating torques with the given tool commands, for some ticks."""
    for _ in range(ticks):
        obs = be.observe()
        cmds = {}
        for name, sim in be.robots.items():
            tau = gravity_vector(np.asarray(obs.robots[name].q), sim.model_params)
            cmds[name] = RobotCommand.torque(tau, tools.get(name))
        be.apply(Command(cmds))
        be.step()


def test_tool_commands_drive_the_simulated_tools() -> None:
    be = SurgicalPyBulletBackend()
    try:
        be.reset(load_procedure(BENCH).scene, 0)
        assert be.scene is not None
        grasper, stitcher = be.scene.tools["endobot_2"], be.scene.tools["endobot_1"]
        assert isinstance(grasper, Grasper) and isinstance(stitcher, Stitcher)
        # the tail-held start: the grasper holds the thread's free end, the needle is in jaw 0
        assert grasper.state is JawState.CLOSED and grasper.held_segment == 0
        assert stitcher.needle_holder == 0
        # Stitcher: close the needle's jaw, then the other one: the needle is handed over
        # (the thread slack from the start; after the grasper below has let go of the
        # thread's end and closed again, the hand-over would pull a taut strand: it stops
        # short at the hand-over drive's 5 N, where the former 50 N drive drew 24.9 N).
        _hold(be, {"endobot_1": ToolCommand(jaw_closed=True, jaw2_closed=False)}, 200)
        assert stitcher.needle_holder == 0
        _hold(be, {"endobot_1": ToolCommand(jaw_closed=True, jaw2_closed=True)}, 400)
        assert stitcher.needle_holder == 1 and not stitcher.stalls
        _hold(be, {"endobot_2": ToolCommand(jaw_closed=False)}, 400)
        assert grasper.state is JawState.OPEN and grasper.held_segment == -1
        _hold(be, {"endobot_2": ToolCommand(jaw_closed=True, hook_extension=0.01)}, 400)
        assert grasper.state is JawState.CLOSED
        assert grasper.hook_extension == pytest.approx(1.0)  # extended over the hinge
        _hold(be, {"endobot_2": ToolCommand(jaw_closed=False, hook_extension=0.0)}, 400)
        assert grasper.state is JawState.OPEN and grasper.hook_extension == pytest.approx(0.0)
        # The hook skill ramps its setpoint and ends within its tolerance: a command that
        # moves in retracts the hook fully even if it never reaches 0.
        _hold(be, {"endobot_2": ToolCommand(hook_extension=0.005)}, 400)
        assert grasper.hook_extension == pytest.approx(1.0)
        _hold(be, {"endobot_2": ToolCommand(hook_extension=0.0049)}, 400)
        assert grasper.hook_extension == pytest.approx(0.0)
    finally:
        be.close()


def test_the_graspers_jaw_reading_is_its_valve_and_the_jaws_shut_one_travel_later() -> None:
    """The grasper is pneumatic (thesis 4.4: commanded open or closed, no jaw sensor): its
    measured ``jaw_closed`` turns true on the tick the jaw is commanded shut, while the
    jaws themselves take the tool's travel time to close on the thread. A skill that acts
    on a grasp must wait that travel (``grasp``'s ``dwell``)."""
    be = SurgicalPyBulletBackend()
    try:
        be.reset(load_procedure(BENCH).scene, 0)
        assert be.scene is not None
        grasper = be.scene.tools["endobot_2"]
        assert isinstance(grasper, Grasper) and grasper.holding  # the tail-held start
        _hold(be, {"endobot_2": ToolCommand(jaw_closed=False)}, 400)
        assert not be.observe().robots["endobot_2"].tool.jaw_closed and not grasper.holding
        # close it where it let go: the thread's end still lies between the jaws
        _hold(be, {"endobot_2": ToolCommand(jaw_closed=True)}, 1)
        assert be.observe().robots["endobot_2"].tool.jaw_closed
        assert grasper.state is JawState.CLOSING and not grasper.holding
        ticks = 1
        while not grasper.holding:
            assert be.observe().robots["endobot_2"].tool.jaw_closed
            _hold(be, {"endobot_2": ToolCommand(jaw_closed=True)}, 1)
            ticks += 1
            assert ticks <= 2 * round(grasper.travel_time / be.dt)
        assert grasper.state is JawState.CLOSED
        assert ticks == pytest.approx(round(grasper.travel_time / be.dt), abs=1)
    finally:
        be.close()


def test_ground_truth_has_the_thread_and_observations_do_not(scene_model) -> None:  # type: ignore[no-untyped-def]
    be = SurgicalPyBulletBackend()
    try:
        first = be.reset(scene_model, 0)
        truth = be.ground_truth()
        line = np.asarray(truth["centerline"])
        assert line.ndim == 2 and line.shape[1] == 3 and len(line) >= 40
        # The thread's length along its centerline is the scene's 300 mm (within a capsule).
        length = float(np.sum(np.linalg.norm(np.diff(line, axis=0), axis=1)))
        assert length == pytest.approx(0.3, abs=0.01)
        assert truth["tension_N"] >= 0.0
        fields = {f.name for f in dataclasses.fields(first)}
        for robot in first.robots.values():
            fields |= {f.name for f in dataclasses.fields(robot)}
        assert not fields & {"centerline", "tension_N", "ground_truth"}
    finally:
        be.close()


def test_plain_backend_builds_robots_only(scene_model) -> None:  # type: ignore[no-untyped-def]
    be = PyBulletBackend()
    try:
        be.reset(scene_model, 0)
        assert be.scene is None and "centerline" not in be.ground_truth()
    finally:
        be.close()


def test_run_records_ground_truth_and_fills_the_knot(tmp_path: Path) -> None:
    from suture_engine.trace.reader import TraceReader

    result = run_procedure(
        PROCS / "skills-grasp-rotate.yaml", backend="pybullet-surgical", out=tmp_path / "d"
    )
    summary = json.loads(result.summary_path.read_text())
    assert summary["outcome"] == "succeeded"
    # Grasp, rotate and release tie nothing: the classifier must call the thread unknotted.
    knot = summary["knot"]
    assert knot is not None and knot["type"] == "unknot" and knot["crossings"] == 0
    topics = {m.topic for m in TraceReader(result.trace).messages()}
    assert {"/ground_truth/suture", "/ground_truth/tension"} <= topics
    # where the true tension peaked: kept live by the run, and read back from its trace
    at = summary["metrics"]["peak_true_tension_at"]
    from suture_engine.runtime.evaluation import evaluate_trace

    again = evaluate_trace(result.trace, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    assert at == again.metrics["peak_true_tension_at"]
    assert summary["metrics"]["peak_true_tension_N"] == again.metrics["peak_true_tension_N"]
    states = {m.data["dest"] for m in TraceReader(result.trace).messages(["/transitions"])}
    assert 1 <= at["joint"] <= 39 and at["state"] in states
    plain = run_procedure(PROCS / "steps.yaml", backend="pybullet", out=tmp_path / "p")
    assert plain.summary.knot is None


def test_first_measurement_is_at_rest_so_the_tare_is_steady() -> None:
    """The runtime tares the base sensors on the first measurement: it must not be taken
    during the thread's and tools' start-up transient. Held still for 0.3 s more, the base
    force must stay where the first measurement put it."""
    be = SurgicalPyBulletBackend()
    try:
        first = be.reset(load_procedure(BENCH).scene, 0)
        _hold(be, {}, 300)
        later = be.observe()
        for name in first.robots:
            drift = np.asarray(later.robots[name].base_wrench[:3]) - np.asarray(
                first.robots[name].base_wrench[:3]
            )
            assert float(np.linalg.norm(drift)) < 0.5, (name, drift)
    finally:
        be.close()


def test_stitched_backend_starts_with_the_stitch_made_and_the_needle_held() -> None:
    """``pybullet-surgical-stitched`` (the registry name of ``start="stitched"``): the thread
    is threaded through the tissue at reset, and the measured tool state is the physical
    one: the stitcher's jaw 1 (the -x jaw, ``needle_holder`` 0) is closed on the needle,
    jaw 2 open; the hook grasper's jaws open, hook retracted."""
    from backends import registry

    be = registry.create("pybullet-surgical-stitched")
    assert isinstance(be, SurgicalPyBulletBackend) and be.start == "stitched"
    try:
        first = be.reset(load_procedure(BENCH).scene, 0)
        assert be.scene is not None and be.scene.tissue is not None
        assert be.scene.tissue.suture is be.scene.suture and len(be.scene.tissue.inside) >= 1
        stitcher, grasper = be.scene.tools["endobot_1"], be.scene.tools["endobot_2"]
        assert isinstance(stitcher, Stitcher) and isinstance(grasper, Grasper)
        tool = first.robots["endobot_1"].tool
        assert stitcher.opening == 0.0 and stitcher.needle_holder == 0
        assert (tool.kind, tool.jaw_closed, tool.jaw2_closed) == ("stitcher", True, False)
        hook = first.robots["endobot_2"].tool
        assert grasper.state is JawState.OPEN and grasper.hook_extension == 0.0
        # The stitcher starts where the stitch's pull (4.3) ends: its tip l_d = 40 mm along
        # the normal from the exit point (the simulator's tool frame), and the thread runs
        # from the exit to the needle in its jaw.
        from backends.pybullet.scene import STITCHED_PULL

        pulled = np.array([0.0, 4e-3, STITCHED_PULL])  # above the bench's exit_2
        tip = np.asarray(be.robots["endobot_1"].true_tool_pose()[0])
        assert np.linalg.norm(tip - pulled) < 1e-3
        line = be.scene.suture.centerline()
        assert np.linalg.norm(line[-1] - tip) < 8e-3  # the needle's end, in jaw 0
        assert (hook.jaw_closed, hook.hook_extension) == (False, 0.0)
        # Commanding the state it reports changes nothing; closing jaw 2 as well passes
        # the needle (Fig. 4.3), and the report follows the physics.
        _hold(be, {"endobot_1": ToolCommand(jaw_closed=True)}, 50)
        assert stitcher.needle_holder == 0 and not stitcher.passing
        _hold(be, {"endobot_1": ToolCommand(jaw_closed=True, jaw2_closed=True)}, 50)
        # The receiving jaw reads closed only once the needle is in it (0.2 s hand-over).
        assert stitcher.passing and not be.observe().robots["endobot_1"].tool.jaw2_closed
        _hold(be, {"endobot_1": ToolCommand(jaw_closed=True, jaw2_closed=True)}, 250)
        assert stitcher.needle_holder == 1 and be.observe().robots["endobot_1"].tool.jaw2_closed
        _hold(be, {"endobot_1": ToolCommand(jaw_closed=False, jaw2_closed=True)}, 50)
        assert stitcher.needle_holder == 1 and stitcher.opening == 0.0
        # Asked while the jaws are still closing, the hand-over waits for them.
        _hold(be, {"endobot_1": ToolCommand(jaw_closed=False, jaw2_closed=False)}, 300)
        assert stitcher.opening == 1.0
        _hold(be, {"endobot_1": ToolCommand(jaw_closed=False, jaw2_closed=True)}, 10)
        _hold(be, {"endobot_1": ToolCommand(jaw_closed=True, jaw2_closed=True)}, 500)
        assert stitcher.needle_holder == 0 and not stitcher.passing
    finally:
        be.close()


def test_needle_start_reports_the_stitcher_closed_on_the_needle_too(scene_model) -> None:  # type: ignore[no-untyped-def]
    be = SurgicalPyBulletBackend()
    try:
        first = be.reset(load_procedure(BENCH).scene, 0)
        tool = first.robots["endobot_1"].tool
        assert (tool.jaw_closed, tool.jaw2_closed) == (True, False)
        assert be.scene is not None and be.scene.tissue is not None
        assert be.scene.tissue.suture is None  # not threaded: the bite is still to be made
    finally:
        be.close()


def test_bad_start_is_a_backend_error() -> None:
    from backends.base import BackendError

    be = SurgicalPyBulletBackend(start="knotted")
    try:
        with pytest.raises(BackendError) as err:
            be.reset(load_procedure(BENCH).scene, 0)
        assert "suture.start" in str(err.value)
    finally:
        be.close()


@pytest.mark.slow
def test_stitch_procedure_passes_the_needle_through_the_tissue(tmp_path: Path) -> None:
    """``procedures/stitch.yaml`` on the surgical backend: the bite no longer locks where the
    needle meets the tissue; the thread ends up through the tissue between entry_2 and
    exit_2 (ground truth) and the estimated tension stays under the 3 N invariant."""
    from suture_engine.trace.reader import TraceReader

    root = PROCS.parent.parent / "procedures"
    result = run_procedure(
        root / "stitch.yaml", backend="pybullet-surgical", seed=1, out=tmp_path / "st"
    )
    summary = json.loads(result.summary_path.read_text())
    assert summary["outcome"] == "succeeded" and not summary["violations"]
    assert summary["max_tension_N"] < 3.0
    last = None
    for m in TraceReader(result.trace).messages():
        if m.topic == "/ground_truth/suture":
            last = m.data
    assert last is not None
    line = np.stack([last["x"], last["y"], last["z"]], axis=1)
    # Between the bite's entry and exit points (y = -4 and 4 mm, x = 0), over the pad,
    # the thread runs below the surface.
    over = (np.abs(line[:, 0]) < 6e-3) & (np.abs(line[:, 1]) < 4e-3)
    assert over.any() and line[over, 2].min() < -1e-3
    for point in ((0.0, -4e-3, 0.0), (0.0, 4e-3, 0.0)):
        assert np.linalg.norm(line - np.asarray(point), axis=1).min() < 6e-3


def test_inject_grasp_slip_drops_what_the_jaw_holds_and_only_the_needle_latch_shows_it() -> None:
    be = SurgicalPyBulletBackend(start="stitched")
    try:
        be.reset(load_procedure(BENCH).scene, 0)
        assert be.scene is not None
        stitcher, grasper = be.scene.tools["endobot_1"], be.scene.tools["endobot_2"]
        assert isinstance(stitcher, Stitcher) and isinstance(grasper, Grasper)
        # The grasper holds nothing yet: nothing to lose.
        assert be.inject_grasp_slip("endobot_2") is False
        # Its jaws (taken off the robot here, to put them on the tail without a motion
        # planner) closed 1 mm above the tail's axis catch a capsule...
        tail = be.scene.suture.centerline()[1]
        import pybullet as p

        grasper_free = be.scene.tools["endobot_2"]
        p.removeConstraint(grasper_free.drive, physicsClientId=be.client)
        grasper_free._mounted = False
        grasper_free._drive_to_world(
            (float(tail[0]), float(tail[1]), float(tail[2]) + 1e-3), (1.0, 0.0, 0.0, 0.0)
        )
        _hold(be, {"endobot_2": ToolCommand(jaw_closed=True)}, 200)
        assert grasper.holding
        # ...and a slip loses it while the jaws stay closed, as the tool state says.
        assert be.inject_grasp_slip("endobot_2") is True
        assert not grasper.holding and grasper.state is JawState.CLOSED
        assert be.observe().robots["endobot_2"].tool.jaw_closed
        # The stitcher's jaw loses the needle: it falls away from the jaw on its thread, and
        # a commanded hand-over then passes nothing. Its jaws read closed on the needle
        # latched in them: with the needle gone neither does, whatever is commanded (the
        # grasper's jaws, above, cannot feel a thread).
        assert be.observe().robots["endobot_1"].tool.jaw_closed
        assert be.inject_grasp_slip("endobot_1") is True and not stitcher.holds_needle
        tool = be.observe().robots["endobot_1"].tool
        assert not tool.jaw_closed and not tool.jaw2_closed
        _hold(be, {"endobot_1": ToolCommand(jaw_closed=True, jaw2_closed=True)}, 300)
        assert stitcher.needle_holder == 0 and not stitcher.passing
        tool = be.observe().robots["endobot_1"].tool
        assert not tool.jaw_closed and not tool.jaw2_closed
        assert be.inject_grasp_slip("endobot_1") is False
        with pytest.raises(Exception, match="no robot"):
            be.inject_grasp_slip("endobot_9")
    finally:
        be.close()


def test_inject_snag_raises_the_channel_friction_for_its_duration() -> None:
    """Snag: with the stitched thread in the channel, the friction the anchors can apply (the
    static cap F_s (4.5)) rises by the snag's extra force for its duration, then returns."""
    from backends.base import BackendError

    be = SurgicalPyBulletBackend(start="stitched")
    try:
        be.reset(load_procedure(BENCH).scene, 0)
        assert be.scene is not None and be.scene.tissue is not None
        tissue = be.scene.tissue

        def cap() -> float:
            return float(tissue.f_static + tissue._snag_extra)

        assert cap() == pytest.approx(0.3)
        be.inject_snag(2.0, 0.05)
        _hold(be, {}, 20)
        assert cap() == pytest.approx(2.3)
        _hold(be, {}, 40)
        assert cap() == pytest.approx(0.3)
        with pytest.raises(BackendError):
            be.inject_snag(-1.0, 0.1)
    finally:
        be.close()


def test_bend_option_bends_the_mounted_bent_tip_grasper() -> None:
    """``bend=(bx, by)``: the mounted bent-tip grasper's jaws sit at link (x) T(0, 0, -L)
    Rx(bx) Ry(by) T(0, 0, L) (L = tip_length; checked with scipy's rotations) and follow the
    robot; unbent, they sit on the tool link."""
    from scipy.spatial.transform import Rotation

    from backends.pybullet.tools import BentTipGrasper

    scene = load_procedure(PROCS.parent.parent / "procedures" / "knot-algorithm-3.yaml").scene
    be = SurgicalPyBulletBackend(bend=(1.2, -0.3))
    try:
        be.reset(scene, 0)
        assert be.scene is not None
        name = next(n for n, t in be.scene.tools.items() if isinstance(t, BentTipGrasper))
        tool = be.scene.tools[name]
        _hold(be, {}, 100)
        link, link_q = be.robots[name].true_tool_pose()
        jaw, jaw_q = tool.pose()
        r_link = Rotation.from_quat(np.asarray(link_q))
        bend = Rotation.from_euler("XY", [1.2, -0.3])
        expected = (
            np.asarray(link)
            + r_link.apply([0.0, 0.0, -tool.tip_length])
            + (r_link * bend).apply([0.0, 0.0, tool.tip_length])
        )
        assert np.linalg.norm(np.asarray(jaw) - expected) < 3e-4
        assert ((Rotation.from_quat(np.asarray(jaw_q)) * (r_link * bend).inv()).magnitude()) < 1e-2
        assert np.linalg.norm(np.asarray(jaw) - np.asarray(link)) > 5e-3
    finally:
        be.close()


def _tips(be: PyBulletBackend) -> dict[str, np.ndarray]:
    return {n: np.asarray(be.ground_truth()[f"{n}/tool_tip"]) for n in be.robots}


@pytest.mark.parametrize("surgical", [False, True])
def test_base_error_moves_the_actual_base_not_the_declared_one(surgical: bool) -> None:
    scene = load_procedure(BENCH).scene
    error = (0.002, -0.001, 0.0005)
    cls = SurgicalPyBulletBackend if surgical else PyBulletBackend
    nominal, shifted = cls(), cls(base_error={"endobot_1": error})
    try:
        nominal.reset(scene, 0)
        shifted.reset(scene, 0)
        a, b = _tips(nominal), _tips(shifted)
        # Same joints, base displaced: the true tool tip moves by the displacement.
        assert np.allclose(b["endobot_1"] - a["endobot_1"], error, atol=2e-5)
        # endobot_2's base is where it was declared; on the surgical backend its jaws start
        # on the thread's free end, which the displaced needle's thread moves a little
        assert np.allclose(b["endobot_2"], a["endobot_2"], atol=1e-3 if surgical else 2e-5)
        if surgical:
            assert not np.allclose(b["endobot_2"], a["endobot_2"], atol=2e-5)
        # What the skills are told (the declared geometry) is unchanged.
        assert dict(nominal.geometry().base_positions) == dict(shifted.geometry().base_positions)
        assert shifted.geometry().base_positions["endobot_1"] == pytest.approx((-0.07, -0.05, 0.12))
    finally:
        nominal.close()
        shifted.close()
    from backends.base import BackendError

    with pytest.raises(BackendError, match="unknown robots"):
        cls(base_error={"endobot_7": error}).reset(scene, 0)


def _drift(friction_scale: float, friction: bool = True) -> np.ndarray:
    """Joint motion [rad, rad, rad, m] after 0.3 s of gravity compensation plus a small
    constant torque on every joint (robots only)."""
    be = PyBulletBackend(friction=friction, friction_scale=friction_scale)
    try:
        first = be.reset(load_procedure(BENCH).scene, 0)
        sim = be.robots["endobot_1"]
        push = np.array([0.05, 0.05, 0.005, 0.5])
        for _ in range(300):
            q = np.asarray(be.observe().robots["endobot_1"].q)
            tau = gravity_vector(q, sim.model_params) + push
            be.apply(Command({"endobot_1": RobotCommand.torque(tau)}))
            be.step()
        return np.asarray(be.observe().robots["endobot_1"].q) - first.robots["endobot_1"].q
    finally:
        be.close()


def test_friction_scale_changes_the_joint_friction() -> None:
    """Less friction, more motion under the same torques; a zero scale is the same as no
    friction at all (an independent switch)."""
    full, reduced = _drift(1.0), _drift(0.5)
    assert np.all(np.abs(reduced) >= np.abs(full) - 1e-9)
    assert np.linalg.norm(reduced - full) > 1e-4
    assert np.allclose(_drift(0.0), _drift(1.0, friction=False), atol=1e-9)


def test_suture_stiffness_options_reach_the_thread() -> None:
    be = SurgicalPyBulletBackend(suture_bending_stiffness=1e-6, suture_stiffness_scale=1.2)
    try:
        be.reset(load_procedure(BENCH).scene, 0)
        assert be.scene is not None
        assert be.scene.suture.params.bending_stiffness == pytest.approx(1.2e-6)
    finally:
        be.close()


@pytest.mark.parametrize(
    ("declared", "options", "damping", "weight_g"),
    [
        ({}, {}, 0.5, 0.1),  # the thread's defaults
        ({"damping": 20.0, "weight": 4e-3}, {}, 20.0, 4.0),  # the scene's model
        ({"damping": 20.0, "weight": 4e-3}, {"thread_damping": 7.0}, 7.0, 4.0),  # a flag wins
    ],
)
def test_the_run_names_the_thread_model_it_built(
    declared: dict[str, float], options: dict[str, float], damping: float, weight_g: float
) -> None:
    """``run_metrics()["thread"]`` reports the thread the run built: the defaults, else
    the scene's ``suture.damping`` and ``suture.weight``, else the backend's options; its
    capsules and their mass as the simulator holds them."""
    import pybullet as p

    scene = load_procedure(BENCH).scene
    scene = scene.model_copy(update={"suture": scene.suture.model_copy(update=declared)})
    be = SurgicalPyBulletBackend(**options)
    try:
        be.reset(scene, 0)
        assert be.scene is not None and be.scene.suture is not None
        model = be.run_metrics()["thread"]
        body = be.scene.suture.bodies[0]
        mass = p.getDynamicsInfo(body, -1, physicsClientId=be.client)[0]  # [kg]
        n = len(be.scene.suture.bodies)
        length = float(scene.suture.length)
        assert model["capsules"] == n
        assert model["capsule_mm"] == pytest.approx(1e3 * length / n)
        assert model["damping_per_s"] == pytest.approx(damping)
        assert model["weight_g_per_m"] == pytest.approx(weight_g)
        assert model["simulated_g_per_m"] == pytest.approx(1e3 * mass / (length / n))
        assert model["smooth_joints"] is False and model["contact_stiffness_N_per_m"] is None
    finally:
        be.close()


def test_ground_truth_is_read_on_look_up_and_matches_the_simulator() -> None:
    """The lazy ground truth gives the same values as reading the simulator directly, and
    only the keys asked for are computed."""
    be = SurgicalPyBulletBackend()
    try:
        be.reset(load_procedure(BENCH).scene, 0)
        assert be.scene is not None
        truth = be.ground_truth()
        assert set(truth) == {
            "endobot_1/tool_tip",
            "endobot_2/tool_tip",
            "centerline",
            "tension_N",
            "tension_joint",
            "contact_diameter",
        }
        assert truth["contact_diameter"] == pytest.approx(
            2 * be.scene.suture.params.collision_radius
        )
        assert np.allclose(truth["centerline"], be.scene.suture.centerline())
        tensions = be.scene.suture.tensions()
        assert truth["tension_N"] == pytest.approx(float(tensions.max()))
        # the joint it acts at, as a point of the centerline: capsules i and i + 1 meet at i + 1
        assert truth["tension_joint"] == 1 + int(np.argmax(tensions))
        tip, _ = be.robots["endobot_1"].true_tool_pose()
        assert np.allclose(truth["endobot_1/tool_tip"], tip)
        assert set(truth._values) == {
            "centerline",
            "tension_N",
            "tension_joint",
            "endobot_1/tool_tip",
            "contact_diameter",
        }  # endobot_2/tool_tip was never looked up: never read
    finally:
        be.close()


def test_both_backends_start_the_grasper_on_the_needle_starts_tail_end() -> None:
    """The tail-held start: the surgical backend's first grasper holds the thread's free end
    30 mm out of the entry point, away from the exit; the robots-only backend, with no
    thread, starts the same grasper at that nominal point, so that a procedure starts from
    the same poses on both. Checked against the declared entry and exit points."""
    scene = load_procedure(PROCS.parent.parent / "procedures" / "stitch.yaml").scene
    points = dict(scene.tissue.points)
    entry, exit_ = np.asarray(points["entry_2"]), np.asarray(points["exit_2"])
    out = (entry - exit_) / np.linalg.norm(entry - exit_)
    robots, surgical = PyBulletBackend(), SurgicalPyBulletBackend()
    try:
        robots.reset(scene, 0)
        surgical.reset(scene, 0)
        tip = _tips(robots)["endobot_2"]
        # 30 mm out less half a capsule (the jaws sit on the end capsule), just above it
        along = float((tip - entry) @ out)
        assert 0.025 < along < 0.03
        assert np.linalg.norm(tip - entry - along * out) < 4e-3
        # the surgical grasper holds the end capsule as laid, a few mm from that point
        assert np.linalg.norm(_tips(surgical)["endobot_2"] - tip) < 6e-3
        assert surgical.scene is not None
        assert surgical.scene.tools["endobot_2"].held_segment == 0  # type: ignore[attr-defined]
        # the stitcher starts where it always did, on both
        assert np.allclose(_tips(robots)["endobot_1"], _tips(surgical)["endobot_1"], atol=2e-3)
    finally:
        robots.close()
        surgical.close()


def test_both_backends_start_the_stitcher_with_the_needle_in_jaw_1() -> None:
    """Every surgical start has the needle in the stitcher's jaw 1 (the stitched start
    included); the robots-only backend, with no needle, reports the same jaws, so that a
    procedure that starts by passing the needle (a knot on a stitch already made) runs
    on both."""
    scene = load_procedure(PROCS.parent.parent / "procedures" / "stitch.yaml").scene
    backends = (PyBulletBackend(), SurgicalPyBulletBackend(), StitchedSurgicalPyBulletBackend())
    try:
        for be in backends:
            tool = be.reset(scene, 0).robots["endobot_1"].tool
            assert (tool.kind, tool.jaw_closed, tool.jaw2_closed) == ("stitcher", True, False)
            # and stays so until a command opens it
            assert be.observe().robots["endobot_1"].tool.jaw_closed
    finally:
        for be in backends:
            be.close()
