"""Per-call cost of the EndoBot model's hot functions, in µs (median of repeats).

Run: ``python benchmarks/robot_call_cost.py``. The 1 kHz budget target is
FK + Jacobian + gravity + one controller update <= 20 µs median together; the
controller update is measured by the control library's own benchmark.
"""

from __future__ import annotations

import statistics
import timeit
from collections.abc import Callable

import numpy as np

from suture_engine.robot import endobot
from suture_engine.robot.params import E1

REPEATS = 31
NUMBER = 2000


def per_call_us(fn: Callable[[], object]) -> float:
    """Median per-call time [µs] over REPEATS batches of NUMBER calls."""
    times = timeit.repeat(fn, number=NUMBER, repeat=REPEATS)
    return statistics.median(times) / NUMBER * 1e6


def main() -> None:
    """Print the table."""
    q = np.array([0.2, -0.3, 0.4, 0.12])
    qd = np.array([0.5, -0.2, 0.3, 0.01])
    jac = np.zeros((4, 4))
    g = np.zeros(4)
    rows = {
        "forward_kinematics": lambda: endobot.forward_kinematics(q),
        "jacobian (out=)": lambda: endobot.jacobian(q, out=jac),
        "gravity_vector (out=)": lambda: endobot.gravity_vector(q, E1, out=g),
        "mass_matrix": lambda: endobot.mass_matrix(q, E1),
        "coriolis_vector": lambda: endobot.coriolis_vector(q, qd, E1),
        "jacobian (new array)": lambda: endobot.jacobian(q),
        "gravity_vector (new array)": lambda: endobot.gravity_vector(q, E1),
    }
    results = {name: per_call_us(fn) for name, fn in rows.items()}
    print(f"{'call':<28}{'median µs/call':>16}")
    for name, us in results.items():
        print(f"{name:<28}{us:>16.2f}")
    hot = ("forward_kinematics", "jacobian (out=)", "gravity_vector (out=)")
    total = sum(results[name] for name in hot)
    print(f"{'FK + Jacobian + gravity':<28}{total:>16.2f}")


if __name__ == "__main__":
    main()
