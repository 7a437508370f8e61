"""Correlation between the energy model's regressor columns (thesis Table 3.2, (3.77)).

Schroeder-phased torque excites each joint of the simulated EndoBot E1 (10 s,
as in Fig. 3.18); the energy-model regressor (3.75) is built over windows of
--window samples; the coefficients of cross-correlation between its columns
[dKE, dPE, int|qd|, int qd^2] are printed in the layout of Table 3.2. The
Coulomb and viscous columns (3, 4) are the nearly collinear pair; the thesis
reports r34 = 0.9442 on the real first joint. Also shows what the collinearity
does: the four-parameter energy fit next to the friction-first fit.

    python benchmarks/energy_model_correlation.py --out results/energy
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from suture_engine.robot.identification import (
    column_correlation,
    energy_regressor,
    estimate_motion,
    fit_energy,
    fit_friction,
)
from suture_engine.robot.identification_experiment import (
    DT,
    JOINT_PLANS,
    joint_truth,
    run_constant_velocity,
    run_excitation,
    simulated_endobot,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/energy_model_correlation"))
    parser.add_argument("--window", type=int, default=50)
    parser.add_argument("--joints", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with simulated_endobot() as sim:
        for j in (k - 1 for k in args.joints):
            plan = JOINT_PLANS[j]
            rec = run_excitation(sim, j, "schroeder", 10.0)
            _, v, _ = estimate_motion(rec.q, DT, None)
            sl = slice(1, rec.q.size - 1)
            rows, _ = energy_regressor(
                rec.q[sl], v[sl], rec.tau[sl], DT, plan.shape, window=args.window
            )
            r = column_correlation(rows)
            print(f"\nJoint {j + 1}: correlation of energy-regressor columns (Table 3.2 layout)")
            print("column        1         2         3         4")
            for a in range(4):
                cells = [f"{r[a, b]:8.4f}" if b > a else "       -" for b in range(4)]
                print(f"  {a + 1}    " + "  ".join(cells))
            print(f"  r34 (Coulomb vs viscous) = {r[2, 3]:.4f}   (thesis, joint 1: 0.9442)")
            truth = joint_truth(sim.model_params, j, plan.hold)
            all4 = fit_energy(rec.q, rec.tau, DT, plan.shape, window=args.window)
            fr = fit_friction(*run_constant_velocity(sim, j), plan.shape)
            first = fit_energy(rec.q, rec.tau, DT, plan.shape, window=args.window, friction=fr)
            print("            I         ml        Fc        Fv      cond")
            for name, est in (("all four", all4), ("fric first", first), ("truth", truth)):
                print(
                    f"  {name:10s}" + "".join(f"{est[k]:9.4f} " for k in range(4))
                    + ("" if np.isnan(est.condition) else f"{est.condition:7.0f}")
                )  # fmt: skip
            fig, ax = plt.subplots(figsize=(4.5, 4))
            ax.scatter(rows[:, 2], rows[:, 3], s=4)
            ax.set_xlabel("window integral of |qd| [rad]")
            ax.set_ylabel("window integral of qd^2 [rad^2/s]")
            ax.set_title(f"joint {j + 1}: r = {r[2, 3]:.3f}")
            fig.tight_layout()
            fig.savefig(args.out / f"energy_columns_joint{j + 1}.png", dpi=120)
    print(f"\nfigures in {args.out}")


if __name__ == "__main__":
    main()
