"""Per-call cost of the EndoBot model's hot functions, in µs (median of repeats).

Run: ``python benchmarks/robot_call_cost.py``. The 1 kHz budget target is
FK + Jacobian + gravity + one controller update <= 20 µs median together; the
controller update is measured by the control library's own benchmark. The
last rows are the simulated robot's per-tick cost (friction solve + PyBullet
step), for a sense of the physics budget.
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


def per_call_us(fn: Callable[[], object], number: int = NUMBER) -> float:
    """Median per-call time [µs] over REPEATS batches of ``number`` calls."""
    times = timeit.repeat(fn, number=number, repeat=REPEATS)
    return statistics.median(times) / number * 1e6


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
    sim_rows()


def sim_rows() -> None:
    """Per-tick cost of :class:`backends.pybullet.robot.EndoBotSim`, one robot, DIRECT."""
    import pybullet as p

    from backends.pybullet.robot import EndoBotSim

    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)
        sim = EndoBotSim(cid)
        tau = np.array([0.1, 0.1, 0.01, 2.0])
        apply_us = per_call_us(lambda: sim.apply(tau), number=200)
        step_us = per_call_us(lambda: sim.step(tau), number=200)
    finally:
        p.disconnect(cid)
    print(f"{'EndoBotSim.apply (friction)':<28}{apply_us:>16.2f}")
    print(f"{'EndoBotSim.step (+physics)':<28}{step_us:>16.2f}")


if __name__ == "__main__":
    main()
