"""``suture steps``: the per-state measurements of runs, as text, JSON or a labelled CSV."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from suture_engine.cli import app
from suture_engine.report.cli_steps import steps_command
from suture_engine.trace.synthetic import synthetic_meta
from suture_engine.trace.writer import TraceWriter
from tests.test_steps import write_trace


def _run(tmp_path: Path, name: str, outcome: str, knot: str) -> Path:
    folder = tmp_path / name
    folder.mkdir()
    write_trace(folder / "trace.mcap")
    (folder / "summary.json").write_text(json.dumps({"outcome": outcome, "knot": {"type": knot}}))
    return folder / "trace.mcap"


def test_csv_rows_are_labelled_with_each_runs_outcome_and_knot(tmp_path: Path) -> None:
    one = _run(tmp_path, "one", "succeeded", "square")
    two = _run(tmp_path, "two", "failed", "trefoil")
    out = io.StringIO()
    target = tmp_path / "steps.csv"
    code = steps_command([one, two], states=["insert"], csv_path=target, out=out)
    assert code == 0, out.getvalue()
    rows = list(csv.DictReader(target.open()))
    assert [(r["knot"], r["outcome"], r["state"]) for r in rows] == [
        ("square", "succeeded", "autonomous/insert"),
        ("trefoil", "failed", "autonomous/insert"),
    ]
    assert float(rows[0]["a.travel_mm"]) == pytest.approx(30.0)
    assert float(rows[0]["a.displacement_x_mm"]) ** 2 + float(
        rows[0]["a.displacement_y_mm"]
    ) ** 2 + float(rows[0]["a.displacement_z_mm"]) ** 2 == pytest.approx(900.0)
    assert float(rows[1]["true_peak_N (ground truth)"]) == pytest.approx(0.75)
    assert rows[1]["true_peak_joint (ground truth)"] == "12"


def test_text_and_json(tmp_path: Path) -> None:
    trace = _run(tmp_path, "one", "succeeded", "square")
    result = CliRunner().invoke(app, ["steps", str(trace), "--state", "insert"])
    assert result.exit_code == 0, result.output
    assert "outcome succeeded, knot square" in result.output
    line = next(x for x in result.output.splitlines() if x.startswith("autonomous/insert"))
    assert "30.0" in line and line.endswith("0.75 (joint 12)")
    result = CliRunner().invoke(app, ["steps", str(trace), "--json"])
    assert result.exit_code == 0, result.output
    rows = json.loads(result.output)
    assert [r["state"].rsplit("/", 1)[-1] for r in rows] == [
        "idle",
        "approach",
        "insert",
        "turn",
        "tied",
    ]


def test_bad_inputs_are_refused_and_nothing_is_written(tmp_path: Path) -> None:
    good = _run(tmp_path, "one", "succeeded", "square")
    err = io.StringIO()
    target = tmp_path / "steps.csv"
    assert steps_command([good, tmp_path / "missing.mcap"], csv_path=target, err=err) == 2
    assert "missing.mcap: no such file" in err.getvalue()
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not a trace")
    err = io.StringIO()
    assert steps_command([good, bad], csv_path=target, err=err) == 1
    assert "bad.mcap" in err.getvalue()
    empty = tmp_path / "empty.mcap"
    with TraceWriter(empty, synthetic_meta(robots=("a",)), fsync=False):
        pass
    err = io.StringIO()
    assert steps_command([empty], csv_path=target, err=err) == 1
    assert "no states recorded" in err.getvalue()
    err = io.StringIO()
    assert steps_command([good], csv_path=tmp_path / "no" / "such" / "x.csv", err=err) == 2
    assert not target.exists()
