"""Tie knots by tool motion on a peg jig (scripted, hand-written trajectories).

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

Swapping the over and under heights (``JigTie.mirror``, the moves reflected through the
thread's plane) ties the mirror-image knot: right-handed trefoil (v3 = +1) by default,
left-handed (v3 = -1) mirrored.

Measured (0.3 m thread, 60 segments, 40 mm pegs): payouts of 0.09, 0.095, 0.10 and
0.105 m tie a trefoil, 0.085 m does not (unknot). With the first, 16 mm pegs, 0.07 and
0.12 m gave unknots (at 0.12 m the rendered frames show the loop formed beside the jig,
not around it) and the mirrored tie failed (the end's rise lifted the loop off the pegs).
After the 2 N pull the grips hold still and the knot settles: the grip force over the last
half second is 1.7-2.5 N (``benchmarks/tie_jig.py``; the mirrored knot's rose). This is a
scripted demonstration of tying by motion in this simulator, tuned by hand, not a robust
tying controller.

**Two throws** (:func:`tie_on_jig`): after the first throw is snugged, the left-hand end
ties the second on a new jig with the same moves reflected in x. On a 0.5 m thread (100
segments) opposite throws classify as the square knot (determinant 9, v2 = 2, v3 = 0)
and like throws as the granny (v3 = +2), both pulled to 2 N and held. The two throws end up about
0.3 m apart along the thread: the knot type is that of a square (granny) knot, trefoil #
mirror trefoil (trefoil # trefoil), but the throws are not stacked on each other as in a
surgeon's tie.

Everything read from the thread here (the centerlines handed back) is ground truth for
evaluation; no move depends on it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from backends.pybullet.scene import PullResult, Scene
    from backends.pybullet.tools import Grasper

__all__ = ["JigTie", "TieResult", "tie_on_jig", "tie_overhand_on_jig"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class JigTie:
    """Geometry and speeds of the jig tie (all world frame, SI).

    Attributes:
        length: thread length [m]; it starts straight along +x from ``(-length / 2, 0, z)``.
        segments: number of thread capsules.
        z: height of the thread and of the pegs' middle [m].
        first_offset: x of the first jig's centre from the left grasper [m].
        y: y of the jig's centre [m] (the thread lies along y = 0).
        half_side: half the side of the square of pegs [m].
        peg_radius: peg radius [m].
        peg_height: peg length between its rounded ends [m].
        peg_friction: Coulomb friction of the pegs [-].
        turn: angle the end turns around the jig centre [rad].
        end_radius: spiral radius at the end of the wrap [m].
        payout: thread the wrap itself uses, over the whole spiral [m]; the tail is paid
            outward by whatever the spiral's shrinking radius frees beyond it.
        high: height of the end when it passes over the thread [m] (above the pegs).
        low: height of the end when it passes under the thread [m] (below the pegs).
        mirror: swap ``high`` and ``low`` (the motion reflected through the thread's
            plane), which ties the mirror-image overhand knot.
        speed: speed of the end along its path [m/s].
        target: tension of the final pull [N].
        hold: hold time at the target [s].
        between: tension the knot is snugged to between throws [N].
        next_offset: x of a later jig's centre from the left grasper [m].
    """

    length: float = 0.3
    segments: int = 60
    z: float = 0.02
    first_offset: float = 0.05
    y: float = 0.018
    half_side: float = 0.010
    peg_radius: float = 1.5e-3
    peg_height: float = 0.04
    peg_friction: float = 0.2
    turn: float = math.pi + 1.0
    end_radius: float = 0.035
    payout: float = 0.095
    high: float = 0.05
    low: float = -0.01
    mirror: bool = False
    speed: float = 0.1
    target: float = 2.0
    hold: float = 1.0
    between: float = 0.5
    next_offset: float = 0.22


class TieResult(NamedTuple):
    """Outcome of :func:`tie_on_jig` (centerlines are ground truth, tail first).

    Attributes:
        start: the straight thread's centerline before any move [m].
        wrapped: centerline after each throw's wrap [m].
        threaded: centerline after the end passed through each throw's loop, pegs still in
            place [m].
        final: centerline at the end of the hold [m].
        pull: the tightening's outcome (forces, stretch).
        span: distance between the thread's two ends at the end [m].
    """

    start: FloatArray
    wrapped: tuple[FloatArray, ...]
    threaded: tuple[FloatArray, ...]
    final: FloatArray
    pull: PullResult
    span: float


def _add_pegs(client: int, jig: JigTie, center: FloatArray) -> list[int]:
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
            at = [float(center[0] + dx), float(center[1] + dy), jig.z]
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


def _throw(
    scene: Scene,
    worker: Grasper,
    holder: Grasper,
    side: float,
    jig: JigTie,
    x: float,
    mirror: bool,
    on_phase: Callable[[str, int], None] | None,
) -> tuple[FloatArray, FloatArray]:
    """One throw on a jig centred at (``x``, ``jig.y``): wrap, pass through, release.

    ``worker`` ties with its end, ``holder`` pays the other end out; ``side`` is +1 when
    the worker holds the +x end (the moves as described in the module doc) and -1 when it
    holds the -x end (the same moves reflected through the plane x = ``x``).

    Returns:
        The centerlines after the wrap and after the pass through the loop [m].
    """
    import pybullet as p

    from backends.pybullet.suture import PHYSICS_RATE

    high, low = (jig.low, jig.high) if mirror else (jig.high, jig.low)
    c = np.array([x, jig.y])
    pegs = _add_pegs(scene.client, jig, c)
    for _ in range(100):
        scene.step()

    # 1. Wrap: a shrinking spiral around the jig, the tail paid out to keep the thread taut.
    here = np.asarray(worker.pose()[0], dtype=float)
    tail = np.asarray(holder.pose()[0], dtype=float)
    r0 = float(np.linalg.norm(here[:2] - c))
    a0 = math.atan2(here[1] - c[1], side * (here[0] - c[0]))
    n = 200
    for k in range(1, n + 1):
        f = k / n
        a = a0 + jig.turn * f
        r = r0 + (jig.end_radius - r0) * f
        rise = min(max((f - 0.6) / 0.2, 0.0), 1.0)
        goal = np.array(
            [c[0] + side * r * math.cos(a), c[1] + r * math.sin(a), jig.z + (high - jig.z) * rise]
        )
        out = max(0.0, (r0 - r) - jig.payout * f)
        steps = max(int(np.linalg.norm(goal - here) / jig.speed * PHYSICS_RATE), 1)
        for i in range(1, steps + 1):
            pos = here + (goal - here) * i / steps
            worker.set_pose((float(pos[0]), float(pos[1]), float(pos[2])))
            holder.set_pose((float(tail[0] - side * out), float(tail[1]), float(tail[2])))
            scene.step()
        here = goal
    assert scene.suture is not None  # the jig's scene is never cut
    wrapped = scene.suture.centerline()
    if on_phase is not None:
        on_phase("wrapped", scene.client)

    # 2. Through the loop: down outside, under the standing part, up inside, out over.
    for goal in (
        np.array([here[0], here[1], low]),
        np.array([c[0] - side * 0.003, c[1] - 0.003, low]),
        np.array([c[0], c[1], high]),
        np.array([c[0], c[1] + jig.end_radius, high]),
    ):
        _move(scene, worker, goal, jig.speed)
    threaded = scene.suture.centerline()
    if on_phase is not None:
        on_phase("threaded", scene.client)

    # 3. Release the loop from the jig; bring the end to its own side for pulling.
    for body in pegs:
        p.removeBody(body, physicsClientId=scene.client)
    for _ in range(200):
        scene.step()
    _move(scene, worker, np.array([c[0] + side * 0.05, c[1] + 0.02, jig.z]), jig.speed)
    return wrapped, threaded


def tie_on_jig(
    throws: tuple[bool, ...] = (False,),
    jig: JigTie | None = None,
    on_phase: Callable[[str, int], None] | None = None,
) -> TieResult:
    """Tie throws in a straight thread by hand-written tool motion (module doc).

    Each throw is an overhand knot tied on the jig, by the right-hand end for even throws
    and by the left-hand end (the moves reflected in x, over and under swapped, so that it
    has the same handedness) for odd ones; ``throws[i]`` is True for a mirrored throw.
    Between throws the knot so far is snugged to ``jig.between`` [N], both ends are brought
    back onto the thread's line and the next jig is placed ``jig.next_offset`` [m] from the
    left grasper (a fixed, measured offset, not read from the thread).

    Args:
        throws: mirror flag per throw: ``(False,)`` overhand knot, ``(False, True)`` two
            opposite throws (square), ``(False, False)`` two like throws (granny).
        jig: geometry and speeds (defaults: :class:`JigTie`).
        on_phase: called with the phase's name (``"wrapped"``, ``"threaded"``, ``"final"``)
            and the physics client id after each phase, e.g. to render a frame.

    Returns:
        The centerlines of each phase, the tightening's outcome and the final end span.
    """
    import pybullet as p

    from backends.pybullet.scene import Scene, pull_ends
    from backends.pybullet.suture import Suture, SutureParams, configure_physics, straight_path
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
        left.close()
        right.close()
        for _ in range(200):
            scene.step()
        wrapped: list[FloatArray] = []
        threaded: list[FloatArray] = []
        for k, mirror in enumerate(throws):
            if k == 0:
                x = float(left.pose()[0][0]) + jig.first_offset
            else:
                pull_ends(scene, left, right, target=jig.between, hold=0.2, timeout=15.0)
                for tool in (left, right):
                    end = np.asarray(tool.pose()[0], dtype=float)
                    _move(scene, tool, np.array([end[0], 0.0, jig.z]), jig.speed)
                x = float(left.pose()[0][0]) + jig.next_offset
            # Throws alternate ends: the right end ties the first, the left end the second.
            # Reflecting the moves in x mirrors the throw, so the left end's heights swap.
            if k % 2 == 0:
                w, t = _throw(scene, right, left, 1.0, jig, x, mirror, on_phase)
            else:
                w, t = _throw(scene, left, right, -1.0, jig, x, not mirror, on_phase)
            wrapped.append(w)
            threaded.append(t)
        pull = pull_ends(scene, left, right, target=jig.target, hold=jig.hold, timeout=15.0)
        final = suture.centerline()
        span = float(np.linalg.norm(final[-1] - final[0]))
        if on_phase is not None:
            on_phase("final", client)
    finally:
        p.disconnect(physicsClientId=client)
    return TieResult(start, tuple(wrapped), tuple(threaded), final, pull, span)


def tie_overhand_on_jig(
    jig: JigTie | None = None, on_phase: Callable[[str, int], None] | None = None
) -> TieResult:
    """Tie one overhand knot: ``tie_on_jig((jig.mirror,), jig, on_phase)``."""
    jig = jig or JigTie()
    return tie_on_jig((jig.mirror,), jig, on_phase)
