"""The thesis' knot failures, reproduced in physics and detected from the ground truth.

1. **Granny knot** (4.4.1: the second throw must be the mirror image). Two throws are
   tied by tool motion on the peg jig (``backends.pybullet.tying.tie_on_jig``): with the
   second throw mirrored the ground-truth classifier must say ``square``; leaving the
   mirror out must give ``granny``. The jig ties the two throws about 0.3 m apart on a
   free thread (no tissue, no post strand), so only the knot type is judged there.
2. **Two half hitches** (7.4, Fig. 7.4: the second throw pulled the wrong way). The
   jig cannot pull a throw the wrong way round a post, so this part is built another
   way and says so: two-strand knots are LAID in the simulator along hand-built curves
   (the square knot's two interlocked bights, and a strand wound twice round a
   straight post), the thread's ends held by graspers and the stitch loop's lowest
   point by a third, fixed one (the tissue); the thread then settles under gravity and
   contact for ``--settle`` seconds and its ends are pulled apart to ``--pull`` N
   (``backends.pybullet.scene.pull_ends``). ``suture_engine.suture.knot.knot_lay``
   judges the settled centerline: ``square`` (post_straight true) for the bights,
   ``half-hitches`` (post_straight false) for the wound strand. This shows the
   detector on simulated centerlines (capsule contacts, sag, stretch); it does not
   show the capsizing itself.

   Two protocols: strand 1's end alone pulled along -x with the other end and the
   tissue grip held (the pull that straightens one strand), and both ends pulled apart.

Usage: ``python benchmarks/failure_analysis.py [--skip-jig] [--settle 0.2] [--pull 0.5]``.
The jig ties take minutes each (two on two processes).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, NamedTuple

import suture_engine  # noqa: F401 (first: it pins OpenBLAS' kernel before numpy loads)

# isort: split
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

UNIT = 2.0e-3
"""Length of one unit of the hand-built lays [m]: strands cross 1 unit (2 mm) apart."""
SEGMENT = 2.2e-3
"""Capsule length of the laid thread [m] (> 2 x the 0.9 mm contact radius)."""


# -- hand-built two-strand lays (units; strand 1, stitch loop, strand 2) ----------------


def _arc(cx: float, cy: float, r: float, t0: float, t1: float, n: int = 40) -> FloatArray:
    t = np.linspace(t0, t1, n)
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


def _leg(x0: float, x1: float, y: Callable[[FloatArray], FloatArray], n: int) -> FloatArray:
    xs = np.linspace(x0, x1, n)
    return np.column_stack([xs, y(xs)])


def _crossings(p: FloatArray, q: FloatArray) -> list[tuple[float, float]]:
    """Fractional indices (along p, along q) where the xy projections of p and q cross."""
    d1 = (p[1:] - p[:-1])[:, None, :]
    d2 = (q[1:] - q[:-1])[None, :, :]
    r = q[:-1][None, :, :] - p[:-1][:, None, :]

    def cross(u: FloatArray, v: FloatArray) -> FloatArray:
        return np.asarray(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0])

    den = cross(d1, d2)
    ok = np.abs(den) > 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(ok, cross(r, d2) / den, -1.0)
        t = np.where(ok, cross(r, d1) / den, -1.0)
    hit = (s >= 0) & (s < 1) & (t >= 0) & (t < 1)
    return [(i + s[i, j], j + t[i, j]) for i, j in zip(*np.nonzero(hit), strict=True)]


def _heights(n: int, knots: list[tuple[float, float]]) -> FloatArray:
    knots = sorted(knots)
    u = [0.0, *(k for k, _ in knots), n - 1.0]
    return np.interp(np.arange(n), u, [0.0, *(z for _, z in knots), 0.0])


def square_lay() -> FloatArray:
    """Square knot laid flat: two interlocked bights (units).

    Strand 1's legs at y = +-a(x), a from 1 to 2 across x in [-3, 3], its bend a half
    circle about (3, 0); strand 2 the same reflected in x. At the six projected
    crossings the strands are 1 unit apart in z, over/under as (+, -, +, +, -, +) along
    strand 1, which closes (ends joined far away) to the square knot; the stitch loop
    runs below and beside the knot.
    """

    def a(x: FloatArray) -> FloatArray:
        return np.clip(1.5 + x / 6.0, 1.0, 2.0)

    def b(x: FloatArray) -> FloatArray:
        return np.clip(1.5 - x / 6.0, 1.0, 2.0)

    s1 = np.vstack(
        [
            _leg(-20, 3, a, 90),
            _arc(3, 0, 2, math.pi / 2, -math.pi / 2)[1:-1],
            _leg(3, -12, lambda x: -a(x), 60),
        ]
    )
    s2 = np.vstack(
        [
            _leg(12, -3, lambda x: -b(x), 60),
            _arc(-3, 0, 2, -math.pi / 2, -3 * math.pi / 2)[1:-1],
            _leg(-3, 20, b, 90),
        ]
    )
    over = (1, -1, 1, 1, -1, 1)
    cr = _crossings(s1, s2)
    z1 = _heights(len(s1), [(s, o / 2) for (s, _), o in zip(cr, over, strict=True)])
    z2 = _heights(len(s2), [(t, -o / 2) for (_, t), o in zip(cr, over, strict=True)])
    loop = np.array([(-14.0, -6.0, -4.0), (0.0, -8.0, -6.0), (14.0, -6.0, -4.0)])
    return np.vstack([np.column_stack([s1, z1]), loop, np.column_stack([s2, z2])])


def half_hitches_lay(turns: float = 2.0, pitch: float = 2.5) -> FloatArray:
    """Strand 1 a straight post along x, strand 2 wound ``turns`` times round it (units).

    The winding is a helix of radius 1 unit about the post's axis, entered from below
    and left towards the +x end.
    """
    n_post = 120
    post = np.column_stack([np.linspace(-20, 10, n_post), np.zeros(n_post), np.zeros(n_post)])
    loop = np.array([(14.0, -6.0, -4.0), (0.0, -8.0, -6.0), (-14.0, -6.0, -4.0)])
    x0 = -pitch * turns / 2
    t = np.linspace(0.0, 1.0, int(60 * turns) + 1)
    helix = np.column_stack(
        [
            x0 + pitch * turns * t,
            -np.cos(2 * math.pi * turns * t),
            np.sin(2 * math.pi * turns * t),
        ]
    )
    approach = np.array([(-10.0, -6.0, -1.0), (x0 - 2.0, -3.0, 0.0)])
    leave = np.array([(helix[-1, 0] + 3.0, -4.0, 0.0), (20.0, -8.0, 0.0)])
    return np.vstack([post, loop, approach, helix, leave])


# -- physics ---------------------------------------------------------------------------


class LaidResult(NamedTuple):
    """A laid two-strand knot after settling and pulling.

    Attributes:
        name: which lay.
        laid: the thread's centerline as laid [m].
        settled: after ``settle`` seconds held still [m].
        pulled: after the pull [m].
        lay_laid, lay_settled, lay_pulled: ``knot_lay(...)`` of each.
        type_pulled: the classifier's knot type of the pulled centerline.
        pull: the pull's outcome (``PullResult``).
        stretch: the thread's elongation at the end [-].
        cpu_s: process time of the simulation [s].
    """

    name: str
    laid: FloatArray
    settled: FloatArray
    pulled: FloatArray
    lay_laid: Any
    lay_settled: Any
    lay_pulled: Any
    type_pulled: str
    pull: Any
    stretch: float
    cpu_s: float


class OnePull(NamedTuple):
    """Outcome of :func:`pull_one`: whether the target was reached, and the last force."""

    reached: bool
    final_force: float


def pull_one(
    scene: Any,
    tool: Any,
    direction: FloatArray,
    target: float,
    speed: float = 0.02,
    hold: float = 0.3,
    timeout: float = 15.0,
) -> OnePull:
    """Carry one grasper along ``direction`` until its grip force reaches ``target`` [N].

    The other grips hold still. Then hold ``hold`` [s]. A hand-written trajectory.
    """
    from backends.pybullet.suture import PHYSICS_RATE

    dt = 1.0 / PHYSICS_RATE
    x = np.asarray(tool.pose()[0], dtype=float)
    t = 0.0
    reached = False
    while t < timeout:
        force = float(tool.grip_force())
        if force >= target:
            reached = True
            break
        x = x + direction * speed * dt * (0.2 if force > 0.3 * target else 1.0)
        tool.set_pose((float(x[0]), float(x[1]), float(x[2])))
        scene.step()
        t += dt
    for _ in range(round(hold * PHYSICS_RATE)):
        scene.step()
    return OnePull(reached, float(tool.grip_force()))


def lay_and_pull(
    name: str,
    settle: float = 0.5,
    pull: float = 0.5,
    hold: float = 0.3,
    z: float = 0.05,
    both: bool = False,
) -> LaidResult:
    """Lay the named hand-built knot as a thread, settle it, pull (module doc).

    Args:
        name: ``"square"`` or ``"half-hitches"``.
        settle: time held still after laying [s].
        pull: tension to pull to [N] (0: no pull).
        hold: hold time after the pull [s].
        z: height of the lay [m].
        both: pull both ends apart (else only strand 1's end, along -x, the other
            end and the tissue grip held still).
    """
    import pybullet as p

    from backends.pybullet.scene import Scene, pull_ends
    from backends.pybullet.suture import PHYSICS_RATE, Suture, SutureParams, configure_physics
    from backends.pybullet.tools import Grasper
    from suture_engine.suture.knot import knot_lay
    from suture_engine.suture.topology import classify_knot

    units = {"square": square_lay, "half-hitches": half_hitches_lay}[name]()
    path = units * UNIT + np.array([0.0, 0.0, z])
    length = float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))
    n = int(length // SEGMENT)
    prm = SutureParams(length=n * SEGMENT, n_segments=n, needle=False)
    dia = 2.0 * prm.collision_radius
    t0 = time.process_time()
    client = p.connect(p.DIRECT)
    try:
        configure_physics(client)
        suture = Suture.create(client, path, prm)
        laid = suture.centerline()
        left = Grasper.create(client, "left", tuple(laid[0]), suture=suture, hook=False)
        right = Grasper.create(client, "right", tuple(laid[-1]), suture=suture, hook=False)
        # the tissue: a fixed grip on the stitch loop's lowest point
        bottom = tuple(laid[int(np.argmin(laid[:, 2]))])
        tissue = Grasper.create(client, "tissue", bottom, suture=suture, hook=False)
        tools = {"left": left, "right": right, "tissue": tissue}
        scene = Scene(client=client, seed=0, suture=suture, tools=tools)  # type: ignore[arg-type]
        for tool in tools.values():
            tool.close()
        for _ in range(round(settle * PHYSICS_RATE)):
            scene.step()
        settled = suture.centerline()
        result: Any = None
        if pull > 0 and both:
            result = pull_ends(scene, left, right, target=pull, hold=hold, timeout=15.0)
        elif pull > 0:
            result = pull_one(scene, left, np.array([-1.0, 0.0, 0.0]), pull, hold=hold)
        pulled = suture.centerline()
        stretch = float(suture.stretch())
    finally:
        p.disconnect(physicsClientId=client)
    return LaidResult(
        name,
        laid,
        settled,
        pulled,
        knot_lay(laid, diameter=dia),
        knot_lay(settled, diameter=dia),
        knot_lay(pulled, diameter=dia),
        classify_knot(pulled).type,
        result,
        stretch,
        time.process_time() - t0,
    )


class JigResult(NamedTuple):
    """Two throws tied on the jig, classified on the ground truth."""

    mirrored: bool
    type: str
    determinant: int
    v2: int
    v3: int
    reached: bool
    cpu_s: float


def tie_two_throws(mirrored: bool) -> JigResult:
    """Tie two throws on the jig, the second mirrored or not, and classify the result."""
    from backends.pybullet.tying import JigTie, tie_on_jig
    from suture_engine.suture.topology import classify_knot

    t0 = time.process_time()
    res = tie_on_jig((False, mirrored), JigTie(length=0.5, segments=100, first_offset=0.16))
    rep = classify_knot(res.final)
    return JigResult(
        mirrored,
        rep.type,
        rep.determinant,
        rep.v2,
        rep.v3,
        bool(res.pull.reached),
        time.process_time() - t0,
    )


def main(argv: Sequence[str]) -> int:
    """Run both parts and print what the ground truth says; 0."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--skip-jig", action="store_true", help="only the laid knots")
    ap.add_argument("--settle", type=float, default=0.2, help="settling time [s]")
    ap.add_argument("--pull", type=float, default=0.5, help="pull tension [N] (0: none)")
    args = ap.parse_args(list(argv))
    print("Two half hitches vs square lay: hand-built two-strand knots LAID in physics")
    print(
        f"(2 mm between crossing strands, 2.2 mm capsules, loop gripped), settled {args.settle:g} s"
    )
    print(f"pulled to {args.pull:g} N by strand 1's end alone (the rest held) or by both ends;")
    print("knot_lay and the classifier on the ground-truth centerline.")
    head = (
        f"{'laid as':13s} {'pull':>6s} {'settled':>13s} {'pulled':>13s} {'straightness':>12s} "
        f"{'post_straight':>13s} {'type':>8s} {'reached':>7s} {'F end':>6s} {'cpu s':>6s}"
    )
    print(head)
    print("-" * len(head))
    for name in ("square", "half-hitches"):
        for both in (False, True):
            r = lay_and_pull(name, settle=args.settle, pull=args.pull, both=both)
            st = ", ".join(f"{v:.2f}" for v in r.lay_pulled.straightness) or "-"
            force = r.pull.final_force if r.pull is not None else float("nan")
            reached = r.pull.reached if r.pull is not None else False
            print(
                f"{name:13s} {'both' if both else 'one':>6s} {r.lay_settled.lay:>13s} "
                f"{r.lay_pulled.lay:>13s} {st:>12s} {r.lay_pulled.post_straight!s:>13s} "
                f"{r.type_pulled:>8s} {reached!s:>7s} {force:6.2f} {r.cpu_s:6.1f}"
            )
    if args.skip_jig:
        return 0
    print("\nGranny vs square: two throws tied by tool motion on the jig (0.5 m thread)")
    with ProcessPoolExecutor(2) as pool:
        jig = list(pool.map(tie_two_throws, (True, False)))
    for j in jig:
        second = "mirrored" if j.mirrored else "NOT mirrored"
        print(
            f"second throw {second:12s}: {j.type:8s} (det {j.determinant}, v2 {j.v2}, "
            f"v3 {j.v3:+d}), pulled to 2 N: {j.reached}, {j.cpu_s:.0f} s cpu"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
