"""Per-tick cost of one simulated EndoBot (backends.pybullet.robot.EndoBotSim), in µs.

What a backend pays per robot and control tick: ``apply`` (torque checks, clipping,
the friction solve of models a-d, one joint-state read, the torque command),
``measure`` (one joint-state read for the encoders and the base F/T joint, the
sensor models); ``apply`` with friction off shows what the friction solve costs;
for scale, ``true_tool_pose`` and PyBullet's ``stepSimulation`` of that one robot.
``measure`` is timed with ideal sensors and with the base sensor of the bench
scene (``procedures/scenes/bench.yaml``: force noise 0.02 N on Fx, Fy, Fz, 2 ms
delay; the ideal encoders then keep drawing from the shared generator). The robot moves between
calls (a sine torque) so the unmodelled-torque estimate runs as in a procedure.

Medians of CPU time (``time.thread_time_ns``) over batches, so other jobs on a shared
machine inflate the figures less than wall time; pin it to one core:

    taskset -c 1 python benchmarks/endobot_sim_cost.py [--batches 15] [--calls 400]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np


def per_call_us(
    fn: Callable[[], object], batches: int, calls: int, between: Callable[[], object] | None = None
) -> float:
    """Median CPU time of ``fn`` per call [µs] over ``batches`` batches of ``calls`` calls;
    ``between`` (untimed) runs after each call."""
    clock = time.thread_time_ns
    out = []
    for _ in range(batches):
        spent = 0
        for _ in range(calls):
            t0 = clock()
            fn()
            spent += clock() - t0
            if between is not None:
                between()
        out.append(spent / calls / 1e3)
    return statistics.median(out)


def main() -> None:
    """Time the calls and print the table."""
    import pybullet as p

    from backends.pybullet.robot import EndoBotSim
    from backends.pybullet.sensors import SensorModel

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--batches", type=int, default=15)
    ap.add_argument("--calls", type=int, default=400)
    args = ap.parse_args()
    kw = {"batches": args.batches, "calls": args.calls}
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"EndoBotSim, median CPU µs per call; load average {load:.2f}")
    noisy_ft = SensorModel(noise_std=(0.02, 0.02, 0.02, 0.0, 0.0, 0.0), delay_ticks=2)
    cid = p.connect(p.DIRECT)
    rows: list[tuple[str, float]] = []
    try:
        p.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)

        def step() -> None:
            p.stepSimulation(physicsClientId=cid)

        for model in ("a", "b", "c", "d", None):
            sim = EndoBotSim(cid, friction_model=model or "b", friction=model is not None)
            drive = _Drive(sim, step)
            label = f"apply, friction model {model}" if model else "apply, friction off"
            rows.append((label, per_call_us(drive.apply, between=drive.advance, **kw)))
            p.removeBody(sim.body_id, physicsClientId=cid)
        for label, ft in (
            ("measure, ideal sensors", None),
            ("measure, noisy delayed F/T", noisy_ft),
        ):
            sim = EndoBotSim(cid, ft_sensor=ft)
            rows.append((label, per_call_us(sim.measure, between=step, **kw)))
            p.removeBody(sim.body_id, physicsClientId=cid)
        sim = EndoBotSim(cid)
        rows.append(("true_tool_pose", per_call_us(sim.true_tool_pose, **kw)))
        rows.append(("stepSimulation, one robot", per_call_us(step, **kw)))
    finally:
        p.disconnect(cid)
    for label, us in rows:
        print(f"  {label:<36}{us:>8.2f}")


class _Drive:
    """A sine torque that keeps one robot moving between timed calls."""

    def __init__(self, sim: Any, step: Callable[[], None]) -> None:
        self.sim = sim
        self.step = step
        self.k = 0
        self.tau = np.zeros(4)
        self.advance()

    def apply(self) -> None:
        self.sim.apply(self.tau)

    def advance(self) -> None:
        """Step the world, then the next tick's torque [N*m, N*m, N*m, N]."""
        self.step()
        self.k += 1
        t = self.k * 1e-3
        self.tau = np.array([0.05 * math.sin(3 * t), 0.05 * math.cos(2 * t), 0.01, 1.0])


if __name__ == "__main__":
    main()
