"""Identification accuracy per excitation signal, clean and with realistic encoder noise (3.5).

For each joint of the simulated EndoBot E1: friction from constant-velocity
sweeps (Fig. 3.17), then each of the four excitation signals (3.5.1) drives
the joint for --duration seconds with the same amplitude limit and band, and
both the differential (3.60-3.64) and the energy model (3.65-3.75, friction
first) are fitted to the same record. "Realistic" encoders are quantised at
2000 counts per motor revolution (2.3e-5 rad at the yaw/pitch joints) with
Gaussian noise of --noise rad (and m). Prints the relative errors of I, ml,
Fc and Fv (differential rows: the fit's own Fc, Fv; energy rows: the sweep's,
since the energy fit takes friction as given) and the regressor's condition
number (3.54).
Saves a bar chart of the worst |error| per signal.

    python benchmarks/identification_accuracy.py --out results/identification
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from suture_engine.robot.excitation import ExcitationKind
from suture_engine.robot.identification import fit_differential, fit_energy, fit_friction
from suture_engine.robot.identification_experiment import (
    DT,
    JOINT_PLANS,
    joint_truth,
    run_constant_velocity,
    run_excitation,
    simulated_endobot,
)

NAMES = ("yaw", "pitch", "roll", "insertion")


def _err(est: float, true: float) -> float:
    return math.nan if math.isnan(true) else 100.0 * (est - true) / true


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/identification"))
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--noise", type=float, default=1e-5)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    worst: dict[tuple[str, str, str], float] = {}
    for label, noisy in (("clean", False), ("realistic", True)):
        noise = args.noise if noisy else 0.0
        print(f"\n== {label} encoders" + (f" (quantised, noise {noise:g})" if noisy else ""))
        print("joint      signal      model          I err   ml err   Fc err   Fv err    cond")
        with simulated_endobot(encoder_noise=noise, quantised=noisy, seed=args.seed) as sim:
            for j, plan in enumerate(JOINT_PLANS):
                cutoff = plan.cutoff if noisy else None
                truth = joint_truth(sim.model_params, j, plan.hold)
                fr = fit_friction(*run_constant_velocity(sim, j, cutoff_hz=cutoff), plan.shape)
                for kind in ExcitationKind:
                    rec = run_excitation(sim, j, kind, args.duration, seed=args.seed + 1)
                    fits = {
                        "differential": fit_differential(
                            rec.q, rec.tau, DT, plan.shape, cutoff_hz=cutoff
                        ),
                        "energy": fit_energy(
                            rec.q, rec.tau, DT, plan.shape, cutoff_hz=cutoff, friction=fr,
                            window=50,
                        ),
                    }  # fmt: skip
                    for model, est in fits.items():
                        e = [_err(est[k], truth[k]) for k in range(4)]
                        if model == "energy":  # friction columns come from the sweeps
                            e[2], e[3] = _err(fr.coulomb, truth[2]), _err(fr.viscous, truth[3])
                        print(
                            f"{j + 1} {NAMES[j]:9s} {kind.value:10s} {model:12s} "
                            + " ".join(f"{x:+7.2f}%" if not math.isnan(x) else "      - "
                                       for x in e)
                            + f"  {est.condition:6.0f}"
                        )  # fmt: skip
                        key = (label, kind.value, model)
                        finite = [abs(x) for x in e[:2] if not math.isnan(x)]
                        worst[key] = max(worst.get(key, 0.0), max(finite))
    fig, ax = plt.subplots(figsize=(9, 4))
    labels = sorted({(k[1], k[2]) for k in worst})
    x = np.arange(len(labels))
    for i, cond in enumerate(("clean", "realistic")):
        ax.bar(x + 0.4 * i, [worst[(cond, s, m)] for s, m in labels], 0.4, label=cond)
    ax.set_xticks(x + 0.2, [f"{s}\n{m}" for s, m in labels], fontsize=7)
    ax.set_ylabel("worst |error| of I, ml over joints [%]")
    ax.set_yscale("log")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out / "identification_accuracy.png", dpi=120)
    print(f"\nfigure in {args.out}; wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
