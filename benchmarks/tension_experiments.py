"""The tension-control experiments of thesis 7.5 (Fig. 7.20, Tables 7.3-7.5), simulated.

A step of tension (15 N) is commanded on a suture whose free tail is fixed; the
suture is a unilateral spring-damper from the EndoBot's tool tip to the fixture
(see :mod:`suture_engine.control.tension_experiment` for the model and its
parameters). Prints, per gain set, the RMS force error against the desired
tension and against the reference actually used, the largest measured tension
(the thesis' e_inf), the largest true tension of the simulated suture, and the
mean error over the last second, beside the thesis' e_RMS and e_inf. Then a
sensitivity section: the peaks of three rows with a softer suture and with less
slack, so the reader sees what the ordering depends on.

Usage: ``python benchmarks/tension_experiments.py [duration_s] [--no-sensitivity]``
(default 30 s, as Figs. 7.21-7.29). Runs use both cores.
"""

from __future__ import annotations

import sys
import time
from concurrent.futures import ProcessPoolExecutor

from suture_engine.control.tension_experiment import (
    THESIS_TABLE,
    SutureSpring,
    TensionCase,
    TensionRun,
    run_tension_experiment,
    thesis_cases,
)


def _run(args: tuple[TensionCase, float, SutureSpring]) -> tuple[TensionRun, float]:
    case, duration, spring = args
    t0 = time.perf_counter()
    run = run_tension_experiment(case, duration=duration, spring=spring)
    return run, time.perf_counter() - t0


def main(argv: list[str]) -> int:
    """Print the table; return 0."""
    duration = float(argv[0]) if argv and not argv[0].startswith("-") else 30.0
    sensitivity = "--no-sensitivity" not in argv
    spring = SutureSpring()
    cases = thesis_cases()
    print(
        f"Tension step to 15 N, {duration:g} s per run; suture k = {spring.stiffness:g} N/m, "
        f"b = {spring.damping:g} N*s/m, {spring.slack * 1e3:g} mm slack; force loop 500 Hz, "
        "torques 1 kHz; tension from the base F/T sensor."
    )
    print("e_RMS: vs F_des (vs f_r); e_inf = max |f_m| (thesis' definition); thesis: step to -15 N")
    head = (
        f"{'gains':34s} {'e_RMS [N]':>16s} {'e_inf [N]':>9s} {'true max':>9s} "
        f"{'final':>7s} | {'thesis e_RMS':>12s} {'e_inf':>6s}"
    )
    print(head)
    print("-" * len(head))
    with ProcessPoolExecutor(2) as pool:
        results = list(pool.map(_run, [(c, duration, spring) for c in cases]))
    wall = 0.0
    for run, w in results:
        wall += w
        th_rms, th_inf = THESIS_TABLE[run.case.label]
        print(
            f"{run.case.label:34s} {run.rms_error:7.2f} ({run.rms_reference:5.2f}) "
            f"{run.max_force:9.2f} {run.max_true:9.2f} {run.final_error:7.3f} | "
            f"{th_rms:12.2f} {th_inf:6.2f}"
        )
    peaks = {run.case.label: run.max_force for run, _ in results}
    i0, i1, i2, ramp = (cases[i].label for i in (0, 1, 2, 5))
    damped = peaks[i1] < peaks[i0] and peaks[i2] < peaks[i0]
    lower = peaks[ramp] < peaks[i2]
    print(f"\nactive damping lowers the peak (Kv = 1000 and 2000 vs 0):  {damped}")
    print(f"ramped reference lowers it further (vs Ki=0.5, Kv=2000):    {lower}")
    print(f"Kv = 2000 below Kv = 1000 (thesis: yes):                     {peaks[i2] < peaks[i1]}")
    print(
        "overshoot above 15 N: "
        + ", ".join(f"{k}: {max(0.0, v - 15.0):.2f}" for k, v in peaks.items())
    )
    print(f"[{wall:.1f} s of run time on 2 processes]")
    if sensitivity:
        print("\nSensitivity of the peaks e_inf [N] to the suture (same gains, same duration):")
        rows = (cases[0], cases[2], cases[5])
        variants = (
            ("soft k = 2000 N/m", SutureSpring(stiffness=2000.0)),
            ("slack 2 mm", SutureSpring(slack=0.002)),
        )
        print(f"{'suture':20s} " + " ".join(f"{c.label:>34s}" for c in rows))
        print(f"{'default':20s} " + " ".join(f"{peaks[c.label]:34.2f}" for c in rows))
        with ProcessPoolExecutor(2) as pool:
            for name, sp in variants:
                runs = list(pool.map(_run, [(c, duration, sp) for c in rows]))
                print(f"{name:20s} " + " ".join(f"{r.max_force:34.2f}" for r, _ in runs))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
