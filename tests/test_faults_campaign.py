"""The fault campaign's machinery on a few short runs (the full campaign is a benchmark)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from suture_engine.faults.campaign import (
    CampaignRow,
    Target,
    classify,
    format_table,
    make_jobs,
    random_fault,
    run_campaign,
    tally,
    trace_violations,
)
from suture_engine.faults.model import FAULT_KINDS, Fault
from suture_engine.faults.syntax import parse_fault

ROOT = Path(__file__).resolve().parent.parent
STEPS = ROOT / "tests" / "procedures" / "steps.yaml"
TARGET = Target(
    STEPS,
    "ideal",
    ("bias", "dropout", "blow-up", "noise"),
    ("prepare", "tighten", "release"),
    ("endobot_1", "endobot_2"),
    horizon_s=0.5,
    max_time_s=5.0,
)


def test_jobs_depend_on_the_base_seed_and_their_index_only(tmp_path: Path) -> None:
    a = make_jobs([TARGET], 12, 5, tmp_path)
    b = make_jobs([TARGET], 20, 5, tmp_path)[:12]
    c = make_jobs([TARGET], 12, 6, tmp_path)
    assert [(j.fault, j.seed) for j in a] == [(j.fault, j.seed) for j in b]
    assert [j.fault for j in a] != [j.fault for j in c]
    assert [j.kind for j in a] == [TARGET.kinds[i % 4] for i in range(12)]
    for job in a:  # every drawn spec is valid and of its kind
        assert parse_fault(job.fault).kind == job.kind


@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_random_faults_are_valid_for_every_kind(kind: str) -> None:
    target = Target(STEPS, "pybullet-surgical", FAULT_KINDS, ("a", "b"), ("r1", "r2"))
    for seed in range(20):
        fault = random_fault(np.random.default_rng(seed), kind, target)
        assert fault.kind == kind
        assert fault.when in (None, "a", "b")
        assert fault.robot in (None, "r1", "r2")
        at = fault.at or 0.0
        assert 0.0 <= at <= target.horizon_s


def test_classify_reads_the_summary() -> None:
    assert classify({"outcome": "succeeded", "final_state": "finished"}) == "succeeded"
    assert classify({"outcome": "aborted", "final_state": "ABORTED"}) == "aborted"
    locked = {"outcome": "failed", "final_state": "lock", "metrics": {"stopped": "locked, ..."}}
    assert classify(locked) == "locked"
    timed = {
        "outcome": "failed",
        "final_state": "autonomous/x",
        "metrics": {"stopped": "time limit 5 s reached"},
    }
    assert classify(timed) == "time-limit"
    assert classify({"outcome": "failed", "final_state": "failed"}) == "failed"


def test_trace_violations_count_ticks_above_the_limit(tmp_path: Path) -> None:
    from suture_engine.trace.writer import TraceMeta, TraceWriter

    path = tmp_path / "t.mcap"
    with TraceWriter(path, TraceMeta("x", 0, 1000.0)) as w:
        for k, (true, est) in enumerate([(1.0, 0.5), (3.5, 2.0), (4.0, float("nan")), (2.0, 3.1)]):
            w.write("/ground_truth/tension", k * 1_000_000, {"tension_N": true})
            w.write("/tension/estimated", k * 1_000_000, {"tension_N": est})
    true_max, true_over, est_max, est_over, onsets = trace_violations(path, 3.0)
    assert (true_max, true_over, est_max, est_over, onsets) == (4.0, 2, 3.1, 1, 0)


def test_tally_and_table() -> None:
    def row(i: int, kind: str, outcome: str, over: int = 0) -> CampaignRow:
        return CampaignRow(i, "p", "ideal", kind, "f", 0, outcome, 0, true_violations=over)

    rows = [row(0, "bias", "locked"), row(1, "bias", "crash", 3), row(2, "noise", "succeeded")]
    t = tally(rows)
    assert list(t) == ["noise", "bias", "all"]
    assert (t["bias"].runs, t["bias"].crashes, t["bias"].true_violation_runs) == (2, 1, 1)
    assert t["all"].outcomes["locked"] == 1 and t["all"].outcomes["succeeded"] == 1
    table = format_table(rows)
    assert table.splitlines()[0].startswith("| fault kind | runs | succeeded")
    assert "| **all** | 3 | 1 | 0 | 0 | 1 | 0 | 1 | 1 | 0 |" in table


def test_four_runs_end_to_end(tmp_path: Path) -> None:
    jobs = make_jobs([TARGET], 4, 0, tmp_path)
    seen: list[int] = []
    rows = run_campaign(jobs, workers=2, keep_traces=True, on_row=lambda r: seen.append(r.index))
    assert sorted(seen) == [0, 1, 2, 3] and [r.index for r in rows] == [0, 1, 2, 3]
    for job, r in zip(jobs, rows, strict=True):
        assert r.outcome in ("succeeded", "failed", "aborted", "locked", "time-limit"), r
        assert r.error == "" and r.exit_code in (0, 1)
        assert (r.exit_code == 0) == (r.outcome == "succeeded")
        assert r.limit_N == pytest.approx(min(0.96, 17.85 / 9.80665) * 9.80665 * 0.5)
        assert (job.out_dir / "trace.mcap").is_file()
        assert math.isnan(r.max_true_tension_N)  # the ideal backend has no thread
    assert sum(r.fault_records for r in rows) >= 1


def test_a_crashing_run_is_counted_as_a_crash(tmp_path: Path) -> None:
    from suture_engine.faults.campaign import CampaignJob, run_job

    missing = Target(tmp_path / "nope.yaml", "ideal", ("noise",), (), ("endobot_1",))
    job = CampaignJob(0, missing, 0, "ft.noise=1 N", "noise", tmp_path / "r")
    row = run_job(job)
    assert row.outcome == "crash" and row.exit_code == 2
    fault = Fault(kind="noise", sensor="ft", value=1.0)
    assert parse_fault(job.fault) == fault
