"""The ``bend`` skill and the bent-tip grasper's universal joint through every backend.

The joint's rate limit is checked against its closed form (angle = min(rate t, goal)),
the bent arm's direction from the encoders (:func:`skills.wrap.bent_arm`) against
scipy's rotations and against the simulator's own jaw pose, and the trace's
``/tool_state`` channel against what the backend measured.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skills.bend import Bend, BendParams
from suture_engine.runtime.observation import (
    Command,
    CommandMode,
    RobotCommand,
    ToolCommand,
)

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "procedures" / "scenes" / "bench-bent-tip.yaml"

PROCEDURE = """\
procedure: bend-test
version: "1"
description: Bend the grasper's universal joint, then straighten it.
scene: scenes/bench-bent-tip.yaml
roles: {{holder: endobot_1, grasper: endobot_2}}
initial: bend
states:
  bend:
    skill: bend
    with: {{robot: {robot}, angles: [20 deg, -60 deg], travel: 0.5 s}}
    timeout: 3 s
    on: {{done: straighten, failed: {{retry: 0, then: lock}}}}
  straighten:
    skill: bend
    with: {{robot: {robot}, angles: [0 deg, 0 deg]}}
    timeout: 3 s
    on: {{done: done, failed: {{retry: 0, then: lock}}}}
  done: {{outcome: succeeded}}
"""


def write_procedure(folder: Path, robot: str = "grasper") -> Path:
    (folder / "scenes").mkdir(parents=True, exist_ok=True)
    shutil.copy(SCENE, folder / "scenes" / SCENE.name)
    shutil.copy(SCENE.parent / "bench.yaml", folder / "scenes" / "bench.yaml")  # it extends
    path = folder / "bend.yaml"
    path.write_text(PROCEDURE.format(robot=robot))
    return path


# ------------------------------------------------------------------------- parameters
def test_angles_take_units_and_a_range() -> None:
    p = BendParams.model_validate({"robot": "grasper", "angles": ["90 deg", "-30 deg"]})
    assert p.angles == pytest.approx((math.pi / 2, -math.pi / 6))
    with pytest.raises(ValueError, match="within"):
        BendParams.model_validate({"robot": "grasper", "angles": ["150 deg", "0 deg"]})
    with pytest.raises(ValueError):
        BendParams.model_validate({"robot": "grasper", "angles": ["10 deg"]})


def test_validation_refuses_a_tool_without_a_universal_joint(tmp_path: Path) -> None:
    from suture_engine.validation.checks import validate_file

    assert validate_file(write_procedure(tmp_path / "ok")) == []
    problems = validate_file(write_procedure(tmp_path / "bad", robot="holder"))
    assert problems and {p.code for p in problems} == {"tool-mismatch"}
    assert "bent-tip-grasper" in problems[0].message


# ---------------------------------------------------------------------- ideal backend
def run(folder: Path, backend: str, **options: Any) -> tuple[dict[str, Any], Any]:
    from suture_engine.runtime.run import run_procedure
    from suture_engine.trace.reader import TraceReader

    out = folder / "run"
    run_procedure(
        write_procedure(folder),
        backend=backend,
        out=out,
        max_time_s=8.0,
        backend_options=options or None,
    )
    summary = json.loads((out / "summary.json").read_text())
    return summary, TraceReader(out / "trace.mcap")


def bends(trace: Any, robot: str = "endobot_2") -> list[tuple[float, list[float]]]:
    return [
        (m.log_time_ns * 1e-9, m.data["bend"]) for m in trace.messages([f"/tool_state/{robot}"])
    ]


def test_ideal_backend_bends_and_straightens_and_the_trace_records_it(tmp_path: Path) -> None:
    summary, trace = run(tmp_path, "ideal", tools={"endobot_2": "bent-tip-grasper"})
    assert summary["outcome"] == "succeeded"
    rec = bends(trace)
    goal = [math.radians(20.0), math.radians(-60.0)]
    # the setpoint ramps in 0.5 s and the ideal joint follows it a tick later; the skill
    # is done once both axes are within 1 deg: axis 1 (60 deg in 0.5 s) at 0.5 (59/60) s
    tol = math.radians(1.0)
    reached = next(t for t, b in rec if np.allclose(b, goal, rtol=0.0, atol=tol))
    assert reached == pytest.approx(0.5 * 59 / 60, abs=3e-3)
    assert max(abs(b[1]) for _, b in rec) == pytest.approx(math.radians(60.0), abs=tol)
    # the ramp is linear at goal / 0.5 s, one tick behind the command
    ramp = [(t, b[1]) for t, b in rec if 0.05 < t < 0.45]
    slope, offset = np.polyfit([t for t, _ in ramp], [b for _, b in ramp], 1)
    assert slope == pytest.approx(goal[1] / 0.5, rel=1e-6)
    assert -offset / slope == pytest.approx(0.001, abs=1.5e-3)  # starts within a tick
    assert rec[-1][1] == pytest.approx([0.0, 0.0], abs=math.radians(1.0))
    assert not list(trace.messages(["/tool_state/endobot_1"]))  # never bent: nothing written


def test_ideal_backend_without_the_joint_fails(tmp_path: Path) -> None:
    summary, trace = run(tmp_path, "ideal")  # endobot_2 reports a plain grasper
    assert summary["outcome"] == "failed"
    faults = [m.data for m in trace.messages(["/events"]) if m.data["kind"] == "unpredictable"]
    assert "no universal joint" in faults[0]["detail"]


def test_replay_serves_the_recorded_bend(tmp_path: Path) -> None:
    from backends.replay import ReplayBackend

    _, trace = run(tmp_path, "ideal", tools={"endobot_2": "bent-tip-grasper"})
    rec = bends(trace)
    be = ReplayBackend(tmp_path / "run" / "trace.mcap")
    served = [be.reset().robots["endobot_2"].tool.bend]
    while not be.exhausted:
        be.step()
        if be.exhausted:
            break
        served.append(be.observe().robots["endobot_2"].tool.bend)
    ticks = {round(t * 1000): b for t, b in rec}
    last = (0.0, 0.0)
    for k, bend in enumerate(served):
        last = tuple(ticks.get(k, last))  # type: ignore[assignment]
        assert bend == last
    assert served[-1] == tuple(rec[-1][1])


# --------------------------------------------------------------------- pybullet backends
def _step(be: Any, robot: str, bend: tuple[float, float] | None, n: int) -> list[Any]:
    out = []
    for _ in range(n):
        meas = be.observe()
        cmd = {
            name: RobotCommand(
                CommandMode.TORQUE,
                tau=np.zeros(4),
                tool=ToolCommand(bend=bend) if name == robot else None,
            )
            for name in meas.robots
        }
        be.apply(Command(cmd))
        be.step()
        out.append(be.observe().robots[robot].tool.bend)
    return out


def test_pybullet_joint_moves_at_its_rate_and_only_on_a_bent_tip_grasper() -> None:
    from backends.pybullet.backend import PyBulletBackend
    from suture_engine.language.loader import load_procedure

    scene = load_procedure(ROOT / "procedures" / "knot-algorithm-3.yaml").scene
    be = PyBulletBackend()
    try:
        be.reset(scene, 0)
        goal = (0.3, -0.5)
        got = np.array(_step(be, "endobot_2", goal, 400))
        t = np.arange(1, 401) * be.dt
        expected = np.stack([np.minimum(be.BEND_RATE * t, abs(g)) * np.sign(g) for g in goal], 1)
        np.testing.assert_allclose(got, expected, atol=1e-9)
        # the plain grasper (endobot_1) has no universal joint: it stays straight
        assert _step(be, "endobot_1", goal, 5)[-1] == (0.0, 0.0)
    finally:
        be.close()


def test_surgical_jaws_turn_with_the_measured_bend() -> None:
    """On the bench-bent-tip scene the commanded bend is reached and the simulated jaws
    sit where :func:`skills.wrap.bent_arm` says, from the encoders and measured bend."""
    from backends.pybullet.backend import StitchedSurgicalPyBulletBackend
    from skills.wrap import BENT_ARM, bent_arm
    from suture_engine.language.loader import load_procedure

    scene = load_procedure(ROOT / "procedures" / "knot-algorithm-3.yaml").scene
    assert scene is not None
    be = StitchedSurgicalPyBulletBackend()
    try:
        be.reset(scene, 1)
        goal = (0.0, -math.pi / 2)
        got = _step(be, "endobot_2", goal, 900)
        assert got[-1] == pytest.approx(goal)
        # about 0.785 s at 2 rad/s
        assert next(i for i, b in enumerate(got) if b == goal) == pytest.approx(785, abs=2)
        meas = be.observe().robots["endobot_2"]
        spec = scene.robots["endobot_2"]
        rot = Rotation.from_euler("xyz", spec.base.rpy).as_matrix()
        base = (tuple(spec.base.position), tuple(rot.reshape(-1)))
        joint, arm = bent_arm(meas.q, base, meas.tool.bend)
        jaw_pos, jaw_orn = be.scene.tools["endobot_2"].pose()
        # the simulator's jaw centre and jaw axis (its +z)
        sim_axis = Rotation.from_quat(jaw_orn).as_matrix()[:, 2]
        np.testing.assert_allclose(jaw_pos, joint + BENT_ARM * arm, atol=1.5e-3)
        assert float(sim_axis @ arm) > math.cos(math.radians(3.0))
        # and an independent construction: link frame (x) T(-L) Rx Ry T(L), with scipy
        link_pos, link_orn = be.robots["endobot_2"].true_tool_pose()
        r_link = Rotation.from_quat(link_orn)
        r_jaw = r_link * Rotation.from_euler("XY", goal)
        expected = (
            np.asarray(link_pos)
            - BENT_ARM * r_link.as_matrix()[:, 2]
            + BENT_ARM * r_jaw.as_matrix()[:, 2]
        )
        np.testing.assert_allclose(jaw_pos, expected, atol=5e-4)
        # the collision shapes (jaws, and the link as a body fixed to them) cover the arm
        # the skills declare, from the joint to the jaws' end, with no gap between them
        import pybullet as p

        from skills.wrap import BENT_JAW_END

        tool = be.scene.tools["endobot_2"]
        link_pos, link_orn = p.getBasePositionAndOrientation(
            tool.link_body, physicsClientId=tool.client
        )
        np.testing.assert_allclose(link_pos, jaw_pos, atol=2e-4)
        covered = []
        for body in (tool.link_body, tool.body):
            (shape,) = p.getCollisionShapeData(body, -1, physicsClientId=tool.client)
            assert shape[2] == p.GEOM_CAPSULE
            height, radius = shape[3][0], shape[3][1]
            centre = shape[5][2]  # along the jaw axis, from the jaw centre
            assert radius == pytest.approx(1.5e-3)
            covered.append((centre - height / 2 - radius, centre + height / 2 + radius))
        start = -BENT_ARM  # the universal joint, in the jaw frame
        (l0, l1), (j0, j1) = covered
        assert l0 <= start + 1e-9 and l1 >= j0 and j1 == pytest.approx(BENT_JAW_END + start)
    finally:
        be.close()


def test_skill_ramps_from_the_measured_bend() -> None:
    skill = Bend(BendParams.model_validate({"robot": "grasper", "angles": ["0 deg", "-90 deg"]}))
    skill._from = (0.0, -0.5)
    skill._goal = (0.0, -math.pi / 2)
    skill.ramp = abs(skill._goal[1] - skill._from[1]) / Bend.RATE
    assert skill.setpoint(0.0) == (0.0, -0.5)
    assert skill.setpoint(skill.ramp / 2)[1] == pytest.approx((-0.5 - math.pi / 2) / 2)
    assert skill.setpoint(10.0) == skill._goal
