"""Friction compensation while tracking circles (thesis 5.2.2, Tables 5.1-5.2, Figs. 5.3-5.4).

The simulated EndoBot E1 tracks horizontal tool-tip circles 0.10 m below the
RCM under the PD law (5.10) with gravity compensation and 7 Hz critically
damped gains (5.15-5.18), velocity from a washout filter, quantised encoders.
Table 5.1: the 10 mm / 0.25 Hz circle with Coulomb compensation (5.19) off and
on, in two conditions: (1) the simulated friction is model b and the
controller's model is exact; (2) the simulated friction has stiction and the
Stribeck effect (model d) and the controller compensates with the other
robot's (E2's) parameters. Table 5.2: all nine circles, compensation on,
condition (2). The first period of each run is not scored.

    python benchmarks/friction_compensation.py --out results/friction
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from suture_engine.control.tracking import (
    TABLE_5_2_FREQUENCIES,
    TABLE_5_2_RADII,
    run_circle_tracking,
)
from suture_engine.robot.params import E2

CONDITIONS = {
    "exact model, friction b": {"friction_model": "b", "model_params": None},
    "E2 model on E1, stiction (d)": {"friction_model": "d", "model_params": E2},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/friction_compensation"))
    parser.add_argument("--skip-table-5-2", action="store_true")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()

    print("Table 5.1: 10 mm circle at 0.25 Hz, PD 7 Hz (thesis: off 0.970 mm, on 0.466 mm)")
    header = "condition                      comp  max j1  max j2  mean j1 mean j2  cart mean [mm]"
    print(header + "\n" + "-" * len(header))
    fig, axes = plt.subplots(1, len(CONDITIONS), figsize=(11, 5))
    for ax, (name, cond) in zip(axes, CONDITIONS.items(), strict=True):
        for comp in (False, True):
            r = run_circle_tracking(0.010, 0.25, friction_compensation=comp, **cond)  # type: ignore[arg-type]
            print(
                f"{name:30s} {'on ' if comp else 'off'}  {r.max_joint_error_deg[0]:6.3f}  "
                f"{r.max_joint_error_deg[1]:6.3f}  {r.mean_joint_error_deg[0]:6.3f}  "
                f"{r.mean_joint_error_deg[1]:6.3f}   {r.mean_cartesian_error_mm:7.4f}"
            )
            err = 1e3 * (r.tip[:, :2] - r.tip_ref[:, :2])
            ax.plot(
                1e3 * r.tip_ref[:, 0] + 20 * err[:, 0],
                1e3 * r.tip_ref[:, 1] + 20 * err[:, 1],
                label=f"compensation {'on' if comp else 'off'}",
            )
        ax.plot(1e3 * r.tip_ref[:, 0], 1e3 * r.tip_ref[:, 1], "k--", lw=0.8, label="desired")
        ax.set_title(f"{name}\n(error magnified x20)")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_aspect("equal")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out / "table_5_1_circles.png", dpi=120)
    print("(joint errors in deg)")

    if not args.skip_table_5_2:
        cond = CONDITIONS["E2 model on E1, stiction (d)"]
        print("\nTable 5.2: mean Cartesian error [mm], compensation on, E2 model on E1, stiction")
        print("freq [Hz]   r=2.5 mm   r=5 mm   r=10 mm    (thesis row w1: 0.409 0.463 0.487)")
        for f in TABLE_5_2_FREQUENCIES:
            row = []
            for rad in TABLE_5_2_RADII:
                res = run_circle_tracking(rad, f, friction_compensation=True, **cond)  # type: ignore[arg-type]
                row.append(res.mean_cartesian_error_mm)
            print(f"{f:8.2f}   " + "   ".join(f"{x:7.4f}" for x in row))
    print(f"\nfigures in {args.out}; wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
