"""Cost and accuracy of the knot classifier on 40-120 point centerlines.

Each hand-built curve (suture_engine.suture.curves) is resampled by arc
length to N points, rotated at random and given Gaussian noise (1 % of the
curve's radius), then classified with 5 voting projections. Prints, per
curve and N: the share of correct answers and the wall time per call
(median, 95th percentile, max) after a warm-up call.

    python benchmarks/knot_classify.py [--runs 50]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from suture_engine.suture import curves
from suture_engine.suture.topology import classify_knot

CASES = {
    "trefoil (right)": (lambda: curves.trefoil(400), ("trefoil", "right")),
    "figure-eight": (lambda: curves.figure_eight(400), ("figure-eight", None)),
    "square": (lambda: curves.square_knot(300), ("square", None)),
    "granny (left)": (lambda: curves.granny_knot(300, right=False), ("granny", "left")),
    "double overhand (right)": (lambda: curves.overhand(2, n=40), ("double-overhand", "right")),
    "surgeon's knot": (lambda: curves.surgeons_knot(), ("surgeons", "right")),
    "wobbly unknot": (lambda: curves.wobbly_unknot(400), ("unknot", None)),
}


def resample(points: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """n points equally spaced in arc length along a polyline."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    target = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(target, s, points[:, k]) for k in range(3)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    print(f"{'curve':<18}{'N':>5}{'correct':>10}{'median ms':>11}{'p95 ms':>9}{'max ms':>9}")
    for name, (make, expected) in CASES.items():
        base = make()
        radius = float(np.max(np.linalg.norm(base - base.mean(axis=0), axis=1)))
        for n in (40, 80, 120):
            pts = resample(base, n)
            classify_knot(pts)  # warm-up
            times, correct = [], 0
            for k in range(args.runs):
                rot = Rotation.random(random_state=k).as_matrix()
                noisy = (pts + rng.normal(scale=0.01 * radius, size=pts.shape)) @ rot.T
                t0 = time.perf_counter()
                rep = classify_knot(noisy, seed=k)
                times.append(time.perf_counter() - t0)
                correct += (rep.type, rep.chirality) == expected
            ms = 1e3 * np.array(times)
            print(
                f"{name:<18}{n:>5}{correct / args.runs:>10.0%}{np.median(ms):>11.1f}"
                f"{np.percentile(ms, 95):>9.1f}{ms.max():>9.1f}"
            )


if __name__ == "__main__":
    main()
