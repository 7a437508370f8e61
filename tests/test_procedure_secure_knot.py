"""``procedures/secure-knot.yaml``: tie, place and secure a square knot (thesis 4.5, 7.1).

The fast checks read the compiled procedure; the slow one runs it on the stitched start
and judges it by the simulated thread (ground truth), not by the procedure's outcome.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from suture_engine.language.loader import load_procedure
from suture_engine.trace.reader import TraceReader

ROOT = Path(__file__).resolve().parent.parent
PROC = ROOT / "procedures" / "secure-knot.yaml"


def test_the_second_securing_is_off_unless_asked_for() -> None:
    """It broke the tension limit (19-22 N true after second throws that tied nothing;
    18.3 N on seed 0 after the model fixes of 2026-12-02, a second throw that had tied)."""
    default: Any = load_procedure(PROC)
    assert not default.states["secure-second"].enabled
    asked: Any = load_procedure(PROC, params={"secure_second": True})
    assert asked.states["secure-second"].enabled


def test_each_securing_pulls_its_throws_way_from_the_runs_tare() -> None:
    proc: Any = load_procedure(PROC, params={"secure_second": True})
    first = proc.states["secure-first"].params
    second = proc.states["secure-second"].params
    assert (first.throw, second.throw) == (1, 2)  # opposite directions (7.1-7.3)
    for p in (first, second):
        # the placement leaves the strand taut; static friction is compensated
        assert p.tare == "run" and p.stiction and p.max_travel == pytest.approx(0.01)
    assert proc.states["place-second"].params.throw == 2
    assert first.tension < second.tension


@pytest.mark.slow
def test_seed_0_places_and_secures_a_square_knot(tmp_path: Path) -> None:
    """The default seed on the stitched start, as shipped (the second securing off): the
    first throw is placed and secured at a regulated tension, the second placed; the
    thread ties a square knot that binds the stitch and lies square, and the true tension
    stays under the limit all along. (Measured on 2026-12-02, after the model's hook and
    hand-over fixes; seed 1, which tied before them, now ties nothing on its first throw.)"""
    out = tmp_path / "secure"
    cmd = [sys.executable, "-m", "suture_engine.cli", "run", str(PROC), "--seed", "0"]
    cmd += ["--out", str(out)]
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "succeeded" and summary["final_state"] == "secured"
    knot = summary["knot"]
    assert knot["type"] == "square" and knot["determinant"] == 9
    assert knot["through_tissue"] and knot["lay"] == "square" and knot["post_straight"]
    events = [m.data["detail"] for m in TraceReader(out / "trace.mcap").messages(["/events"])]
    assert "done:secure-first" in events and "done:place-second" in events
    assert "skipped:secure-second (when: false)" in events
    assert summary["metrics"]["peak_true_tension_N"] < summary["tension_limit_N"]
