"""What the monitor's tension estimate reads with no thread, and with a known tip force.

1. Both robots tour their workspace (``tests/procedures/tour.yaml``) on the PyBullet
   backend (robots only, no thread) at several tool speeds. Printed per speed: the
   largest tension the monitor read (the thesis' base-sensor estimate, 7.6-7.9,
   low-pass filtered) beside what the previous monitor read (the tared magnitude
   of the base force, unfiltered), both over the whole run.
2. The stitcher holds still; PyBullet pushes its tool tip with a known force for
   1 s. Printed: the force, the estimate 0.5-0.9 s into the push and the moment
   left about the tool tip (7.9; ~0 for a pure tip force).

Usage: ``python benchmarks/tension_estimate.py [--speeds 20,50,100]`` (mm/s).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
PROCS = ROOT / "tests" / "procedures"


def _run(procedure: Path, sets: list[str], on_tick: Any, max_time_s: float) -> Any:
    """Run ``procedure`` on pybullet (seed 1) into a temporary folder; its summary."""
    import tempfile

    from suture_engine.runtime.run import run_procedure

    with tempfile.TemporaryDirectory() as out:
        return run_procedure(
            procedure,
            backend="pybullet",
            seed=1,
            sets=sets,
            out=Path(out) / "run",
            max_time_s=max_time_s,
            on_tick=on_tick,
        ).summary


def tour(speed_mm_s: float) -> tuple[str, float, float, float]:
    """(outcome, sim time [s], new max [N], previous monitor's max [N]) of one tour."""
    previous = [0.0]
    tare: dict[str, np.ndarray] = {}  # the first measurement, as the runtime tares

    def on_tick(it: Any) -> None:
        for name, robot in it._obs.robots.items():
            zero = tare.setdefault(name, np.array(robot.base_wrench[:3]))
            f = np.asarray(robot.base_wrench[:3]) - zero
            previous[0] = max(previous[0], float(np.linalg.norm(f)))

    s = _run(PROCS / "tour.yaml", [f"speed={speed_mm_s:g} mm/s"], on_tick, 30.0)
    return s.outcome, s.sim_time_s, s.max_tension_N, previous[0]


def push() -> tuple[float, float, float, float]:
    """(|F| [N], min and max estimate 0.5-0.9 s into the push [N], max tip moment [N*m])."""
    force = np.array([0.9, -0.6, 1.1])
    read: list[float] = []
    moment: list[float] = []

    def on_tick(it: Any) -> None:
        t = round(it._obs.t, 3)
        if t == 0.5:
            it.backend.apply_external_force("endobot_1", tuple(force), 1.0)
        if 1.0 <= t <= 1.4:
            read.append(it._tension["endobot_1"])
            w = it.tension.tip_wrench("endobot_1", it._obs.robots["endobot_1"])
            moment.append(math.sqrt(w[3] ** 2 + w[4] ** 2 + w[5] ** 2))

    _run(PROCS / "steps.yaml", ["hold_time=1.8 s"], on_tick, 1.5)
    return float(np.linalg.norm(force)), min(read), max(read), max(moment)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speeds", default="20,50,100", help="tool speeds [mm/s]")
    args = parser.parse_args()
    print("tour of the workspace, no thread (tests/procedures/tour.yaml, pybullet, seed 1)")
    print(
        f"{'speed':>8} {'outcome':>10} {'sim [s]':>8} {'estimate max [N]':>17} {'previous [N]':>13}"
    )
    for speed in (float(v) for v in args.speeds.split(",")):
        outcome, sim, new, old = tour(speed)
        print(f"{speed:>5g} mm/s {outcome:>10} {sim:>8.2f} {new:>17.3f} {old:>13.3f}")
    f, lo, hi, m = push()
    print("known force on the stitcher's tool tip, robot holding (steps.yaml, pybullet)")
    print(
        f"  |F| = {f:.4f} N; estimate {lo:.4f}-{hi:.4f} N "
        f"({100 * (lo / f - 1):+.2f}% to {100 * (hi / f - 1):+.2f}%); "
        f"moment left about the tip <= {m:.2e} N*m"
    )


if __name__ == "__main__":
    main()
