"""Knot placement (thesis 4.5): loop-end trajectories for beta = 0 and beta = beta_max.

Entry and exit points 10 mm apart, the knot starts 30 mm above the tissue
and slides down the normal at 5 mm/s to 1 mm above it; friction between
strands mu = 0.3; 10 mm of free strand between knot and grasp. Prints the
loop end (strand 2) in the knot-tying plane (u along entry -> exit, v along
the normal) and the bridge tension per applied tension, for the
minimum-tension choice beta = beta_min = 0 (4.40) and for the steepest pull
that still slides, 0.95 beta_max(gamma) (4.31); compare thesis Fig. 4.19.

    python benchmarks/knot_placement.py
"""

from __future__ import annotations

import numpy as np

from suture_engine.suture.knot import placement_trajectory


def main() -> None:
    pa, pb, normal = np.array([-0.005, 0, 0]), np.array([0.005, 0, 0]), np.array([0, 0, 1.0])
    knot0 = np.array([0.0, 0.0, 0.03])
    runs = {
        "beta = 0 (4.40)": placement_trajectory(
            pa, pb, knot0, normal, rate=0.005, mu=0.3, lengths=(0.01, 0.01), seat_height=0.001
        ),
        "beta = 0.95 beta_max": placement_trajectory(
            pa,
            pb,
            knot0,
            normal,
            rate=0.005,
            mu=0.3,
            lengths=(0.01, 0.01),
            seat_height=0.001,
            beta="max",
        ),
    }
    for name, tr in runs.items():
        print(f"\n{name}")
        print(
            f"{'t [s]':>7}{'knot v [mm]':>13}{'gamma [deg]':>13}{'beta [deg]':>12}"
            f"{'end u [mm]':>12}{'end v [mm]':>12}{'F_b/F_a':>9}"
        )
        for k in np.linspace(0, len(tr.time) - 1, 8).astype(int):
            print(
                f"{tr.time[k]:7.2f}{1e3 * tr.knot[k, 2]:13.2f}{np.degrees(tr.gamma[k, 1]):13.1f}"
                f"{np.degrees(tr.beta[k, 1]):12.1f}{-1e3 * tr.end2[k, 0]:12.2f}"
                f"{1e3 * tr.end2[k, 2]:12.2f}{tr.tension_ratio[k, 1]:9.3f}"
            )


if __name__ == "__main__":
    main()
