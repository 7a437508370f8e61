"""Tests of ``suture trace`` and ``suture diff`` (in-process, plus one real subprocess)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from suture_engine.cli import app
from suture_engine.trace.writer import TraceMeta, TraceWriter

runner = CliRunner()


def _trace(path: Path, gain: float = 1.0, ticks: int = 30, close: bool = True) -> Path:
    w = TraceWriter(path, TraceMeta("cli-demo", 4, 500.0), flush_interval_ns=0)
    for k in range(ticks):
        t = k * 2_000_000
        w.write("/command/left", t, {"kind": "velocity", "values": [gain * k]})
        w.write("/tension/estimated", t, {"tension_N": 0.5})
    if close:
        w.close()
    else:
        w.flush()
    return path


def test_trace_info_text_and_json(tmp_path: Path) -> None:
    path = _trace(tmp_path / "t.mcap")
    result = runner.invoke(app, ["trace", str(path)])
    assert result.exit_code == 0, result.output
    assert "complete" in result.output and "cli-demo" in result.output
    assert "/command/left" in result.output and "30" in result.output
    result = runner.invoke(app, ["trace", str(path), "--json"])
    assert result.exit_code == 0
    report = json.loads(result.output)
    assert report["complete"] is True and report["message_count"] == 61
    assert report["meta"]["procedure"] == "cli-demo"
    counts = {c["topic"]: c["messages"] for c in report["channels"]}
    assert counts == {"/meta": 1, "/command/left": 30, "/tension/estimated": 30}


def test_trace_info_on_a_truncated_trace(tmp_path: Path) -> None:
    path = _trace(tmp_path / "t.mcap", close=False)
    result = runner.invoke(app, ["trace", str(path), "--json"])
    assert result.exit_code == 0
    report = json.loads(result.output)
    assert report["complete"] is False and report["truncated_at_ns"] == 29 * 2_000_000


def test_diff_match_and_divergence(tmp_path: Path) -> None:
    a = _trace(tmp_path / "a.mcap")
    assert runner.invoke(app, ["diff", str(a), str(_trace(tmp_path / "b.mcap"))]).exit_code == 0
    c = _trace(tmp_path / "c.mcap", gain=2.0)
    result = runner.invoke(app, ["diff", str(a), str(c)])
    assert result.exit_code == 1
    assert "first at tick 1 " in result.output and "/command/left" in result.output
    only = runner.invoke(app, ["diff", str(a), str(c), "--topic", "/tension/*"])
    assert only.exit_code == 0, only.output


@pytest.mark.parametrize(("content", "code"), [(b"not a trace at all, just text", 1), (None, 2)])
def test_bad_files_give_exit_codes_without_traceback(
    tmp_path: Path, content: bytes | None, code: int
) -> None:
    path = tmp_path / "x.mcap"
    if content is not None:
        path.write_bytes(content)
    for args in (["trace", str(path)], ["diff", str(path), str(path)]):
        result = runner.invoke(app, args)
        assert result.exit_code == code
        assert "Traceback" not in result.output
        assert result.exception is None or isinstance(result.exception, SystemExit)


def test_real_cli_process(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    path.write_bytes(b"\x00" * 32)
    proc = subprocess.run(
        [sys.executable, "-m", "suture_engine.cli", "trace", str(path)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 1
    assert "not an MCAP file" in proc.stderr and "Traceback" not in proc.stderr
