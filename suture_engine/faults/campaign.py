"""The fault campaign: many runs with random faults, each classified from its trace.

Run ``i`` goes to target (procedure on a backend) ``i mod T`` and draws its fault
from ``numpy.random.SeedSequence([base_seed, i])``: within a target the kind
cycles through the target's kinds, so the jobs cycle over procedure x fault kind
(``T * K`` consecutive jobs hold every pair once); the robot, magnitude, trigger
(a time, a step entered, or random with a seed) and the run's seed are drawn.
Each run is a real ``suture run ... --fault SPEC`` in its own process (a crash of
one run is seen as a crash, never takes the campaign down), and is then
classified into the issue's three outcomes, the third one split by the policy
that ended the run:

- ``succeeded``: the procedure reached its success terminal;
- ``failed after retries``: it reached a failure terminal;
- ``aborted by policy: abort``: a step's policy (or the operator) aborted it;
- ``aborted by policy: lock``: the monitor's emergency lock, or a step's
  ``then: lock`` after its retries, locked the robots to wait for the surgeon;
  the campaign has no surgeon, so the run stops there, locked (the safe state);
- ``aborted by policy: time limit``: the run's simulated-time budget
  (``--max-time``, set above the fault-free duration plus the step timeouts)
  ran out; the runtime's summary says ``failed`` with ``metrics.stopped`` "time
  limit ... reached", and the campaign counts that budget as a policy of the run;
- a **crash**: an exit code other than 0 / 1, a traceback in the output, an
  invalid-input exit (the campaign's specs are valid), or a missing or
  unreadable trace or summary.

A job with an empty fault is a fault-free *baseline* run (kind ``none``).

Its trace is read for tension-limit violations: ticks where the simulator's true
tension (``/ground_truth/tension``, backends with a thread) is above the scene's
derived limit, and, reported apart, ticks where the *estimated* tension is (on a
backend without a thread that estimate is all there is, and a sensor fault moves
it without any thread being pulled).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from suture_engine.faults.model import FAULT_KINDS, JOINTS, Fault
from suture_engine.faults.syntax import format_fault

__all__ = [
    "ABORTED",
    "OUTCOMES",
    "OUTCOME_CLASSES",
    "TABLE_HEAD",
    "CampaignJob",
    "CampaignRow",
    "Target",
    "baseline_job",
    "classify",
    "format_table",
    "make_jobs",
    "outcome_class",
    "random_fault",
    "run_campaign",
    "run_job",
    "summary_knot",
    "summary_through_tissue",
    "tally",
    "trace_violations",
]

ABORTED = "aborted by policy"
"""The issue's third outcome; its sub-outcomes start with this prefix."""
OUTCOMES = (
    "succeeded",
    "failed after retries",
    f"{ABORTED}: abort",
    f"{ABORTED}: lock",
    f"{ABORTED}: time limit",
)
"""The classified outcomes, in table order."""
OUTCOME_CLASSES = ("succeeded", "failed after retries", ABORTED)
"""The issue's three classified outcomes (each outcome of :data:`OUTCOMES` is in one)."""


@dataclass(frozen=True)
class Target:
    """A procedure run in the campaign, on one backend.

    Attributes:
        procedure: the procedure file.
        backend: the backend name.
        kinds: the fault kinds drawn for it.
        steps: the procedure's step names (for ``when`` triggers).
        robots: the scene's robot names.
        horizon_s: fault times are drawn in ``[0, horizon_s]`` [s].
        max_time_s: the run's simulated time limit [s].
        sets: ``name=value`` overrides of the procedure's parameters (``--set``).
    """

    procedure: Path
    backend: str
    kinds: tuple[str, ...]
    steps: tuple[str, ...]
    robots: tuple[str, ...]
    horizon_s: float = 12.0
    max_time_s: float = 40.0
    sets: tuple[str, ...] = ()


class CampaignJob(NamedTuple):
    """One run of the campaign.

    Attributes:
        number: the run's index.
        target: what it runs.
        seed: the run's seed.
        fault: the ``--fault`` spec.
        kind: the fault's kind.
        out_dir: the run's output folder.
    """

    number: int
    target: Target
    seed: int
    fault: str
    kind: str
    out_dir: Path


@dataclass(frozen=True)
class CampaignRow:
    """One finished run.

    Attributes:
        index: the run's index.
        procedure: the procedure's file name.
        backend: the backend.
        kind: the fault kind.
        fault: the ``--fault`` spec.
        seed: the run's seed.
        outcome: one of :data:`OUTCOMES`, or ``crash``.
        exit_code: the process exit code.
        final_state: the automaton's final state.
        retries: retries taken.
        limit_N: the scene's derived tension limit [N].
        max_true_tension_N: the largest true tension (NaN without a thread) [N].
        true_violations: ticks with the true tension above the limit.
        max_estimated_tension_N: the largest finite estimated tension [N].
        estimate_over_limit: ticks with the estimated tension above the limit.
        fault_records: fault onsets recorded in the trace.
        error: why the run is a crash ("" otherwise).
        sim_time_s: the simulated time the run lasted (NaN for a crash) [s].
        knot: the ground truth's knot at the run's end (the summary's ``knot.type``;
            several knots joined by ``+``; "" without a thread or a summary).
        through_tissue: whether the thread still runs through the tissue at the end
            (the summary's ``knot.through_tissue``): ``yes``, ``no`` (no stitch made,
            or it was pulled out), or "" (not known).
    """

    index: int
    procedure: str
    backend: str
    kind: str
    fault: str
    seed: int
    outcome: str
    exit_code: int
    final_state: str = ""
    retries: int = 0
    limit_N: float = math.nan
    max_true_tension_N: float = math.nan
    true_violations: int = 0
    max_estimated_tension_N: float = math.nan
    estimate_over_limit: int = 0
    fault_records: int = 0
    error: str = ""
    sim_time_s: float = math.nan
    knot: str = ""
    through_tissue: str = ""


def _when_or_at(rng: np.random.Generator, target: Target, data: dict[str, Any]) -> None:
    """A trigger: a time (1/2), entering a step (1/4), or random with a seed (1/4)."""
    r = rng.random()
    if r < 0.5 or not target.steps:
        data["at"] = round(float(rng.uniform(0.0, target.horizon_s)), 3)
    elif r < 0.75:
        # a sub-procedure's step by its own name ("tighten" for "mirrored-knot.tighten"):
        # the trigger matches the first step of that name entered, and the --fault syntax
        # takes no dotted name
        data["when"] = str(rng.choice(list(target.steps))).rsplit(".", 1)[-1]
        data["at"] = round(float(rng.uniform(0.0, 2.0)), 3)
    elif r < 0.875:
        data["rate"] = round(float(rng.uniform(0.1, 1.0)), 3)
    else:
        data["probability"] = round(float(rng.uniform(0.3, 1.0)), 3)
        data["within"] = target.horizon_s
    if "rate" in data or "probability" in data:
        data["seed"] = int(rng.integers(1_000_000))


def random_fault(rng: np.random.Generator, kind: str, target: Target) -> Fault:
    """A random fault of ``kind`` for ``target`` (magnitudes in the ranges below).

    noise: ft 0.01-1 N, encoders 1e-4-5e-3 rad; bias: ft 0.1-5 N on a random axis,
    encoders 1e-3-0.05 rad; delay 1-20 ms; dropout 5-100 ms; snag 0.5-5 N for
    50-500 ms; joint-lock on a random joint, for good or 0.1-2 s; joint-weak scale
    0-0.9; blow-up NaN or energy. Robot: one of the scene's, or every robot.
    """
    data: dict[str, Any] = {"kind": kind}
    robot_pick = rng.integers(len(target.robots) + 1)
    if robot_pick < len(target.robots):
        data["robot"] = target.robots[robot_pick]
    if kind in ("noise", "bias", "delay", "dropout"):
        sensor = "ft" if rng.random() < 0.5 else "encoders"
        data["sensor"] = sensor
        if kind == "noise":
            data["value"] = (
                float(rng.uniform(0.01, 1.0)) if sensor == "ft" else float(rng.uniform(1e-4, 5e-3))
            )
        elif kind == "bias":
            if sensor == "ft":
                data["value"] = float(rng.uniform(0.1, 5.0)) * (1 if rng.random() < 0.5 else -1)
                data["axis"] = str(rng.choice(["x", "y", "z"]))
            else:
                data["value"] = float(rng.uniform(1e-3, 0.05))
        elif kind == "delay":
            data["value"] = float(rng.uniform(0.001, 0.02))
        else:
            data["duration"] = round(float(rng.uniform(0.005, 0.1)), 3)
    elif kind == "snag":
        data["value"] = float(rng.uniform(0.5, 5.0))
        data["duration"] = round(float(rng.uniform(0.05, 0.5)), 3)
    elif kind in ("joint-lock", "joint-weak"):
        data["joint"] = str(rng.choice(list(JOINTS)))
        if "robot" not in data:
            data["robot"] = str(rng.choice(list(target.robots)))
        if kind == "joint-weak":
            data["value"] = float(rng.uniform(0.0, 0.9))
        elif rng.random() < 0.5:
            data["duration"] = round(float(rng.uniform(0.1, 2.0)), 3)
    elif kind == "blow-up":
        data["mode"] = "nan" if rng.random() < 0.5 else "energy"
    if "value" in data:
        data["value"] = float(f"{data['value']:.3g}")
    _when_or_at(rng, target, data)
    if kind in ("grasp-slip", "snag", "blow-up", "joint-lock") and "rate" in data:
        data.pop("rate")  # one-shot kinds: at most one onset
        data["probability"] = round(float(rng.uniform(0.3, 1.0)), 3)
        data["within"] = target.horizon_s
    return Fault.model_validate(data)


def make_jobs(
    targets: Sequence[Target], runs: int, base_seed: int, out_root: Path
) -> list[CampaignJob]:
    """``runs`` jobs spread over ``targets`` (in turn), each fault drawn from its own seed."""
    jobs: list[CampaignJob] = []
    counters: Counter[int] = Counter()
    for i in range(runs):
        t_index = i % len(targets)
        target = targets[t_index]
        k = counters[t_index]
        counters[t_index] += 1
        rng = np.random.default_rng(np.random.SeedSequence([base_seed, i]))
        kind = target.kinds[k % len(target.kinds)]
        fault = random_fault(rng, kind, target)
        seed = int(rng.integers(1_000_000))
        jobs.append(
            CampaignJob(i, target, seed, format_fault(fault), kind, out_root / f"run-{i:04d}")
        )
    return jobs


def trace_violations(trace: Path, limit_N: float) -> tuple[float, int, float, int, int]:
    """``(max true tension, ticks above the limit, max finite estimate, estimate ticks above,
    fault onsets)`` read from a trace (NaN maxima when a channel is absent).

    Raises:
        TraceError: the trace cannot be read.
    """
    from suture_engine.faults.record import read_faults
    from suture_engine.trace.reader import TraceReader

    reader = TraceReader(trace)
    true_max = est_max = -math.inf
    true_over = est_over = 0
    for msg in reader.messages(["/ground_truth/tension", "/tension/estimated"]):
        value = msg.data.get("tension_N")
        if value is None or not math.isfinite(float(value)):
            continue
        v = float(value)
        if msg.topic == "/ground_truth/tension":
            true_max = max(true_max, v)
            true_over += v > limit_N
        else:
            est_max = max(est_max, v)
            est_over += v > limit_N
    onsets = sum(1 for r in read_faults(trace) if r.phase == "start")
    nan = math.nan
    return (
        true_max if true_max > -math.inf else nan,
        true_over,
        est_max if est_max > -math.inf else nan,
        est_over,
        onsets,
    )


def classify(summary: dict[str, Any]) -> str:
    """The campaign outcome (one of :data:`OUTCOMES`) of a run's ``summary.json``.

    The runtime's summary says ``succeeded``, ``aborted`` or ``failed``; a ``failed``
    run is split by ``metrics.stopped`` and the final state: stopped by the time
    limit, locked (waiting for a surgeon), or at a failure terminal.
    """
    outcome = str(summary.get("outcome", ""))
    stopped = str((summary.get("metrics") or {}).get("stopped", ""))
    if outcome == "succeeded":
        return "succeeded"
    if outcome == "aborted":
        return f"{ABORTED}: abort"
    if stopped.startswith("time limit"):
        return f"{ABORTED}: time limit"
    final = str(summary.get("final_state", ""))
    if final == "lock" or final.endswith("_notbe") or "locked" in stopped:
        return f"{ABORTED}: lock"
    return "failed after retries"


def outcome_class(outcome: str) -> str:
    """The issue's outcome (one of :data:`OUTCOME_CLASSES`) of a campaign outcome, or
    ``crash``."""
    if outcome.startswith(ABORTED):
        return ABORTED
    return outcome


def baseline_job(target: Target, number: int, seed: int, out_dir: Path) -> CampaignJob:
    """A fault-free run of ``target`` (kind ``none``): its outcome and simulated time
    are the reference of the faulted runs."""
    return CampaignJob(number, target, seed, "", "none", out_dir)


def run_job(job: CampaignJob, python: str = sys.executable) -> CampaignRow:
    """Run one job as ``python -m suture_engine.cli run ...`` and classify it."""
    t = job.target
    shutil.rmtree(job.out_dir, ignore_errors=True)
    cmd = [
        python,
        "-m",
        "suture_engine.cli",
        "run",
        str(t.procedure),
        "--backend",
        t.backend,
        "--seed",
        str(job.seed),
        "--max-time",
        str(t.max_time_s),
        "--out",
        str(job.out_dir),
    ]
    for text in t.sets:
        cmd += ["--set", text]
    if job.fault:
        cmd += ["--fault", job.fault]
    env = {**os.environ, "COLUMNS": "200", "NO_COLOR": "1"}

    def crash(code: int, error: str) -> CampaignRow:
        return _row(job, "crash", code, error=error[:300])

    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900)
    except subprocess.TimeoutExpired:
        return crash(-1, "hung (15 min wall)")
    output = proc.stdout + proc.stderr
    if proc.returncode not in (0, 1) or "Traceback" in output:
        return crash(proc.returncode, " | ".join(output.strip().splitlines()[-3:]))
    summary_path = job.out_dir / "summary.json"
    trace = job.out_dir / "trace.mcap"
    if not summary_path.is_file() or not trace.is_file():
        tail = " | ".join(output.strip().splitlines()[-2:])
        return crash(proc.returncode, f"no summary or trace: {tail}")
    try:
        summary = json.loads(summary_path.read_text(encoding="utf-8"))
        limit = float(summary.get("tension_limit_N") or math.nan)
        true_max, true_over, est_max, est_over, onsets = trace_violations(trace, limit)
    except Exception as exc:  # an unreadable trace or summary is a crash of the run
        return crash(proc.returncode, f"unreadable: {exc}")
    return _row(
        job,
        classify(summary),
        proc.returncode,
        final_state=str(summary.get("final_state", "")),
        retries=int(summary.get("retries", 0)),
        limit_N=limit,
        max_true_tension_N=true_max,
        true_violations=true_over,
        max_estimated_tension_N=est_max,
        estimate_over_limit=est_over,
        fault_records=onsets,
        sim_time_s=float(summary.get("sim_time_s", math.nan)),
        knot=summary_knot(summary),
        through_tissue=summary_through_tissue(summary),
    )


def _knot_entries(summary: dict[str, Any]) -> list[dict[str, Any]]:
    """The summary's ``knot`` classifications: it holds one, or a list (one per knot)."""
    knot = summary.get("knot")
    entries = knot if isinstance(knot, list) else [knot]
    return [k for k in entries if isinstance(k, dict)]


def summary_knot(summary: dict[str, Any]) -> str:
    """The ground truth's knot type in a run's summary ("" when it has none)."""
    types = [str(k.get("type", "")) for k in _knot_entries(summary)]
    return "+".join(t for t in types if t)


def summary_through_tissue(summary: dict[str, Any]) -> str:
    """``yes`` / ``no``: whether every knot entry of a run's summary has its thread through
    the tissue ("" when the summary does not say)."""
    flags = [k.get("through_tissue") for k in _knot_entries(summary)]
    flags = [f for f in flags if isinstance(f, bool)]
    if not flags:
        return ""
    return "yes" if all(flags) else "no"


def _row(job: CampaignJob, outcome: str, exit_code: int, **fields: Any) -> CampaignRow:
    t = job.target
    return CampaignRow(
        index=job.number,
        procedure=t.procedure.name,
        backend=t.backend,
        kind=job.kind,
        fault=job.fault,
        seed=job.seed,
        outcome=outcome,
        exit_code=exit_code,
        **fields,
    )


def run_campaign(
    jobs: Sequence[CampaignJob],
    workers: int = 2,
    keep_traces: bool = False,
    on_row: Callable[[CampaignRow], None] | None = None,
) -> list[CampaignRow]:
    """Run the jobs, ``workers`` at a time (each in its own process); rows in index order."""
    rows: list[CampaignRow] = []
    for row in _results(jobs, workers, keep_traces):
        rows.append(row)
        if on_row is not None:
            on_row(row)
    return sorted(rows, key=lambda r: r.index)


def _results(jobs: Sequence[CampaignJob], workers: int, keep: bool) -> Iterator[CampaignRow]:
    def one(job: CampaignJob) -> CampaignRow:
        row = run_job(job)
        if not keep and row.outcome != "crash":
            shutil.rmtree(job.out_dir, ignore_errors=True)
        return row

    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        pending = {pool.submit(one, job) for job in jobs}
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                yield fut.result()


@dataclass
class _Tally:
    runs: int = 0
    outcomes: Counter[str] = field(default_factory=Counter)
    crashes: int = 0
    true_violation_runs: int = 0
    estimate_runs: int = 0
    with_thread: int = 0


def tally(rows: Sequence[CampaignRow], by: str = "kind") -> dict[str, _Tally]:
    """Counts per fault kind (``by="kind"``) or per procedure (``by="procedure"``), and
    ``all``."""
    out: dict[str, _Tally] = {}
    for row in rows:
        key = row.kind if by == "kind" else row.procedure
        for k in (key, "all"):
            t = out.setdefault(k, _Tally())
            t.runs += 1
            if row.outcome == "crash":
                t.crashes += 1
            else:
                t.outcomes[row.outcome] += 1
            t.true_violation_runs += row.true_violations > 0
            t.estimate_runs += row.estimate_over_limit > 0
            t.with_thread += math.isfinite(row.max_true_tension_N)
    if by == "kind":
        order = [k for k in ("none", *FAULT_KINDS) if k in out]
    else:
        order = sorted(k for k in out if k != "all")
    return {k: out[k] for k in [*order, "all"] if k in out}


TABLE_HEAD = (
    "runs",
    "succeeded",
    "failed after retries",
    "aborted by policy",
    "(abort)",
    "(lock)",
    "(time limit)",
    "crashes",
    "runs with a thread",
    "limit violations",
    "estimate > limit",
)
"""The table's columns after the first (see :func:`format_table`)."""


def format_table(rows: Sequence[CampaignRow], by: str = "kind") -> str:
    """The outcome counts per fault kind (or per procedure) as a Markdown table.

    Columns: runs; the issue's three outcomes (succeeded, failed after retries,
    aborted by policy), then the aborted runs split by the policy that ended them
    (an ``abort`` step, a ``lock`` waiting for the surgeon, the run's time limit);
    crashes; runs whose backend has a thread (a true tension); runs whose true
    tension went above the limit; runs whose estimated tension did.
    """
    first = "fault kind" if by == "kind" else "procedure"
    head = [first, *TABLE_HEAD]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for key, t in tally(rows, by).items():
        aborted = sum(n for o, n in t.outcomes.items() if o.startswith(ABORTED))
        cells = [
            f"**{key}**" if key == "all" else key,
            str(t.runs),
            str(t.outcomes.get("succeeded", 0)),
            str(t.outcomes.get("failed after retries", 0)),
            str(aborted),
            *(str(t.outcomes.get(o, 0)) for o in OUTCOMES[2:]),
            str(t.crashes),
            str(t.with_thread),
            str(t.true_violation_runs),
            str(t.estimate_runs),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
