"""Speed-up of ``suture sweep`` from 1 to 2 worker processes on a fixed batch.

Runs the same batch (``tests/procedures/steps.yaml``, fixed seeds and values) in the
spawn process pool with 1 and then 2 workers, and prints the wall times, the
speed-up T1/T2 and the parallel efficiency T1 / (2 T2) (target >= 85%). The
machine's load average and the workers' CPU share are printed beside them: other
work on the machine takes cores away from the pool, and then the figure measures
the machine, not the sweep.

Usage:
    python benchmarks/sweep_scaling.py [--runs 8] [--hold 1.5]
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

from suture_engine.report.sweep import SweepConfig, _pool_results, parse_vary, run_sweep

ROOT = Path(__file__).resolve().parents[1]
PROCEDURE = ROOT / "tests" / "procedures" / "steps.yaml"


def _timed(runs: int, hold_s: float, workers: int) -> tuple[float, float]:
    """``(wall time [s], CPU time of the worker processes [s])`` of the batch."""
    vary = (parse_vary(f"hold_time=uniform({hold_s} s, {hold_s} s)"),)
    config = SweepConfig(PROCEDURE, runs, vary, base_seed=0, max_time_s=30.0)
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        result = run_sweep(config, out, runner=lambda jobs: _pool_results(jobs, workers))
        elapsed = time.perf_counter() - start
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    bad = [r for r in result.rows if r.outcome != "succeeded"]
    if bad:
        raise SystemExit(f"{len(bad)} runs did not succeed: {bad[0]}")
    return elapsed, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=8, help="runs in the batch")
    parser.add_argument("--hold", type=float, default=1.5, help="first hold of steps.yaml [s]")
    args = parser.parse_args()
    load_before = os.getloadavg()
    t1, cpu1 = _timed(args.runs, args.hold, 1)
    t2, cpu2 = _timed(args.runs, args.hold, 2)
    load_after = os.getloadavg()
    speedup = t1 / t2
    print(f"batch: {args.runs} runs of {PROCEDURE.name}, hold_time {args.hold} s, spawn pool")
    print(f"cores: {os.cpu_count()}, load average (1 min) before {load_before[0]:.2f}, "
          f"after {load_after[0]:.2f}")  # fmt: skip
    # CPU share: the workers' CPU time over (wall time x workers); well below 100% means
    # the workers waited for a core (other load), not that the sweep serialises.
    print(f"1 worker : {t1:7.2f} s  ({t1 / args.runs:.2f} s per run), CPU share {cpu1 / t1:.0%}")
    print(
        f"2 workers: {t2:7.2f} s  ({t2 / args.runs:.2f} s per run), CPU share {cpu2 / (2 * t2):.0%}"
    )
    print(f"speed-up : {speedup:.2f}x   efficiency {speedup / 2:.0%} (target >= 85%)")


if __name__ == "__main__":
    main()
