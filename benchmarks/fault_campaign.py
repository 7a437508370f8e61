"""The fault campaign (issue #8): many runs of a bundled procedure with random faults.

Each run is ``suture run procedures/stitch.yaml --fault SPEC`` in its own process
(``--workers`` at a time), with one random fault drawn from the run's seed (kind
in turn, then target, magnitude and trigger: a time, a step entered, or random
with its own seed). Every run is classified from its summary and its trace, and
the script prints a table of outcome counts per fault kind, the tension-limit
violations read from the traces (true tension, where the backend has a thread;
the estimate, apart) and the crashes.

Why ``stitch.yaml`` on the ``ideal`` backend: it is the shortest bundled procedure
that moves both skills of a stitch (a 9 s approach, then the bite and the pull;
about 15 s simulated, 5 s of CPU on the ideal backend against 11 s on ``pybullet``
and 30 s on ``pybullet-surgical``), so 200 runs fit in 30 minutes on 2 cores.
Grasp slip and snag need the thread: with ``--surgical N`` they run N times each
on ``pybullet-surgical`` (when that backend has the ``inject_grasp_slip`` and
``inject_snag`` hooks), with a 15 s time limit.

Usage:
    nice python benchmarks/fault_campaign.py [--runs 200] [--workers 2] [--seed 0]
        [--surgical 0] [--out DIR] [--keep-traces] [--csv FILE]

Rows are appended to the CSV as runs end: an interrupted campaign resumes where it
stopped (same ``--runs``, ``--seed`` and ``--surgical``, the CSV of the first start).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import os
import resource
import tempfile
import time
from pathlib import Path

from suture_engine.faults.campaign import (
    CampaignJob,
    CampaignRow,
    Target,
    format_table,
    make_jobs,
    run_campaign,
)
from suture_engine.faults.model import FAULT_KINDS

ROOT = Path(__file__).resolve().parents[1]
STITCH = ROOT / "procedures" / "stitch.yaml"
ROBOTS = ("endobot_1", "endobot_2")
THREAD_KINDS = ("grasp-slip", "snag")


def targets(
    surgical: int, backend: str = "ideal", surgical_max_time: float = 30.0
) -> list[tuple[Target, int]]:
    """(target, share) pairs: the stitch on ``backend``, and the surgical one if asked.

    ``surgical_max_time`` [s]: the surgical runs' time limit (the stitch takes about 17 s
    simulated on ``pybullet-surgical``; the first campaign's 15 s cut every run before its end).
    """
    from suture_engine.runtime.run import load_plan

    _, plan = load_plan(STITCH)
    steps = tuple(plan.steps)
    ideal = Target(
        STITCH,
        backend,
        tuple(k for k in FAULT_KINDS if k not in THREAD_KINDS),
        steps,
        ROBOTS,
        horizon_s=12.0,
        max_time_s=40.0,
    )
    out = [(ideal, 0)]
    if surgical > 0:
        from backends.pybullet.backend import SurgicalPyBulletBackend

        hooks = all(
            hasattr(SurgicalPyBulletBackend, h) for h in ("inject_grasp_slip", "inject_snag")
        )
        if hooks:
            out.append(
                (
                    Target(
                        STITCH,
                        "pybullet-surgical",
                        THREAD_KINDS,
                        steps,
                        ROBOTS,
                        10.0,
                        surgical_max_time,
                    ),
                    surgical * len(THREAD_KINDS),
                )
            )
        else:
            print("pybullet-surgical has no inject_grasp_slip / inject_snag: no thread faults")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=200, help="runs on --backend")
    ap.add_argument(
        "--backend",
        choices=("ideal", "pybullet"),
        default="ideal",
        help="backend of the --runs runs (pybullet: the simulated robots, no thread)",
    )
    ap.add_argument(
        "--surgical-max-time",
        type=float,
        default=30.0,
        help="time limit of the surgical runs [s]",
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0, help="base seed of the fault draws")
    ap.add_argument("--surgical", type=int, default=0, help="runs per thread fault kind")
    ap.add_argument("--out", type=Path, default=None, help="run folders (default: a temp dir)")
    ap.add_argument("--keep-traces", action="store_true", help="keep every run's folder")
    ap.add_argument(
        "--csv",
        type=Path,
        default=None,
        help="one row per run, appended as runs end; the runs already there are not run "
        "again (default: OUT/campaign.csv)",
    )
    args = ap.parse_args()

    out = args.out or Path(tempfile.mkdtemp(prefix="fault-campaign-"))
    jobs: list[CampaignJob] = []
    for n, (target, share) in enumerate(
        targets(args.surgical, args.backend, args.surgical_max_time)
    ):
        count = args.runs if share == 0 else share
        batch = make_jobs([target], count, args.seed + 1000 * n, out / target.backend)
        jobs += [j._replace(number=len(jobs) + k) for k, j in enumerate(batch)]
    out.mkdir(parents=True, exist_ok=True)
    csv_path = args.csv or out / "campaign.csv"
    done_rows = read_rows(csv_path)
    todo = [j for j in jobs if j.number not in done_rows]
    print(
        f"{len(jobs)} runs ({len(done_rows)} already in {csv_path}), {args.workers} workers, "
        f"output {out}"
    )
    start = time.perf_counter()
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
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
            if row.outcome == "crash" or len(done_rows) % 20 == 0:
                print(
                    f"  [{len(done_rows)}/{len(jobs)}] run {row.index} {row.kind}: "
                    f"{row.outcome} {row.error}",
                    flush=True,
                )

        run_campaign(todo, workers=args.workers, keep_traces=args.keep_traces, on_row=progress)
    elapsed = time.perf_counter() - start
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    rows = [done_rows[j.number] for j in jobs if j.number in done_rows]
    print()
    print(format_table(rows))
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
