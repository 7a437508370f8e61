"""``summary.json``: knots per stitch and stitch metrics from the ground truth, JSON-ready."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from suture_engine.runtime.automaton import Outcome, Plan, StepSpec
from suture_engine.runtime.interpreter import Interpreter
from suture_engine.runtime.summary import RunSummary, write_summary
from suture_engine.runtime.testing import IdealBackend, ScriptedSkill

HERE = Path(__file__).resolve().parent


def _plan() -> Plan:
    return Plan(
        "p",
        "a",
        {"a": StepSpec("a", lambda: ScriptedSkill("a", "success", after_s=0.05), "end")},
        {"end": Outcome.SUCCEEDED},
    )


class ThreadTruth(IdealBackend):
    """The ideal backend with a ground-truth thread: a fixed hand-built centerline of three
    stitches (tests/test_evaluation.py's) and a true tension rising 25 N/s for 40 ms, then 0.5 N."""

    def __init__(self, centerline: np.ndarray) -> None:
        super().__init__()
        self.centerline = centerline

    def ground_truth(self) -> dict[str, Any]:
        t = self.tick * self.dt
        return {
            "centerline": self.centerline,
            "tension_N": 25.0 * t if t < 0.04 else 0.5,
            "contact_diameter": 0.5e-3,
        }


def test_summary_has_one_knot_per_stitch_and_the_stitch_metrics(tmp_path: Path) -> None:
    from test_evaluation import SITES, _thread

    be = ThreadTruth(_thread(SITES))
    it = Interpreter(_plan(), be, be.reset())
    s = it.run("p", "ideal")
    assert s.outcome == "succeeded"
    assert isinstance(s.knot, list)
    assert [(k["stitch"], k["type"]) for k in s.knot] == [
        (1, "square"),
        (2, "unknot"),
        (3, "granny"),
    ]
    for k in s.knot:
        assert {"type", "determinant", "v2", "v3", "seated", "post_straight"} <= set(k)
    # a knotted stitch has its lay; the unknotted one has none (post_straight null)
    assert "lay" in s.knot[0] and "lay" in s.knot[2] and "lay" not in s.knot[1]
    assert s.knot[1]["post_straight"] is None
    stitches = s.metrics["stitches"]
    assert stitches["count"] == 3
    assert stitches["bite_depth_mm"] == pytest.approx([2.0, 3.0, 2.5])
    assert stitches["spacing_mean_mm"] == pytest.approx(5.5)
    # no scene: no declared points, no position errors
    assert stitches["entry_error_mm"] == [None, None, None]
    assert s.metrics["peak_true_tension_N"] == pytest.approx(25.0 * 0.039)
    assert s.metrics["final_true_tension_N"] == pytest.approx(0.5)
    assert s.metrics["peak_tension_N"] == pytest.approx(s.max_tension_N)
    path = write_summary(tmp_path / "summary.json", s)
    data = json.loads(path.read_text())
    assert [k["type"] for k in data["knot"]] == ["square", "unknot", "granny"]
    assert data["metrics"]["stitches"]["count"] == 3


def test_the_true_peak_is_placed_in_time_state_and_joint_and_a_nan_does_not_reset_it() -> None:
    from test_evaluation import SITES, _thread

    class Placed(ThreadTruth):
        def ground_truth(self) -> dict[str, Any]:
            truth = super().ground_truth()
            t = self.tick * self.dt
            if 0.04 <= t < 0.045:
                truth["tension_N"] = float("nan")  # a blown-up reading after the peak
            truth["tension_joint"] = 7 if t < 0.03 else 12
            return truth

    be = Placed(_thread(SITES))
    s = Interpreter(_plan(), be, be.reset()).run("p", "ideal")
    assert s.metrics["peak_true_tension_N"] == pytest.approx(25.0 * 0.039)
    at = s.metrics["peak_true_tension_at"]
    assert at["t_s"] == pytest.approx(0.039) and at["joint"] == 12
    assert at["state"].rsplit("/", 1)[-1] == "a"


def test_summary_without_a_thread_has_no_knot_and_tension_figures() -> None:
    be = IdealBackend()
    it = Interpreter(_plan(), be, be.reset())
    be.apply_external_force("endobot_1", (0.0, 0.0, 1.0), 0.02)
    s = it.run("p", "ideal")
    assert s.knot is None and s.metrics["stitches"] is None
    assert s.metrics["peak_true_tension_N"] is None
    assert s.metrics["peak_true_tension_at"] is None
    assert 0.4 < s.metrics["peak_tension_N"] <= 1.0  # the 20 ms push through the low-pass
    assert s.metrics["final_tension_N"] == pytest.approx(0.0, abs=0.05)  # it ended 30 ms ago


def test_skill_metrics_win_over_the_evaluations_names() -> None:
    class WithMetrics(ScriptedSkill):
        def metrics(self) -> dict[str, Any]:
            return {"peak_tension_N": "the skill's own"}

    plan = Plan(
        "p",
        "a",
        {"a": StepSpec("a", lambda: WithMetrics("a", "success", after_s=0.02), "end")},
        {"end": Outcome.SUCCEEDED},
    )
    be = IdealBackend()
    s = Interpreter(plan, be, be.reset()).run("p", "ideal")
    assert s.metrics["peak_tension_N"] == "the skill's own"


def test_a_list_of_knots_is_json_ready() -> None:
    s = RunSummary(
        "p",
        "succeeded",
        "end",
        1.0,
        1.0,
        1.0,
        1e3,
        0.0,
        None,
        [],
        0,
        0,
        knot=[{"type": "square", "height": float("nan")}, {"type": "granny"}],
    )
    out = s.to_dict()
    assert out["knot"] == [{"type": "square", "height": None}, {"type": "granny"}]
