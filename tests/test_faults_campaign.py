"""The fault campaign's machinery on a few short runs (the full campaign is a benchmark)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from benchmark_modules import load_benchmark

from suture_engine.faults.campaign import (
    OUTCOME_CLASSES,
    OUTCOMES,
    CampaignRow,
    Target,
    baseline_job,
    classify,
    format_table,
    make_jobs,
    outcome_class,
    random_fault,
    run_campaign,
    run_job,
    summary_knot,
    summary_through_tissue,
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
    assert classify({"outcome": "aborted", "final_state": "ABORTED"}) == (
        "aborted by policy: abort"
    )
    locked = {"outcome": "failed", "final_state": "lock", "metrics": {"stopped": "locked, ..."}}
    assert classify(locked) == "aborted by policy: lock"
    notbe = {"outcome": "failed", "final_state": "autonomous/bite_notbe"}
    assert classify(notbe) == "aborted by policy: lock"
    assert classify({"outcome": "failed", "final_state": "failed"}) == "failed after retries"


def test_a_time_limit_stop_is_aborted_by_policy() -> None:
    # what the runtime writes when a run reaches --max-time (interpreter.tick / summary)
    timed = {
        "outcome": "failed",
        "final_state": "autonomous/approach",
        "metrics": {"stopped": "time limit 60 s reached"},
    }
    assert classify(timed) == "aborted by policy: time limit"
    assert outcome_class(classify(timed)) == "aborted by policy"
    # the time limit wins over a NOT-BE state the run was cut in
    timed_notbe = {**timed, "final_state": "autonomous/approach~notbe"}
    assert classify(timed_notbe) == "aborted by policy: time limit"
    # every outcome is in one of the three classes; a crash is in none
    assert {outcome_class(o) for o in OUTCOMES} == set(OUTCOME_CLASSES)
    assert outcome_class("crash") not in OUTCOME_CLASSES


def _target(name: str, kinds: tuple[str, ...]) -> Target:
    return Target(ROOT / "procedures" / name, "ideal", kinds, ("a",), ("endobot_1",))


def test_jobs_cycle_over_procedure_and_fault_kind(tmp_path: Path) -> None:
    kinds = ("noise", "bias", "delay", "dropout", "joint-lock", "joint-weak", "blow-up")
    targets = [_target(n, kinds) for n in ("stitch.yaml", "square-knot.yaml", "x.yaml")]
    jobs = make_jobs(targets, 200, 3, tmp_path)
    pairs = [(j.target.procedure.name, j.kind) for j in jobs]
    block = len(targets) * len(kinds)
    for start in range(0, 200 - block + 1, block):  # every block of T*K holds every pair once
        assert len(set(pairs[start : start + block])) == block
    counts = {p: pairs.count(p) for p in set(pairs)}
    assert len(counts) == block and set(counts.values()) == {9, 10}  # 200 = 21 * 9 + 11
    assert [j.target.procedure.name for j in jobs[:4]] == [
        "stitch.yaml",
        "square-knot.yaml",
        "x.yaml",
        "stitch.yaml",
    ]
    assert len({j.out_dir for j in jobs}) == 200


def test_a_baseline_job_carries_no_fault(tmp_path: Path) -> None:
    job = baseline_job(TARGET, 7, 1, tmp_path / "b")
    assert (job.fault, job.kind, job.number) == ("", "none", 7)


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
    def row(i: int, kind: str, outcome: str, over: int = 0, proc: str = "p") -> CampaignRow:
        true = 1.0 if over else math.nan
        return CampaignRow(
            i,
            proc,
            "ideal",
            kind,
            "f",
            0,
            outcome,
            0,
            true_violations=over,
            max_true_tension_N=true,
        )

    lock, limit = "aborted by policy: lock", "aborted by policy: time limit"
    rows = [
        row(0, "bias", lock),
        row(1, "bias", "crash", 3),
        row(2, "noise", "succeeded", proc="q"),
        row(3, "noise", limit, proc="q"),
        row(4, "blow-up", "failed after retries"),
    ]
    t = tally(rows)
    assert list(t) == ["noise", "bias", "blow-up", "all"]
    assert (t["bias"].runs, t["bias"].crashes, t["bias"].true_violation_runs) == (2, 1, 1)
    assert t["all"].outcomes[lock] == 1 and t["all"].outcomes["succeeded"] == 1
    table = format_table(rows)
    assert table.splitlines()[0].startswith(
        "| fault kind | runs | succeeded | failed after retries | aborted by policy | (abort) "
        "| (lock) | (time limit) | crashes |"
    )
    # runs, succeeded, failed, aborted (abort, lock, time limit), crashes, thread, over, est.
    assert "| **all** | 5 | 1 | 1 | 2 | 0 | 1 | 1 | 1 | 1 | 1 | 0 |" in table
    assert "| noise | 2 | 1 | 0 | 1 | 0 | 0 | 1 | 0 | 0 | 0 | 0 |" in table
    by_proc = format_table(rows, by="procedure")
    assert by_proc.splitlines()[0].startswith("| procedure | runs |")
    assert "| p | 3 | 0 | 1 | 1 | 0 | 1 | 0 | 1 | 1 | 1 | 0 |" in by_proc
    assert "| q | 2 | 1 | 0 | 1 | 0 | 0 | 1 | 0 | 0 | 0 | 0 |" in by_proc


def test_four_runs_end_to_end(tmp_path: Path) -> None:
    jobs = make_jobs([TARGET], 4, 0, tmp_path)
    seen: list[int] = []
    rows = run_campaign(jobs, workers=2, keep_traces=True, on_row=lambda r: seen.append(r.index))
    assert sorted(seen) == [0, 1, 2, 3] and [r.index for r in rows] == [0, 1, 2, 3]
    for job, r in zip(jobs, rows, strict=True):
        assert r.outcome in OUTCOMES, r
        assert 0.0 < r.sim_time_s <= TARGET.max_time_s + 0.01
        assert r.error == "" and r.exit_code in (0, 1)
        assert (r.exit_code == 0) == (r.outcome == "succeeded")
        assert r.limit_N == pytest.approx(min(0.96, 17.85 / 9.80665) * 9.80665 * 0.5)
        assert (job.out_dir / "trace.mcap").is_file()
        assert math.isnan(r.max_true_tension_N)  # the ideal backend has no thread
        assert r.knot == "" and r.through_tissue == ""
    assert sum(r.fault_records for r in rows) >= 1


def test_a_crashing_run_is_counted_as_a_crash(tmp_path: Path) -> None:
    from suture_engine.faults.campaign import CampaignJob, run_job

    missing = Target(tmp_path / "nope.yaml", "ideal", ("noise",), (), ("endobot_1",))
    job = CampaignJob(0, missing, 0, "ft.noise=1 N", "noise", tmp_path / "r")
    row = run_job(job)
    assert row.outcome == "crash" and row.exit_code == 2
    fault = Fault(kind="noise", sensor="ft", value=1.0)
    assert parse_fault(job.fault) == fault


def test_a_baseline_run_is_fault_free(tmp_path: Path) -> None:
    row = run_job(baseline_job(TARGET, 0, 1, tmp_path / "b"))
    assert row.kind == "none" and row.fault == "" and row.error == "", row
    assert row.outcome in OUTCOMES and row.fault_records == 0
    assert 0.0 < row.sim_time_s <= TARGET.max_time_s + 0.01


def test_a_short_time_limit_is_classified(tmp_path: Path) -> None:
    # a real run cut by its time limit ends in a classified outcome, not a crash
    short = Target(STEPS, "ideal", ("noise",), (), ("endobot_1",), 0.1, max_time_s=0.05)
    row = run_job(baseline_job(short, 0, 1, tmp_path / "t"))
    assert row.outcome == "aborted by policy: time limit", row
    assert row.exit_code == 1 and row.sim_time_s == pytest.approx(0.05, abs=0.002)


def test_a_target_passes_its_parameter_overrides_to_the_run(tmp_path: Path) -> None:
    # steps.yaml bounds hold_time to 5 s: the override reaches the run, which refuses it
    bad = Target(STEPS, "ideal", ("noise",), (), ("endobot_1",), 0.1, 1.0, ("hold_time=9 s",))
    row = run_job(baseline_job(bad, 0, 1, tmp_path / "s"))
    assert row.outcome == "crash" and "hold_time" in row.error, row
    good = Target(STEPS, "ideal", ("noise",), (), ("endobot_1",), 0.1, 5.0, ("hold_time=20 ms",))
    fast = run_job(baseline_job(good, 0, 1, tmp_path / "g"))
    slow = run_job(baseline_job(replace(good, sets=()), 0, 1, tmp_path / "d"))
    assert fast.outcome == slow.outcome == "succeeded", (fast, slow)
    assert slow.sim_time_s - fast.sim_time_s == pytest.approx(0.18, abs=0.005)


def test_the_benchmark_sets_each_procedure_its_limit_from_its_baseline() -> None:
    bench = load_benchmark("fault_campaign")
    procs = [bench.procedure_path(n) for n in ("stitch", "square-knot.yaml")]
    assert [p.name for p in procs] == ["stitch.yaml", "square-knot.yaml"]
    assert all(p.is_file() for p in procs)

    def base(proc: str, sim: float) -> CampaignRow:
        return CampaignRow(0, proc, "pybullet", "none", "", 1, "succeeded", 0, sim_time_s=sim)

    rows = {"stitch.yaml": base("stitch.yaml", 17.15), "square-knot.yaml": base("sq", 109.65)}
    stitch, square = bench.targets(procs, "pybullet", rows, None)
    # stitch: timeouts 15 s + 30 s + 40 s + 20 s; 17.15 + 105 = 122.15 -> 130 s
    assert (stitch.max_time_s, stitch.horizon_s) == (130.0, 17.1)
    # the campaign's square knot makes its stitch (by default it starts from one made), and
    # does not check its second throw's cinch (the robots alone have no thread to draw)
    assert square.sets == ("stitch=true", "check_throw=false") and stitch.sets == ()
    _, square_timeouts = bench.plan_steps(procs[1], square.sets)
    assert square.max_time_s >= 109.65 + square_timeouts
    assert square.max_time_s - (109.65 + square_timeouts) < 10.0
    assert {s.split(".")[0] for s in square.steps} >= {"simple-knot", "mirrored-knot"}
    for t in (stitch, square):
        assert "grasp-slip" not in t.kinds and "snag" not in t.kinds and len(t.kinds) == 7
    fixed = bench.targets(procs, "pybullet", rows, 40.0)
    assert [t.max_time_s for t in fixed] == [40.0, 40.0]


def test_the_thread_runs_take_any_kinds_procedure_and_overrides() -> None:
    bench = load_benchmark("fault_campaign")
    default = bench.surgical_target(40.0)
    assert default is not None
    assert (default.procedure.name, default.backend, default.kinds) == (
        "stitch.yaml",
        "pybullet-surgical",
        ("grasp-slip", "snag"),
    )
    knot = bench.surgical_target(
        120.0,
        tuple(FAULT_KINDS),
        bench.procedure_path("knot-algorithm-2"),
        "pybullet-surgical-stitched",
        ("stitch=false",),
        60.0,
    )
    assert knot is not None
    assert knot.kinds == tuple(FAULT_KINDS) and knot.sets == ("stitch=false",)
    assert (knot.horizon_s, knot.max_time_s) == (60.0, 120.0)
    # state triggers can name the knot's steps, not only the stitch's
    assert "cinch" in knot.steps and "cinch" not in default.steps
    with pytest.raises(SystemExit, match="must have a thread"):
        bench.surgical_target(40.0, backend="pybullet")


def test_state_triggers_of_sub_procedure_steps_parse_and_match(tmp_path: Path) -> None:
    # the square knot's steps are qualified ("mirrored-knot.tighten"); the --fault syntax
    # takes no dotted name, so the campaign names the step by its own name, which the
    # schedule matches as a step of a sub-procedure
    from suture_engine.faults.schedule import state_matches

    steps = ("simple-knot.stitch.approach", "simple-knot.tighten", "mirrored-knot.tighten")
    target = Target(STEPS, "pybullet", FAULT_KINDS, steps, ("endobot_1", "endobot_2"))
    jobs = make_jobs([target], 120, 0, tmp_path)
    whens = [parse_fault(j.fault).when for j in jobs]  # every spec parses
    drawn = {w for w in whens if w is not None}
    assert drawn == {"approach", "tighten"}
    for name in drawn:
        assert any(state_matches(step, name) for step in steps)


def test_the_row_keeps_the_ground_truth_knot_of_the_summary() -> None:
    assert summary_knot({"knot": {"type": "trefoil", "determinant": 3}}) == "trefoil"
    two = {"knot": [{"type": "square"}, {"type": "unknot"}, {"type": "granny"}]}
    assert summary_knot(two) == "square+unknot+granny"
    assert summary_knot({}) == summary_knot({"knot": None}) == ""
    assert summary_through_tissue({"knot": {"type": "unknot", "through_tissue": True}}) == "yes"
    out = {"knot": [{"through_tissue": True}, {"through_tissue": False}]}
    assert summary_through_tissue(out) == "no"
    assert summary_through_tissue({"knot": {"type": "unknot"}}) == summary_through_tissue({}) == ""


def test_the_knot_table_counts_knots_by_kind_and_outcome() -> None:
    bench = load_benchmark("fault_campaign")

    def row(i: int, kind: str, outcome: str, knot: str) -> CampaignRow:
        return CampaignRow(i, "k.yaml", "pybullet-surgical", kind, "", 1, outcome, 0, knot=knot)

    rows = [
        row(0, "noise", "succeeded", "trefoil"),
        row(1, "noise", "succeeded", "unknot"),
        row(2, "snag", "aborted by policy: lock", "unknot"),
        row(3, "snag", "succeeded", "trefoil"),
        row(4, "bias", "succeeded", ""),  # no thread: left out
    ]
    fooled = replace(row(5, "snag", "succeeded", "unknot"), through_tissue="no")
    table = bench.knot_table(rows).splitlines()
    assert table[0] == (
        "| fault kind | succeeded: trefoil | succeeded: unknot | not succeeded: unknot |"
    )
    assert table[2:] == [
        "| noise | 1 | 1 | 0 |",
        "| snag | 1 | 0 | 1 |",
        "| **all** | 2 | 1 | 1 |",
    ]
    assert bench.knot_table(rows[4:]) == ""
    with_fooled = bench.knot_table([*rows, fooled]).splitlines()
    assert "succeeded: unknot (thread out of the tissue)" in with_fooled[0]
    assert with_fooled[-1] == "| **all** | 2 | 1 | 1 | 1 |"
