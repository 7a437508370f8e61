"""A simulated calibration error (suture_engine/runtime/calibration.py): checked values,
where the tool lands in PyBullet, and its trip through a trace. (The bases the skills see
before and after a registration: tests/test_register.py.)"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from backends.pybullet.backend import PyBulletBackend
from suture_engine.errors import InvalidValue
from suture_engine.language.loader import load_procedure
from suture_engine.runtime.calibration import (
    CalibrationSpecError,
    calibration_offsets,
    parse_calibration_spec,
)
from suture_engine.runtime.interpreter import Interpreter
from suture_engine.runtime.run import load_plan, replay_trace, run_procedure

ROOT = Path(__file__).resolve().parent.parent
PROCS = Path(__file__).resolve().parent / "procedures"
SCENE = load_procedure(ROOT / "procedures" / "register-bases.yaml").scene


def test_offsets_are_checked_against_the_scene() -> None:
    got = calibration_offsets({"endobot_1": [1e-3, 0, -2e-3]}, SCENE)
    assert got == {"endobot_1": (1e-3, 0.0, -2e-3)}
    assert calibration_offsets(None, SCENE) == {}
    # an array is a vector too (its components come back as floats)
    got = calibration_offsets({"endobot_2": np.array([0.5e-3, -1e-3, 0.0])}, SCENE)
    assert got == {"endobot_2": (0.5e-3, -1e-3, 0.0)}
    assert all(type(v) is float for v in got["endobot_2"])
    with pytest.raises(InvalidValue, match="a robot of the scene") as err:
        calibration_offsets({"endobot_9": (0, 0, 0)}, SCENE)
    assert err.value.value == "endobot_9"
    for bad in ((1e-3, 0.0), (0.0, float("nan"), 0.0), "abc", 1e-3):
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
