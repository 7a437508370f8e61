"""Laid knots drawn tight, with the thread's contacts rigid or as springs: do they hold?

Run: ``python benchmarks/knot_hold.py [--stiffness 0,10000] [--joints tip,smooth]
[--target 2] [--hold 5]``.
Lays the overhand (60 segments), square and granny knots (80 segments) along hand-built
curves, has two graspers draw the ends apart to ``--target`` newtons and hold for
``--hold`` seconds (:func:`backends.pybullet.scene.pull_ends`), and prints per knot and
contact stiffness (0: PyBullet's rigid contacts;
:meth:`backends.pybullet.suture.Suture.soften_contacts` otherwise, damping 5 N*s/m) and
joint shape (``tip``: the capsules meet tip to tip, a groove at each joint, as every
bundled scene; ``smooth``: they reach over the joints, ``SutureParams.smooth_joints``):

- the classifier's type and determinant of the final centerline (a knot that pulled
  through reads ``unknot``);
- the smallest and the settled grip force over the hold [N] (the knot holds when both
  stay near the target);
- the deepest overlap of two bodies in the thread's last contacts [mm] (a capsule's
  contact radius is 0.9 mm: an overlap near 1.8 mm is a strand passing through another);
- the largest tension at any of the thread's joints at the end [N] (ground truth): inside
  a knot it can exceed the pull, where contacts wedge the capsules.
"""

from __future__ import annotations

import argparse
import time
from typing import NamedTuple

import suture_engine  # noqa: F401 (first: it pins OpenBLAS' kernel before numpy loads)

KNOTS = (("overhand", 60), ("square", 80), ("granny", 80))
JOINTS = ("tip", "smooth")


class Held(NamedTuple):
    """What one knot did under the pull (module doc).

    Attributes:
        knot: the knot laid.
        stiffness: the thread's contact stiffness [N/m]; 0: rigid.
        joints: ``"tip"`` or ``"smooth"`` (module doc).
        type: the classifier's type at the end.
        determinant: its determinant.
        min_hold: the smallest grip force over the hold [N].
        settled: the grip force settled at the hold's end [N].
        deepest: the deepest overlap in the thread's contacts at the end [m].
        peak: the largest tension at a joint of the thread at the end [N].
        cpu: the CPU time of the pull and hold [s].
    """

    knot: str
    stiffness: float
    joints: str
    type: str
    determinant: int
    min_hold: float
    settled: float
    deepest: float
    peak: float
    cpu: float

    def row(self) -> str:
        """The printed row."""
        return (
            f"{self.knot:9s} {self.stiffness:9.0f} {self.joints:6s} {self.type:10s} "
            f"{self.determinant:3d} "
            f"{self.min_hold:8.2f} {self.settled:10.2f} {self.deepest * 1e3:11.3f} "
            f"{self.peak:9.2f} {self.cpu:6.1f}"
        )


def hold(
    knot: str, segments: int, stiffness: float, target: float, seconds: float, joints: str = "tip"
) -> Held:
    """One knot drawn to ``target`` [N] and held ``seconds`` [s]; ``joints`` is ``"tip"`` or
    ``"smooth"`` (module doc)."""
    import numpy as np
    import pybullet as p

    from backends.pybullet.scene import build_scene, pull_ends
    from backends.pybullet.suture import CONTACT_DAMPING
    from suture_engine.suture.topology import classify_knot

    if joints not in JOINTS:
        raise ValueError(f"joints: one of {JOINTS}, got {joints!r}")
    suture_cfg = {
        "knot": knot,
        "segments": segments,
        "knot_scale": 0.0025,
        "smooth_joints": joints == "smooth",
    }
    scene = build_scene({"tissue": {}, "suture": suture_cfg})
    try:
        suture = scene.suture
        assert suture is not None
        if stiffness > 0:
            suture.soften_contacts(stiffness, CONTACT_DAMPING)
        t0 = time.process_time()
        left, right = scene.tools["left"], scene.tools["right"]
        pulled = pull_ends(scene, left, right, target=target, hold=seconds, timeout=8 + seconds)
        report = classify_knot(suture.centerline())
        depths = [
            c[8]
            for b in suture.bodies
            for c in p.getContactPoints(bodyA=b, physicsClientId=scene.client)
        ]
        deepest = -min(depths, default=0.0)
        peak = float(np.max(suture.tensions()))
        cpu = time.process_time() - t0
    finally:
        scene.close()
    return Held(
        knot, stiffness, joints, report.type, report.determinant, pulled.min_hold_force,
        pulled.settled_force, deepest, peak, cpu,
    )  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    """Parse the options; print one row per knot and stiffness."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stiffness", default="0,10000", help="contact stiffnesses [N/m], 0: rigid")
    ap.add_argument("--joints", default="tip", help="joint shapes: tip, smooth or both")
    ap.add_argument("--target", type=float, default=2.0, help="the pull [N]")
    ap.add_argument("--hold", type=float, default=5.0, help="the hold after it [s]")
    args = ap.parse_args(argv)
    try:
        stiffnesses = [float(s) for s in args.stiffness.split(",")]
    except ValueError:
        ap.error(f"--stiffness: numbers separated by commas, got {args.stiffness!r}")
    if any(s < 0 for s in stiffnesses):
        ap.error(f"--stiffness: each >= 0 [N/m], got {args.stiffness!r}")
    shapes = [j.strip() for j in args.joints.split(",")]
    if not shapes or any(j not in JOINTS for j in shapes):
        ap.error(f"--joints: from {','.join(JOINTS)} separated by commas, got {args.joints!r}")
    print(f"pull {args.target:g} N, hold {args.hold:g} s")
    print(
        "knot      k [N/m] joints type       det min_hold settled[N] deepest[mm] peak T[N] cpu[s]"
    )
    for knot, segments in KNOTS:
        for joints in shapes:
            for k in stiffnesses:
                held = hold(knot, segments, k, args.target, args.hold, joints)
                print(held.row(), flush=True)


if __name__ == "__main__":
    main()
