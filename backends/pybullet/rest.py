"""The thread's rest test: a knot pulled taut and let go should stay where it is.

A real suture is so light that the pad's friction stops it almost at once: a knot drawn
taut and released keeps its place, give or take the thread's own stretch springing back.
The simulated thread weighs about a thousand times more (mass scaling, see
:mod:`backends.pybullet.suture`), while the weight that presses it on the pad is the real
one, so friction hardly slows it. What the chain's stretch stores under a pull (about
half the pull times the stretch, 0.37 mJ at 1 N) comes back as motion when it is let go;
a knot turns that motion sideways, and the thread coasts on it unless its damping
(``SutureParams.linear_damping``) takes it away.

:func:`released_knot_travel` measures it: a knot laid along a hand-built curve
(:func:`backends.pybullet.suture.knotted_path`) on a flat plate settles, its two end
capsules are drawn apart by point constraints until they carry the pull, held, and let
go; it returns how far any joint of the thread moves afterwards (ground truth), beside
how far a straight thread so pulled springs back (the chain's stretch alone).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from backends.pybullet.suture import (
    PHYSICS_RATE,
    Suture,
    SutureParams,
    configure_physics,
    knotted_path,
    straight_path,
)

__all__ = ["Released", "released_knot_travel"]

_PLATE_FRICTION = 0.5
"""Friction coefficient of the plate the knot rests on [-]."""
_KNOT_SCALE = 2.5e-3
"""Size of one laid throw [m] (:func:`knotted_path`' ``scale``)."""


class Released(NamedTuple):
    """How far a released thread moved (ground truth).

    Attributes:
        travel: the largest displacement of any of the thread's joints over the time
            after release [m].
        type: the knot classifier's type of the thread at the end ("unknot" for the
            straight thread).
        reached: whether the pull reached its target before the time allowed.
    """

    travel: float
    type: str
    reached: bool


def released_knot_travel(
    throws: tuple[bool, ...] | None,
    damping: float,
    pull: float = 1.0,
    hold: float = 0.5,
    after: float = 2.0,
    params: SutureParams | None = None,
) -> Released:
    """Pull a knot on a plate to ``pull`` by its ends, hold, let go; how far does it move?

    Args:
        throws: the knot's throws (:func:`knotted_path`: ``(False,)`` the overhand knot,
            ``(False, True)`` the square knot); None: a straight thread.
        damping: the thread's damping rate [1/s], linear and angular.
        pull: the force the two end capsules are drawn to [N].
        hold: how long the pull is held before release [s].
        after: how long the thread is watched after release [s].
        params: the thread (default: 0.3 m in 40 capsules); its damping and needle are
            replaced (no needle).

    Returns:
        The travel, the knot's type at the end, and whether the pull was reached.
    """
    import dataclasses

    import pybullet as p

    from suture_engine.suture.topology import classify_knot

    prm = dataclasses.replace(
        params or SutureParams(), needle=False, linear_damping=damping, angular_damping=damping
    )
    c = p.connect(p.DIRECT)
    try:
        configure_physics(c)
        box = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.25, 0.25, 0.01], physicsClientId=c)
        plate = p.createMultiBody(0, box, -1, [0, 0, -0.01], physicsClientId=c)
        p.changeDynamics(plate, -1, lateralFriction=_PLATE_FRICTION, physicsClientId=c)
        r = prm.collision_radius
        if throws is None:
            path = straight_path((-prm.length / 2, 0, r), (1, 0, 0), prm.length)
        else:
            path = knotted_path(throws, (0, 0, r + _KNOT_SCALE), _KNOT_SCALE, prm.length)
        sut = Suture.create(c, path, prm)
        _step(sut, c, round(1.5 * PHYSICS_RATE))  # settle on the plate
        grips = _grip_ends(sut, c)
        held, steps = 0, round(10 * PHYSICS_RATE)
        for _ in range(steps):
            states = [p.getConstraintState(g[0], physicsClientId=c) for g in grips]
            force = float(np.mean([np.linalg.norm(s) for s in states]))
            if held or force >= pull:
                held += 1
                if held > hold * PHYSICS_RATE:
                    break
            else:
                speed = 0.02 if force < 0.3 * pull else 0.004  # [m/s], slower once taut
                for cid, at, out in grips:
                    at[0] += out * speed / PHYSICS_RATE
                    p.changeConstraint(cid, at.tolist(), maxForce=50, physicsClientId=c)
            _step(sut, c, 1)
        before = sut.centerline().copy()
        for cid, _, _ in grips:
            p.removeConstraint(cid, physicsClientId=c)
        travel = 0.0
        for _ in range(round(after * 10)):
            _step(sut, c, round(PHYSICS_RATE / 10))
            moved = float(np.linalg.norm(sut.centerline() - before, axis=1).max())
            travel = max(travel, moved)
        return Released(travel, classify_knot(sut.centerline()).type, held > 0)
    finally:
        p.disconnect(physicsClientId=c)


def _step(sut: Suture, client: int, n: int) -> None:
    import pybullet as p

    for _ in range(n):
        sut.pre_step()
        p.stepSimulation(physicsClientId=client)
        sut.stepped()


def _grip_ends(sut: Suture, client: int) -> list[tuple[int, Any, float]]:
    """A point constraint at each end of the thread, pinned where it is: (constraint id,
    its world pivot [m], the pull's sign along x)."""
    import pybullet as p

    half = sut.params.segment_length / 2
    grips = []
    for body, local, out in ((sut.bodies[0], -half, -1.0), (sut.bodies[-1], half, 1.0)):
        pos, orn = p.getBasePositionAndOrientation(body, physicsClientId=client)
        at = np.array(p.multiplyTransforms(pos, orn, [0, 0, local], [0, 0, 0, 1])[0])
        cid = p.createConstraint(
            body, -1, -1, -1, p.JOINT_POINT2POINT, [0, 0, 0], [0, 0, local], at.tolist(),
            physicsClientId=client,
        )  # fmt: skip
        grips.append((cid, at, out))
    return grips
