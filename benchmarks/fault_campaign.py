"""The fault campaign (issue #8): runs of bundled procedures with random faults.

Each run is ``suture run procedures/X.yaml --fault SPEC`` in its own process
(``--workers`` at a time), with one random fault drawn from the run's seed. The
jobs cycle over procedure x fault kind (run ``i`` goes to procedure ``i mod P``;
each procedure takes the kinds in turn); the robot, magnitude and trigger (a
time, a step entered, or random with its own seed) are drawn. Every run is
classified from its summary and its trace (succeeded, failed after retries,
aborted by policy: an abort step, a lock waiting for the surgeon, or the run's
time limit; or a crash), and the script prints the outcome counts per fault kind
and per procedure, the tension-limit violations read from the traces (true
tension, where the backend has a thread; the estimate, apart) and the crashes.

Before the faulted runs, each procedure runs once fault-free on the backend (its
*baseline*, kept in ``OUT/baseline.csv``): its outcome is the reference, and its
simulated duration sets the procedure's time limit (the duration plus the sum of
its steps' timeouts, rounded up to 10 s, unless ``--max-time``) and the window
fault times are drawn from (``[0, duration]``). So a run that reaches the time
limit is an arm that crawls, not a short budget.

Default procedures: ``stitch``, ``square-knot``, ``shared-control-line`` and
``shared-control-circle`` (fault-free on ``pybullet`` all four succeed; on
``ideal`` the square knot locks, as the thread-less backend cannot tie it).
Grasp slip and snag need the thread: with ``--surgical N`` they run N times each
on ``pybullet-surgical`` (when that backend has the ``inject_grasp_slip`` and
``inject_snag`` hooks) on ``stitch.yaml``, with ``--surgical-max-time`` (the
stitch takes about 17.4 s simulated there). ``--surgical-kinds`` widens the thread
runs to other kinds (``all``: every kind, so the sensor, joint and physics faults
are also measured against the thread's true tension); ``--surgical-procedure``,
``--surgical-backend``, ``--surgical-set`` and ``--surgical-window`` run them on
another procedure, for example one throw of algorithm 2 on the stitched start.

Usage:
    nice python benchmarks/fault_campaign.py [--runs 200] [--backend pybullet]
        [--procedures stitch square-knot ...] [--workers 1] [--seed 0]
        [--surgical 0] [--surgical-kinds grasp-slip snag | all]
        [--surgical-procedure stitch] [--surgical-backend pybullet-surgical]
        [--surgical-set NAME=VALUE ...] [--surgical-window 10]
        [--out DIR] [--keep-traces] [--csv FILE]

Rows are appended to the CSV as runs end: an interrupted campaign resumes where it
stopped (same arguments, the CSV of the first start).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import os
import resource
import tempfile
import time
from pathlib import Path

from suture_engine.faults.campaign import (
    CampaignJob,
    CampaignRow,
    Target,
    baseline_job,
    format_table,
    make_jobs,
    run_campaign,
)
from suture_engine.faults.model import FAULT_KINDS

ROOT = Path(__file__).resolve().parents[1]
PROCEDURES = ROOT / "procedures"
STITCH = PROCEDURES / "stitch.yaml"
DEFAULT_PROCEDURES = ("stitch", "square-knot", "shared-control-line", "shared-control-circle")
# the robots alone have no thread for the second throw's cinch to draw taut
PROCEDURE_SETS = {"square-knot.yaml": ("stitch=true", "check_throw=false")}
"""``--set`` values per procedure: the square knot makes its stitch first (the whole
chain; by default it starts from a stitch already made)."""
ROBOTS = ("endobot_1", "endobot_2")
THREAD_KINDS = ("grasp-slip", "snag")
BASELINE_MAX_TIME_S = 900.0


def procedure_path(name: str) -> Path:
    """``stitch``, ``stitch.yaml`` or a path: the procedure file."""
    path = Path(name)
    if path.is_file():
        return path.resolve()
    stem = name[:-5] if name.endswith(".yaml") else name
    return PROCEDURES / f"{stem}.yaml"


def plan_steps(procedure: Path, sets: tuple[str, ...] = ()) -> tuple[tuple[str, ...], float]:
    """The procedure's step names and the sum of their timeouts [s], with ``sets``."""
    from suture_engine.runtime.run import load_plan

    _, plan = load_plan(procedure, sets)
    steps = tuple(plan.steps)
    timeouts = sum(float(s.timeout_s or 0.0) for s in plan.steps.values())
    return steps, timeouts


def time_limit(duration_s: float, timeouts_s: float) -> float:
    """The faulted runs' time limit [s]: the fault-free duration plus the sum of the
    step timeouts, rounded up to 10 s."""
    return 10.0 * math.ceil((duration_s + timeouts_s) / 10.0)


def baselines(
    procedures: list[Path], backend: str, seed: int, out: Path, workers: int
) -> dict[str, CampaignRow]:
    """The fault-free run of each procedure (read back from ``OUT/baseline.csv``)."""
    path = out / "baseline.csv"
    done = {r.procedure: r for r in read_rows(path).values()}
    todo = []
    for n, proc in enumerate(procedures):
        if proc.name in done:
            continue
        sets = PROCEDURE_SETS.get(proc.name, ())
        steps, _ = plan_steps(proc, sets)
        target = Target(proc, backend, (), steps, ROBOTS, 0.0, BASELINE_MAX_TIME_S, sets)
        todo.append(baseline_job(target, n, seed, out / "baseline" / proc.stem))
    if todo:
        print(f"fault-free baselines: {', '.join(j.target.procedure.name for j in todo)}")
        rows = run_campaign(todo, workers=workers)
        write_rows(path, rows)
        done.update({r.procedure: r for r in rows})
    return done


def targets(
    procedures: list[Path],
    backend: str,
    base: dict[str, CampaignRow],
    max_time: float | None,
) -> list[Target]:
    """One target per procedure on ``backend``, its time limit and fault window from its
    baseline."""
    out = []
    for proc in procedures:
        sets = PROCEDURE_SETS.get(proc.name, ())
        steps, timeouts = plan_steps(proc, sets)
        duration = base[proc.name].sim_time_s
        limit = max_time if max_time is not None else time_limit(duration, timeouts)
        out.append(
            Target(
                proc,
                backend,
                tuple(k for k in FAULT_KINDS if k not in THREAD_KINDS),
                steps,
                ROBOTS,
                horizon_s=round(max(duration, 1.0), 1),
                max_time_s=limit,
                sets=sets,
            )
        )
    return out


def surgical_target(
    surgical_max_time: float,
    kinds: tuple[str, ...] = THREAD_KINDS,
    procedure: Path = STITCH,
    backend: str = "pybullet-surgical",
    sets: tuple[str, ...] = (),
    window_s: float = 10.0,
) -> Target | None:
    """``procedure`` on a thread backend with ``kinds`` (by default the stitch with the
    thread faults), if the backend has the thread-fault hooks.

    Args:
        surgical_max_time: each run's simulated time limit [s].
        kinds: the fault kinds, taken in turn.
        procedure: the procedure file.
        backend: a backend with a thread (``pybullet-surgical`` or a variant).
        sets: ``name=value`` overrides of the procedure's parameters.
        window_s: timed faults start in ``[0, window_s]`` [s].
    """
    from backends.pybullet.backend import SurgicalPyBulletBackend

    if not backend.startswith("pybullet-surgical"):
        raise SystemExit(f"--surgical-backend must have a thread (pybullet-surgical*): {backend}")
    hooks = all(hasattr(SurgicalPyBulletBackend, h) for h in ("inject_grasp_slip", "inject_snag"))
    if not hooks:
        print(f"{backend} has no inject_grasp_slip / inject_snag: no thread faults")
        return None
    steps, _ = plan_steps(procedure, sets)
    return Target(procedure, backend, kinds, steps, ROBOTS, window_s, surgical_max_time, sets)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=200, help="faulted runs on --backend")
    ap.add_argument(
        "--backend",
        choices=("ideal", "pybullet"),
        default="pybullet",
        help="backend of the --runs runs (pybullet: the simulated robots with friction and "
        "sensors, no thread)",
    )
    ap.add_argument(
        "--procedures",
        nargs="+",
        default=list(DEFAULT_PROCEDURES),
        help="procedures (names in procedures/ or paths); the runs cycle over them",
    )
    ap.add_argument(
        "--max-time",
        type=float,
        default=None,
        help="time limit of every --runs run [s] (default: per procedure, its fault-free "
        "duration plus its step timeouts)",
    )
    ap.add_argument(
        "--surgical-max-time",
        type=float,
        default=30.0,
        help="time limit of the surgical runs [s]",
    )
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0, help="base seed of the fault draws")
    ap.add_argument(
        "--surgical", type=int, default=0, help="thread runs per kind of --surgical-kinds"
    )
    ap.add_argument(
        "--surgical-kinds",
        nargs="+",
        default=list(THREAD_KINDS),
        choices=[*FAULT_KINDS, "all"],
        help="fault kinds of the thread runs (default: grasp-slip snag; all: every kind)",
    )
    ap.add_argument(
        "--surgical-procedure",
        default="stitch",
        help="procedure of the thread runs (a name in procedures/ or a path)",
    )
    ap.add_argument(
        "--surgical-backend",
        default="pybullet-surgical",
        help="backend of the thread runs (one with a thread)",
    )
    ap.add_argument(
        "--surgical-set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="parameter override of the thread runs' procedure (repeatable)",
    )
    ap.add_argument(
        "--surgical-window",
        type=float,
        default=10.0,
        help="timed faults of the thread runs start in [0, this] [s]",
    )
    ap.add_argument("--out", type=Path, default=None, help="run folders (default: a temp dir)")
    ap.add_argument("--keep-traces", action="store_true", help="keep every run's folder")
    ap.add_argument(
        "--csv",
        type=Path,
        default=None,
        help="one row per run, appended as runs end; the runs already there are not run "
        "again (default: OUT/campaign.csv)",
    )
    ap.add_argument(
        "--report",
        action="store_true",
        help="run nothing: print the tables of the rows already in the CSV (an interrupted "
        "campaign's first N runs)",
    )
    args = ap.parse_args()
    if args.report:
        if args.out is None and args.csv is None:
            raise SystemExit("--report needs --out or --csv")
        report(args.csv or args.out / "campaign.csv", args.out)
        return

    out = args.out or Path(tempfile.mkdtemp(prefix="fault-campaign-"))
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    jobs: list[CampaignJob] = []
    base: dict[str, CampaignRow] = {}
    if args.runs > 0:
        procedures = [procedure_path(p) for p in args.procedures]
        missing = [str(p) for p in procedures if not p.is_file()]
        if missing:
            raise SystemExit(f"no such procedure: {', '.join(missing)}")
        base = baselines(procedures, args.backend, args.seed, out, args.workers)
        crashed = [r for r in base.values() if r.outcome == "crash"]
        if crashed:
            raise SystemExit(f"a fault-free run crashed: {crashed}")
        plan = targets(procedures, args.backend, base, args.max_time)
        print(
            "| procedure | fault-free outcome | simulated [s] | time limit [s] | fault window [s] |"
        )
        print("|---|---|---|---|---|")
        for t in plan:
            b = base[t.procedure.name]
            print(
                f"| {t.procedure.stem} | {b.outcome} | {b.sim_time_s:.1f} | {t.max_time_s:g} | "
                f"0-{t.horizon_s:g} |"
            )
        jobs += make_jobs(plan, args.runs, args.seed, out / args.backend)
    if args.surgical > 0:
        kinds = tuple(FAULT_KINDS) if "all" in args.surgical_kinds else tuple(args.surgical_kinds)
        surgical_proc = procedure_path(args.surgical_procedure)
        if not surgical_proc.is_file():
            raise SystemExit(f"no such procedure: {surgical_proc}")
        surgical = surgical_target(
            args.surgical_max_time,
            kinds,
            surgical_proc,
            args.surgical_backend,
            tuple(args.surgical_set),
            args.surgical_window,
        )
        if surgical is not None:
            batch = make_jobs(
                [surgical],
                args.surgical * len(surgical.kinds),
                args.seed + 1000,
                out / surgical.backend,
            )
            jobs += [j._replace(number=len(jobs) + k) for k, j in enumerate(batch)]
    csv_path = args.csv or out / "campaign.csv"
    done_rows = read_rows(csv_path)
    todo = [j for j in jobs if j.number not in done_rows]
    print(
        f"{len(jobs)} runs ({len(done_rows)} already in {csv_path}), {args.workers} workers, "
        f"output {out}"
    )
    fields = [f.name for f in dataclasses.fields(CampaignRow)]
    new_file = not csv_path.is_file() or csv_path.stat().st_size == 0
    with csv_path.open("a", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields)
        if new_file:
            writer.writeheader()

        def progress(row: CampaignRow) -> None:
            writer.writerow(dataclasses.asdict(row))
            fh.flush()
            done_rows[row.index] = row
            print(
                f"  [{len(done_rows)}/{len(jobs)} {(time.perf_counter() - start) / 60:.1f} min] "
                f"run {row.index} {row.procedure} {row.kind}: {row.outcome} "
                f"({row.sim_time_s:.1f} s simulated) {row.error}",
                flush=True,
            )

        run_campaign(todo, workers=args.workers, keep_traces=args.keep_traces, on_row=progress)
    elapsed = time.perf_counter() - start
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    rows = [done_rows[j.number] for j in jobs if j.number in done_rows]
    print()
    print_tables(rows)
    crashes = [r for r in rows if r.outcome == "crash"]
    violations = sum(r.true_violations > 0 for r in rows)
    with_truth = sum(r.max_true_tension_N == r.max_true_tension_N for r in rows)
    print()
    print(
        f"runs: {len(rows)}  crashes: {len(crashes)}  this session: {len(todo)} runs, "
        f"wall {elapsed / 60:.1f} min, CPU of the runs {cpu / 60:.1f} min "
        f"(load average {os.getloadavg()[0]:.1f})"
    )
    print(f"tension-limit violations (true tension, {with_truth} runs with a thread): {violations}")
    print(
        "runs whose estimated tension went above the limit: "
        f"{sum(r.estimate_over_limit > 0 for r in rows)}"
    )
    print(f"runs whose trace records no fault onset: {sum(r.fault_records == 0 for r in rows)}")
    for r in crashes:
        print(f"  crash: run {r.index} --fault {r.fault!r} exit {r.exit_code}: {r.error}")


def report(csv_path: Path, out: Path | None) -> None:
    """Print the tables of a campaign CSV (and its baselines, if ``out`` has them)."""
    if out is not None and (out / "baseline.csv").is_file():
        print(format_table(list(read_rows(out / "baseline.csv").values()), by="procedure"))
        print()
    rows = sorted(read_rows(csv_path).values(), key=lambda r: r.index)
    print_tables(rows)
    print()
    crashes = [r for r in rows if r.outcome == "crash"]
    with_truth = sum(math.isfinite(r.max_true_tension_N) for r in rows)
    print(
        f"runs: {len(rows)} (indices {rows[0].index if rows else '-'}-"
        f"{rows[-1].index if rows else '-'})  crashes: {len(crashes)}  "
        f"tension-limit violations (true tension, {with_truth} runs with a thread): "
        f"{sum(r.true_violations > 0 for r in rows)}  "
        f"estimate > limit: {sum(r.estimate_over_limit > 0 for r in rows)}  "
        f"no fault onset: {sum(r.fault_records == 0 for r in rows)}"
    )
    for r in crashes:
        print(f"  crash: run {r.index} --fault {r.fault!r} exit {r.exit_code}: {r.error}")


def print_tables(rows: list[CampaignRow]) -> None:
    """Print the outcome tables per fault kind and per procedure, and the knot table when
    the runs had a thread."""
    print(format_table(rows))
    print()
    print(format_table(rows, by="procedure"))
    knots = knot_table(rows)
    if knots:
        print()
        print(knots)


def knot_table(rows: list[CampaignRow]) -> str:
    """The ground truth's knot at the end of each run with a thread, by fault kind and
    outcome class, as a Markdown table ("" when no row has a knot).

    A run that ``succeeded`` without the knot its procedure ties, or with its thread out
    of the tissue (no stitch made), is the procedure fooled: this table is where that
    shows.
    """
    knotted = [r for r in rows if r.knot]
    if not knotted:
        return ""
    kinds = sorted({r.kind for r in knotted})
    cells: dict[tuple[str, str, str], int] = {}
    columns: set[tuple[str, str]] = set()
    for r in knotted:
        cls = "succeeded" if r.outcome == "succeeded" else "not succeeded"
        knot = f"{r.knot} (thread out of the tissue)" if r.through_tissue == "no" else r.knot
        cells[(r.kind, cls, knot)] = cells.get((r.kind, cls, knot), 0) + 1
        columns.add((cls, knot))
    order = sorted(columns, key=lambda c: (c[0] != "succeeded", c[1]))
    head = ["fault kind", *(f"{cls}: {knot}" for cls, knot in order)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for kind in [*kinds, "all"]:
        counts = [
            sum(n for (k, c, t), n in cells.items() if (c, t) == col and kind in (k, "all"))
            for col in order
        ]
        label = "**all**" if kind == "all" else kind
        lines.append("| " + " | ".join([label, *map(str, counts)]) + " |")
    return "\n".join(lines)


def write_rows(path: Path, rows: list[CampaignRow]) -> None:
    """Append rows to a campaign CSV (with its header if new)."""
    fields = [f.name for f in dataclasses.fields(CampaignRow)]
    new_file = not path.is_file() or path.stat().st_size == 0
    with path.open("a", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields)
        if new_file:
            writer.writeheader()
        for row in rows:
            writer.writerow(dataclasses.asdict(row))


def read_rows(path: Path) -> dict[int, CampaignRow]:
    """The rows already in a campaign CSV (a resumed campaign skips them)."""
    if not path.is_file():
        return {}
    types = {f.name: f.type for f in dataclasses.fields(CampaignRow)}
    rows: dict[int, CampaignRow] = {}
    with path.open(newline="", encoding="utf-8") as fh:
        for rec in csv.DictReader(fh):
            values: dict[str, object] = {}
            for key, text in rec.items():
                kind = str(types.get(key, "str"))
                if kind == "int":
                    values[key] = int(text)
                elif kind == "float":
                    values[key] = float(text)
                else:
                    values[key] = text
            row = CampaignRow(**values)  # type: ignore[arg-type]
            rows[row.index] = row
    return rows


if __name__ == "__main__":
    main()
