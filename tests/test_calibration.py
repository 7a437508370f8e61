"""A simulated calibration error (suture_engine/runtime/calibration.py): checked values, the
bases the skills see, where the tool lands in PyBullet, and its trip through a trace."""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

from backends.pybullet.backend import PyBulletBackend
from suture_engine.errors import InvalidValue
from suture_engine.language.loader import load_procedure
from suture_engine.runtime.automaton import FailurePolicy, Outcome, Plan, StepSpec, Then
from suture_engine.runtime.calibration import (
    CalibrationSpecError,
    calibration_offsets,
    parse_calibration_spec,
)
from suture_engine.runtime.interpreter import Interpreter
from suture_engine.runtime.run import load_plan, replay_trace, run_procedure
from suture_engine.runtime.testing import IdealBackend, ScriptedSkill

ROOT = Path(__file__).resolve().parent.parent
PROCS = Path(__file__).resolve().parent / "procedures"
SCENE = load_procedure(ROOT / "procedures" / "register-bases.yaml").scene


def test_offsets_are_checked_against_the_scene() -> None:
    got = calibration_offsets({"endobot_1": [1e-3, 0, -2e-3]}, SCENE)
    assert got == {"endobot_1": (1e-3, 0.0, -2e-3)}
    assert calibration_offsets(None, SCENE) == {}
    with pytest.raises(InvalidValue, match="a robot of the scene") as err:
        calibration_offsets({"endobot_9": (0, 0, 0)}, SCENE)
    assert err.value.value == "endobot_9"
    for bad in ((1e-3, 0.0), (0.0, float("nan"), 0.0), "abc"):
        with pytest.raises(InvalidValue, match="three finite numbers"):
            calibration_offsets({"endobot_2": bad}, SCENE)  # type: ignore[dict-item]


def test_a_command_line_value_is_robot_and_millimetres() -> None:
    name, vector = parse_calibration_spec("endobot_2=1, 0,-0.5")
    assert name == "endobot_2"
    np.testing.assert_allclose(vector, (1e-3, 0.0, -0.5e-3))
    for bad in ("endobot_2", "=1,2,3", "endobot_2=1,2", "endobot_2=1,x,3", "endobot_2=1,inf,3"):
        with pytest.raises(CalibrationSpecError) as err:
            parse_calibration_spec(bad)
        assert err.value.spec == bad


class _Sees(ScriptedSkill):
    seen: ClassVar[list[Any]] = []

    def start(self, ctx: Any) -> None:
        super().start(ctx)
        _Sees.seen.append(dict(ctx.base_poses))


class _Registers(ScriptedSkill):
    """A registration that measures endobot_1's base 1 mm further along -x than believed."""

    base_corrections: ClassVar[dict[str, Any]] = {"endobot_1": (-1e-3, 0.0, 0.0)}


def test_the_skills_plan_from_the_believed_base_until_a_registration_corrects_it() -> None:
    _Sees.seen = []
    policy = FailurePolicy(0, Then.FAIL)
    plan = Plan(
        "p",
        "before",
        {
            "before": StepSpec("before", lambda: _Sees("before"), "register", policy),
            "register": StepSpec("register", lambda: _Registers("register"), "after", policy),
            "after": StepSpec("after", lambda: _Sees("after"), "end", policy),
        },
        {"end": Outcome.SUCCEEDED},
    )
    be = IdealBackend()
    it = Interpreter(
        plan, be, be.reset(), scene=SCENE, calibration_error={"endobot_1": (1e-3, 0.0, 0.0)}
    )
    assert it.run("p", "ideal").outcome == "succeeded"
    before, after = _Sees.seen
    declared = {n: tuple(s.base.position) for n, s in SCENE.robots.items()}
    np.testing.assert_allclose(
        np.subtract(before["endobot_1"][0], declared["endobot_1"]), (1e-3, 0, 0), atol=1e-15
    )
    # the registration's measured correction takes the error out: the declared base again
    np.testing.assert_allclose(after["endobot_1"][0], declared["endobot_1"], atol=1e-15)
    assert before["endobot_2"][0] == declared["endobot_2"] == after["endobot_2"][0]


def _final_tip(calibration: dict[str, Any] | None, base_error: dict[str, Any] | None) -> Any:
    """The stitcher's true tool tip (PyBullet's link state) at the end of reach.yaml."""
    proc, plan = load_plan(PROCS / "reach.yaml", ["speed=100 mm/s"])
    be = PyBulletBackend(base_error=base_error)
    try:
        first = be.reset(proc.scene, 0)
        it = Interpreter(
            plan,
            be,
            first,
            roles=proc.roles,
            params=proc.params,
            scene=proc.scene,
            max_time_s=10,
            calibration_error=calibration,
        )
        while it.tick():
            pass
        assert it.automaton.state == "finished"
        return np.array(be.ground_truth()["endobot_1/tool_tip"]), proc
    finally:
        be.close()


def test_a_calibration_error_moves_the_tool_as_a_placement_error_of_the_opposite_sign() -> None:
    c = np.array([0.0, 2e-3, -1e-3])  # believed base minus actual [m]
    exact, proc = _final_tip(None, None)
    believed_off, _ = _final_tip({"endobot_1": tuple(c)}, None)
    placed_off, _ = _final_tip(None, {"endobot_1": tuple(-c)})
    goal = np.array(proc.scene.tissue.points["entry"]) + np.array([0.0, 0.0, 0.06])
    assert np.linalg.norm(exact - goal) < 0.5e-3  # move-to's tolerance
    # planned from a base c off, the tool lands c the other way (PyBullet's link state)
    np.testing.assert_allclose(believed_off - goal, -c, atol=0.5e-3)
    # and where a robot built -c off its declared base lands it
    np.testing.assert_allclose(believed_off, placed_off, atol=0.5e-3)


def test_a_run_records_its_calibration_error_and_a_replay_applies_it_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from suture_engine.runtime import run as run_module
    from suture_engine.trace.reader import TraceReader

    c = {"endobot_1": (0.0, 2e-3, -1e-3)}
    result = run_procedure(
        PROCS / "reach.yaml",
        backend="pybullet",
        out=tmp_path / "run",
        sets=["speed=100 mm/s"],
        max_time_s=10,
        calibration_error=c,
    )
    assert result.summary.outcome == "succeeded"
    meta = TraceReader(result.trace).meta
    assert meta.get("extra", meta)["calibration_error"] == {"endobot_1": [0.0, 2e-3, -1e-3]}
    replayed = replay_trace(result.trace, check=True)
    assert replayed.ok, replayed.diff
    # a replay that dropped it would plan from the declared base, and its commands differ
    monkeypatch.setattr(run_module, "calibration_offsets", lambda errors, scene: {})
    assert not replay_trace(result.trace, check=True).ok
