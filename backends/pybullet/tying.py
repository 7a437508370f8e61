"""Tie an overhand knot by tool motion on a peg jig (scripted, hand-written trajectories).

The thread starts straight; nothing is laid knotted. Two graspers hold its ends; four fixed
vertical pegs (a jig, static capsules) stand beside it. The moves, all hand-written:

1. **Wrap.** The right grasper carries its end counter-clockwise around the jig on a
   shrinking spiral (about half a turn and one radian more), rising above the thread in the
   last part so that it crosses *over* the standing part. Meanwhile the left grasper pays
   the tail outward by as much as the spiral's radius shrinks beyond what the wrap itself
   uses (``payout`` [m] over the whole spiral), so the thread stays taut and lies around
   the outside of the pegs: an open loop held by the jig.
2. **Thread the needle.** The end drops below the loop's plane outside it, passes *under*
   the standing part into the loop, rises through the loop between the pegs and leaves it
   *over* the far side. In projection the end crosses over, under, over: an overhand knot.
3. **Release and tighten.** The pegs are removed, the end is brought to the +x side and
   both graspers pull apart (:func:`backends.pybullet.scene.pull_ends`) to the target
   tension, then hold.

Measured (``tests/test_tying.py``): the payout window that wraps the pegs cleanly is narrow
(0.09-0.10 m gives a trefoil; 0.07 m leaves the thread slack and it slips between the
pegs; 0.12 m pulls the loop off the jig before the end crosses); this is a scripted
demonstration of tying by motion in this simulator, not a robust tying controller.

Everything read from the thread here (the centerlines handed back) is ground truth for
evaluation; no move depends on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from backends.pybullet.scene import PullResult, Scene
    from backends.pybullet.tools import Grasper

__all__ = ["JigTie", "TieResult", "tie_overhand_on_jig"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class JigTie:
    """Geometry and speeds of the jig tie (all world frame, SI).

    Attributes:
        length: thread length [m]; it starts straight along +x from ``(-length / 2, 0, z)``.
        segments: number of thread capsules.
        z: height of the thread and of the pegs' middle [m].
        center: jig centre (x, y) [m].
        half_side: half the side of the square of pegs [m].
        peg_radius: peg radius [m].
        peg_height: peg length between its rounded ends [m].
        peg_friction: Coulomb friction of the pegs [-].
        turn: angle the end turns around the jig centre [rad].
        end_radius: spiral radius at the end of the wrap [m].
        payout: thread the wrap itself uses, over the whole spiral [m]; the tail is paid
            outward by whatever the spiral's shrinking radius frees beyond it.
        high: height of the end when it passes over the thread [m].
        low: height of the end when it passes under the thread [m].
        speed: speed of the end along its path [m/s].
        target: tension of the final pull [N].
        hold: hold time at the target [s].
    """

    length: float = 0.3
    segments: int = 60
    z: float = 0.02
    center: tuple[float, float] = (-0.10, 0.018)
    half_side: float = 0.010
    peg_radius: float = 1.5e-3
    peg_height: float = 0.016
    peg_friction: float = 0.2
    turn: float = math.pi + 1.0
    end_radius: float = 0.035
    payout: float = 0.095
    high: float = 0.04
    low: float = 0.0
    speed: float = 0.1
    target: float = 2.0
    hold: float = 1.0


class TieResult(NamedTuple):
    """Outcome of :func:`tie_overhand_on_jig` (centerlines are ground truth, tail first).

    Attributes:
        start: the straight thread's centerline before any move [m].
        wrapped: centerline after the wrap [m].
        threaded: centerline after the end passed through the loop, pegs still in place [m].
        final: centerline at the end of the hold [m].
        pull: the tightening's outcome (forces, stretch).
        span: distance between the thread's two ends at the end [m].
    """

    start: FloatArray
    wrapped: FloatArray
    threaded: FloatArray
    final: FloatArray
    pull: PullResult
    span: float


def _add_pegs(client: int, jig: JigTie) -> list[int]:
    """Four static vertical capsules at the corners of the jig's square."""
    import pybullet as p

    col = p.createCollisionShape(
        p.GEOM_CAPSULE, radius=jig.peg_radius, height=jig.peg_height, physicsClientId=client
    )
    vis = p.createVisualShape(
        p.GEOM_CAPSULE,
        radius=jig.peg_radius,
        length=jig.peg_height,
        rgbaColor=[0.9, 0.5, 0.1, 1.0],
        physicsClientId=client,
    )
    pegs = []
    for dx in (-jig.half_side, jig.half_side):
        for dy in (-jig.half_side, jig.half_side):
            at = [jig.center[0] + dx, jig.center[1] + dy, jig.z]
            body = p.createMultiBody(0.0, col, vis, at, physicsClientId=client)
            p.changeDynamics(body, -1, lateralFriction=jig.peg_friction, physicsClientId=client)
            pegs.append(body)
    return pegs


def _move(scene: Scene, tool: Grasper, goal: FloatArray, speed: float) -> None:
    """Carry a tool's tip in a straight line to ``goal`` [m] at ``speed`` [m/s]."""
    start = np.asarray(tool.pose()[0], dtype=float)
    steps = max(int(np.linalg.norm(goal - start) / speed * 1000.0), 1)
    for i in range(1, steps + 1):
        x = start + (goal - start) * i / steps
        tool.set_pose((float(x[0]), float(x[1]), float(x[2])))
        scene.step()


def tie_overhand_on_jig(jig: JigTie | None = None) -> TieResult:
    """Tie an overhand knot in a straight thread by hand-written tool motion (module doc).

    Args:
        jig: geometry and speeds (defaults: :class:`JigTie`).

    Returns:
        The centerlines of each phase, the tightening's outcome and the final end span.
    """
    import pybullet as p

    from backends.pybullet.scene import Scene, pull_ends
    from backends.pybullet.suture import (
        PHYSICS_RATE,
        Suture,
        SutureParams,
        configure_physics,
        straight_path,
    )
    from backends.pybullet.tools import Grasper

    jig = jig or JigTie()
    client = p.connect(p.DIRECT)
    try:
        configure_physics(client)
        suture = Suture.create(
            client,
            straight_path((-jig.length / 2, 0.0, jig.z), (1.0, 0.0, 0.0), jig.length),
            SutureParams(length=jig.length, n_segments=jig.segments, needle=False),
        )
        start = suture.centerline()
        left = Grasper.create(client, "left", tuple(start[0]), suture=suture, hook=False)
        right = Grasper.create(client, "right", tuple(start[-1]), suture=suture, hook=False)
        scene = Scene(client=client, seed=0, suture=suture, tools={"left": left, "right": right})
        pegs = _add_pegs(client, jig)
        left.close()
        right.close()
        for _ in range(200):
            scene.step()

        # 1. Wrap: a shrinking spiral around the jig, the tail paid out to keep the thread taut.
        c = np.array([jig.center[0], jig.center[1]])
        end = start[-1]
        r0 = float(np.linalg.norm(end[:2] - c))
        a0 = math.atan2(end[1] - c[1], end[0] - c[0])
        tail = np.asarray(left.pose()[0], dtype=float)
        here = np.asarray(right.pose()[0], dtype=float)
        n = 200
        for k in range(1, n + 1):
            f = k / n
            a = a0 + jig.turn * f
            r = r0 + (jig.end_radius - r0) * f
            rise = min(max((f - 0.6) / 0.2, 0.0), 1.0)
            goal = np.array(
                [c[0] + r * math.cos(a), c[1] + r * math.sin(a), jig.z + (jig.high - jig.z) * rise]
            )
            out = max(0.0, (r0 - r) - jig.payout * f)
            steps = max(int(np.linalg.norm(goal - here) / jig.speed * PHYSICS_RATE), 1)
            for i in range(1, steps + 1):
                x = here + (goal - here) * i / steps
                right.set_pose((float(x[0]), float(x[1]), float(x[2])))
                left.set_pose((float(tail[0] - out), float(tail[1]), float(tail[2])))
                scene.step()
            here = goal
        wrapped = suture.centerline()

        # 2. Through the loop: down outside, under the standing part, up inside, out over.
        for goal in (
            np.array([here[0], here[1], jig.low]),
            np.array([c[0] - 0.003, c[1] - 0.003, jig.low]),
            np.array([c[0], c[1], jig.high]),
            np.array([c[0], c[1] + jig.end_radius, jig.high]),
        ):
            _move(scene, right, goal, jig.speed)
        threaded = suture.centerline()

        # 3. Release the loop from the jig and tighten.
        for body in pegs:
            p.removeBody(body, physicsClientId=client)
        for _ in range(200):
            scene.step()
        _move(scene, right, np.array([c[0] + 0.05, c[1] + 0.02, jig.z]), jig.speed)
        pull = pull_ends(scene, left, right, target=jig.target, hold=jig.hold, timeout=15.0)
        final = suture.centerline()
        span = float(np.linalg.norm(final[-1] - final[0]))
    finally:
        p.disconnect(physicsClientId=client)
    return TieResult(start, wrapped, threaded, final, pull, span)
