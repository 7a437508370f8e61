"""The thread's rest test over damping rates: how far does a released knot move?

Run: ``python benchmarks/knot_rest.py [--rates 0.5,2,5,10,20,50] [--weights 0.1,4]
[--pull 1]``.
Lays the overhand and square knots on a flat plate, draws their ends apart to ``--pull``
newtons, holds 0.5 s and lets go (:func:`backends.pybullet.rest.released_knot_travel`),
and prints per damping rate (``SutureParams.linear_damping``, 0.5 /s by default) and
kept weight (``SutureParams.real_mass_per_length``, 0.1 g/m by default) how far any joint
of the thread moves in the 2 s after release [mm], the knot's type at the end, and beside
it the straight thread's spring-back (the chain's stretch alone).

It also prints what the two cost: a whole thread dragged at 20 mm/s is held back by its
capsules' mass times the rate times (1 + speed) times the speed [mN]; the thread falls
at most at the kept weight over its simulated mass and the rate [mm/s]; and the whole
thread's kept weight [mN].
"""

from __future__ import annotations

import argparse
import time

import suture_engine  # noqa: F401 (first: it pins OpenBLAS' kernel before numpy loads)


def main() -> None:
    """Print the table (module doc)."""
    from backends.pybullet.rest import released_knot_travel
    from backends.pybullet.suture import SutureParams

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", default="0.5,2,5,10,20,50", help="damping rates [1/s]")
    ap.add_argument("--weights", default="0.1,4", help="kept weights [g/m]")
    ap.add_argument("--pull", type=float, default=1.0, help="the pull before release [N]")
    args = ap.parse_args()
    rates = [float(r) for r in args.rates.split(",")]
    weights = [float(w) * 1e-3 for w in args.weights.split(",")]
    speed = 0.02
    print(f"released after a {args.pull:g} N pull, watched 2 s; travel of the farthest joint")
    print(
        "| rate [1/s] | weight [g/m] | overhand [mm] | square [mm] | straight [mm] "
        "| drag at 20 mm/s [mN] | fall at most [mm/s] | weight [mN] |"
    )
    print("|---|---|---|---|---|---|---|---|")
    t0 = time.perf_counter()
    for weight in weights:
        prm = SutureParams(real_mass_per_length=weight)
        for rate in rates:
            cells = []
            for throws in ((False,), (False, True), None):
                r = released_knot_travel(throws, rate, pull=args.pull, params=prm)
                kind = "" if throws is None else f" ({r.type})"
                cells.append(f"{r.travel * 1e3:.2f}{kind}" if r.reached else "not reached")
            mass = prm.n_segments * prm.segment_mass
            drag = mass * rate * (1 + speed) * speed
            pull = 9.81 * weight * prm.length  # the kept weight [N]
            fall = pull / (mass * rate) if rate > 0 else float("inf")
            print(
                f"| {rate:g} | {weight * 1e3:g} | {' | '.join(cells)} | {drag * 1e3:.1f} "
                f"| {fall * 1e3:.1f} | {pull * 1e3:.2f} |"
            )
    print(f"{time.perf_counter() - t0:.0f} s wall")


if __name__ == "__main__":
    main()
