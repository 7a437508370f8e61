"""The thread's knot at the end of each state, read from a trace (`suture knot TRACE`).

The traces are written here by hand: a straight thread, then a hand-built trefoil
(and a square knot) between known state changes, so every row's expected knot is known
without the engine.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from suture_engine.cli import app
from suture_engine.suture import curves
from suture_engine.suture.timeline import NoGroundTruth, knot_timeline
from suture_engine.trace.channels import GROUND_TRUTH_SUTURE, GROUND_TRUTH_TENSION, TRANSITIONS
from suture_engine.trace.synthetic import synthetic_meta
from suture_engine.trace.writer import TraceWriter

runner = CliRunner()
S = 1_000_000_000


def _line(pts: np.ndarray) -> dict[str, list[float]]:
    return {"x": pts[:, 0].tolist(), "y": pts[:, 1].tolist(), "z": pts[:, 2].tolist()}


def _write(path: Path, *, thread: bool = True) -> None:
    straight = np.stack([np.linspace(0, 0.1, 40), np.zeros(40), np.zeros(40)], axis=1)
    trefoil = 0.001 * curves.trefoil()
    square = 0.001 * curves.square_knot()
    with TraceWriter(path, synthetic_meta(), fsync=False) as w:
        steps = [
            (0.5, GROUND_TRUTH_SUTURE, _line(straight)),
            (0.6, GROUND_TRUTH_TENSION, {"tension_N": 0.2}),
            (1.0, TRANSITIONS, {"source": "grab", "dest": "wrap"}),
            (1.5, GROUND_TRUTH_TENSION, {"tension_N": 1.25}),
            (1.9, GROUND_TRUTH_SUTURE, _line(trefoil)),
            (2.0, TRANSITIONS, {"source": "wrap", "dest": "throw-2.tighten"}),
            (2.5, GROUND_TRUTH_TENSION, {"tension_N": 0.5}),
            (2.9, GROUND_TRUTH_SUTURE, _line(square)),
            (3.0, TRANSITIONS, {"source": "throw-2.tighten", "dest": "tied"}),
            (3.5, GROUND_TRUTH_SUTURE, _line(straight)),
        ]
        for t, topic, msg in steps:
            if thread or not topic.startswith("/ground_truth"):
                w.write(topic, int(t * S), msg)


def test_each_state_gets_the_knot_held_when_it_ended(tmp_path: Path) -> None:
    _write(tmp_path / "trace.mcap")
    rows = list(knot_timeline(tmp_path / "trace.mcap"))
    assert [r.state for r in rows] == ["grab", "wrap", "throw-2.tighten", "tied"]
    assert [r.knot for r in rows] == ["unknot", "trefoil", "square", "unknot"]
    assert [r.determinant for r in rows] == [1, 3, 9, 1]
    assert [(r.start_s, r.end_s) for r in rows] == [(0.0, 1.0), (1.0, 2.0), (2.0, 3.0), (3.0, 3.5)]
    # the peak true tension is per state, not running over the run
    assert [r.peak_tension_N for r in rows] == [0.2, 1.25, 0.5, None]


def test_cli_prints_the_table_and_json(tmp_path: Path) -> None:
    _write(tmp_path / "trace.mcap")
    result = runner.invoke(app, ["knot", str(tmp_path / "trace.mcap")])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert lines[0].split()[:2] == ["state", "start"]
    assert lines[2].split()[0] == "wrap" and "trefoil" in lines[2] and "1.25" in lines[2]
    result = runner.invoke(app, ["knot", str(tmp_path / "trace.mcap"), "--json"])
    assert result.exit_code == 0, result.output
    assert [r["knot"] for r in json.loads(result.stdout)][2] == "square"


def test_a_trace_without_a_thread_is_a_clear_error(tmp_path: Path) -> None:
    _write(tmp_path / "trace.mcap", thread=False)
    with pytest.raises(NoGroundTruth):
        list(knot_timeline(tmp_path / "trace.mcap"))
    result = runner.invoke(app, ["knot", str(tmp_path / "trace.mcap")])
    assert result.exit_code == 1
    assert "no /ground_truth/suture" in result.stderr and "Traceback" not in result.output


def test_a_missing_or_foreign_trace_is_a_clear_error(tmp_path: Path) -> None:
    result = runner.invoke(app, ["knot", str(tmp_path / "none.mcap")])
    assert result.exit_code == 2 and "cannot read" in result.stderr
    (tmp_path / "bad.mcap").write_bytes(b"not a trace at all")
    result = runner.invoke(app, ["knot", str(tmp_path / "bad.mcap")])
    assert result.exit_code == 1 and "Traceback" not in result.output
