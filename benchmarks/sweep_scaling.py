"""Speed-up of ``suture sweep`` from 1 to 2 worker processes on a fixed batch.

Runs the same batch (``tests/procedures/steps.yaml``, fixed seeds and values) in the
spawn process pool with 1 and then 2 workers, and prints the wall times, the
speed-up T1/T2 and the parallel efficiency T1 / (2 T2) (target >= 85%). The
machine's load average is printed beside them: other work on the machine takes
cores away from the pool.

Usage:
    python benchmarks/sweep_scaling.py [--runs 8] [--hold 1.5]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from suture_engine.report.sweep import SweepConfig, _pool_results, parse_vary, run_sweep

ROOT = Path(__file__).resolve().parents[1]
PROCEDURE = ROOT / "tests" / "procedures" / "steps.yaml"


def _timed(runs: int, hold_s: float, workers: int) -> float:
    vary = (parse_vary(f"hold_time=uniform({hold_s} s, {hold_s} s)"),)
    config = SweepConfig(PROCEDURE, runs, vary, base_seed=0, max_time_s=30.0)
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        result = run_sweep(config, out, runner=lambda jobs: _pool_results(jobs, workers))
        elapsed = time.perf_counter() - start
    bad = [r for r in result.rows if r.outcome != "succeeded"]
    if bad:
        raise SystemExit(f"{len(bad)} runs did not succeed: {bad[0]}")
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=8, help="runs in the batch")
    parser.add_argument("--hold", type=float, default=1.5, help="first hold of steps.yaml [s]")
    args = parser.parse_args()
    load_before = os.getloadavg()
    t1 = _timed(args.runs, args.hold, 1)
    t2 = _timed(args.runs, args.hold, 2)
    load_after = os.getloadavg()
    speedup = t1 / t2
    print(f"batch: {args.runs} runs of {PROCEDURE.name}, hold_time {args.hold} s, spawn pool")
    print(f"cores: {os.cpu_count()}, load average (1 min) before {load_before[0]:.2f}, "
          f"after {load_after[0]:.2f}")  # fmt: skip
    print(f"1 worker : {t1:7.2f} s  ({t1 / args.runs:.2f} s per run)")
    print(f"2 workers: {t2:7.2f} s  ({t2 / args.runs:.2f} s per run)")
    print(f"speed-up : {speedup:.2f}x   efficiency {speedup / 2:.0%} (target >= 85%)")


if __name__ == "__main__":
    main()
