"""The chapter 6 shared-control experiments on the simulated EndoBot (Tables 6.2-6.4).

A simulated operator pushes the tool tip "in all directions with the same impedance"
(6.3.4) while sliding along the fixture and rolling the tool; the shared controller
holds the fixture. Prints, per constraint row, the peak deviation, the peak constraint
force recovered from the applied torques (6.53) and their ratio (6.54), beside the
thesis' figures, plus the same stiffness seen from the operator's side (their normal
force against the deviation), which also carries inertia and joint friction.

Usage: ``python benchmarks/shared_control.py [duration_s]`` (default 8 s, as Fig. 6.3).
"""

from __future__ import annotations

import sys
import time

from suture_engine.control.shared_experiment import (
    ExperimentResult,
    OperatorModel,
    run_experiment,
    thesis_circle,
    thesis_line,
)

THESIS = {
    ("task", "line"): ((0.0047, 4.680, 1003.0), (0.0041, 4.097, 1002.0)),  # Table 6.2
    ("joint", "line"): ((0.0013, 8.1838, 6268.0), (0.00062, 9.763, 15570.0)),  # Table 6.3
    ("joint", "circle"): ((0.0032, 102.02, 31400.0), (0.002, 3.49, 1770.0)),  # Table 6.4
}


def _print(res: ExperimentResult, wall: float) -> None:
    title = {"task": "task-space (6.24)", "joint": "joint-space (6.35-6.37)"}[res.controller]
    desired = (
        f", desired stiffness {res.desired_stiffness:.0f} N/m" if res.controller == "task" else ""
    )
    limits = "" if res.saturate else ", NO motor torque limits"
    print(f"\n{title} shared control, {res.fixture}{desired}{limits}  [{wall:.1f} s wall]")
    print(
        f"{'row':4s} {'max|e| [m]':>11s} {'max|Fc| [N]':>12s} {'K (6.54) [N/m]':>15s}"
        f" {'operator K [N/m]':>17s} {'op. slope [N/m]':>16s}   thesis (e, Fc, K)"
    )
    ref = THESIS.get((res.controller, res.fixture))
    for i in range(len(res.table.stiffness)):
        th = f"{ref[i][0]:.4f} m, {ref[i][1]:.3f} N, {ref[i][2]:.0f} N/m" if ref else "-"
        print(
            f"ec{i + 1:<2d} {res.table.max_deviation[i]:11.5f} {res.table.max_force[i]:12.3f}"
            f" {res.table.stiffness[i]:15.0f} {res.operator_table.stiffness[i]:17.0f}"
            f" {res.operator_slope[i]:16.0f}   {th}"
        )
    if res.controller == "task":
        err = 100.0 * (res.table.stiffness / res.desired_stiffness - 1.0)
        print("stiffness error vs desired: " + ", ".join(f"{e:+.1f} %" for e in err))
    print(
        f"operator travel along the fixture {res.free_travel:.3f}"
        f" {'rad' if res.fixture == 'circle' else 'm'}, roll range {res.roll_range:.2f} rad,"
        f" ticks with a saturated motor {res.saturated_ticks} of {len(res.t)}"
    )


def main(duration: float = 8.0) -> None:
    gentle = OperatorModel(push=0.006)  # the insertion motor (2.47 N) carries ~2.3 N of weight
    runs = [
        (thesis_line(), "task", None, True),
        (thesis_circle(), "task", gentle, True),
        (thesis_circle(), "task", gentle, False),
        (thesis_line(), "joint", None, True),
        (thesis_circle(), "joint", gentle, True),
        (thesis_circle(), "joint", gentle, False),
    ]
    print(
        "Chapter 6 shared control on the PyBullet EndoBot (E1, Coulomb+viscous joint friction,"
        f" 1 kHz, {duration:.0f} s each)"
    )
    print("line: Table 6.1 (a = (1, 1, -2), z up) in the base frame; circle: Fig. 6.14.")
    for fixture, controller, op, saturate in runs:
        t0 = time.perf_counter()
        res = run_experiment(
            fixture, controller=controller, duration=duration, operator=op, saturate=saturate
        )
        _print(res, time.perf_counter() - t0)


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 8.0)
