"""Cut the tied thread, and load the next stitch's: an interrupted suture, one stitch at a time.

In an interrupted suture each stitch has its own suture: it is stitched, tied, and its
ends are cut; then a new suture is loaded for the next stitch. The simulated world does
the same in two operations that a procedure asks for between its knots:

- :func:`cut_thread` takes the scene's thread out of play (its knot stays in the tissue;
  the simulation keeps its last centerline for evaluation and parks its bodies far
  away, static and touching nothing: PyBullet would give a removed body's id, and the
  collision filter pairs set on it, to the next new body), with the tissue pad that
  held it. Whatever the tools held of it is let go; the
  stitcher's jaw holds no needle afterwards.
- :func:`load_thread` adds a new thread and pad for the stitch at the named entry and exit
  points, in the backend's start state: ``"stitched"`` (the stitch made, as the stitched
  start lays it, the needle in the stitcher's holding jaw wherever the stitcher now is; on
  algorithm 3's bench, which has no stitcher, the thread's end in the needle holder's
  jaws) or ``"needle"`` (the thread hangs from the needle in the stitcher's jaw).

What this leaves out, stated: the cut knots are not obstacles for the next stitch (their
short cut tails would be), and the wound edges are not pulled together by them.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from backends.pybullet.scene import (
    PARKED,
    Scene,
    SceneError,
    carrier_jaw,
    hanging_path,
    model_tissue,
    needle_holder,
    stitch_points,
    stitched_path,
    suture_params,
)
from backends.pybullet.suture import Suture
from backends.pybullet.tissue import WOUND_GAP
from backends.pybullet.tools import Grasper, Stitcher

__all__ = ["RELOAD_STARTS", "CutThread", "cut_thread", "load_thread"]

RELOAD_STARTS = ("stitched", "needle")
"""The start states a loaded thread can take (a held tail needs the assistant there)."""


class CutThread(NamedTuple):
    """A thread taken out of the world by :func:`cut_thread` (ground truth).

    Attributes:
        centerline: its centerline when cut, tail to needle, world frame [m] (N x 3).
        time: simulated time of the cut [s].
    """

    centerline: NDArray[np.float64]
    time: float


def cut_thread(scene: Scene) -> CutThread:
    """Cut the scene's thread and take it, and its tissue pad, out of play (parked).

    Raises:
        SceneError: the scene has no thread to cut.
    """
    suture = scene.suture
    if suture is None:
        raise SceneError("suture", None, ["a thread in the world (cut once per load)"])
    cut = CutThread(np.array(suture.centerline(), dtype=float), float(scene.time))
    if scene.tissue is not None:
        scene.tissue.park(PARKED)
        scene.tissue = None
    for tool in scene.tools.values():
        if isinstance(tool, (Grasper, Stitcher)):
            tool.set_thread(None)
    suture.park(PARKED)
    scene.suture = None
    return cut


def load_thread(
    scene: Scene,
    model: Any,
    entry: str,
    exit_: str,
    start: str,
    tail: float,
    bending_stiffness: float = 0.0,
    wound_gap: float = WOUND_GAP,
    wound_depth: float | None = None,
) -> Suture:
    """Load a new thread for the stitch from ``entry`` to ``exit_`` (tissue point names).

    Args:
        scene: the built scene, its thread cut (:func:`cut_thread`).
        model: the scene model it was built from (robots, tissue, suture).
        entry: the new stitch's entry point's name.
        exit_: its exit point's name.
        start: ``"stitched"`` or ``"needle"`` (:data:`RELOAD_STARTS`).
        tail: the stitched thread's tail out of the entry point [m].
        bending_stiffness: the thread's flexural rigidity EI [N*m^2].
        wound_gap: the new pad's wound width, as the thread's contacts meet it [m]
            (:data:`~backends.pybullet.tissue.WOUND_GAP`).
        wound_depth: how deep its wound stays open [m] (None: through the pad).

    Returns:
        The new thread (also ``scene.suture``).

    Raises:
        SceneError: a thread is still in the world, an unknown start or point name, no
            stitcher or needle holder to hold the needle (a holder takes the stitched
            start only), or a thread too short to reach the jaw.
    """
    import pybullet as p

    if scene.suture is not None:
        raise SceneError("suture", "loaded", ["cut the thread first"])
    if start not in RELOAD_STARTS:
        raise SceneError("start", start, list(RELOAD_STARTS))
    stitchers = [t for t in scene.tools.values() if isinstance(t, Stitcher)]
    holder = needle_holder(model.robots) if not stitchers else None
    if not stitchers and holder is None:
        raise SceneError(
            "robots",
            sorted(scene.tools),
            ["a stitcher to hold the needle, or a plain grasper (algorithm 3's needle holder)"],
        )
    if holder is not None and start != "stitched":
        raise SceneError("start", start, ["stitched (a needle holder holds the thread's end)"])
    a, b = stitch_points(model.tissue, (entry, exit_))
    client = scene.client
    normal = np.asarray(model.tissue.normal, float)
    normal = normal / np.linalg.norm(normal)
    tissue = model_tissue(client, model, a, b, wound_gap, wound_depth)
    params = suture_params(model, bending_stiffness)
    if holder is None:
        at, along = stitchers[0].needle_jaw()
        jaw, axis = np.asarray(at, float), np.asarray(along, float)
    else:  # as the stitched start lays it
        jaw, axis = carrier_jaw(scene.robots[holder], stitcher=False)
    lift = params.collision_radius + 0.5e-3
    try:
        if start == "stitched":
            path = stitched_path(
                tissue.channel,
                normal,
                lift,
                tail,
                np.asarray(jaw, float),
                np.asarray(axis, float),
                params.length,
                params.segment_length,
            )
        else:
            path = hanging_path(jaw, a, b, normal, params.length)
        suture = Suture.create(client, path, params)
    except BaseException:
        tissue.park(PARKED)  # nothing half-built stays in the scene
        raise
    if start == "stitched":
        tissue.thread(suture)
    tissue.track(suture)
    for robot in scene.robots.values():
        for link in range(-1, p.getNumJoints(robot.body_id, physicsClientId=client)):
            for body in [*tissue.bodies, suture.needle_body]:
                p.setCollisionFilterPair(robot.body_id, body, link, -1, 0, physicsClientId=client)
    for tool in scene.tools.values():
        for part in (b for b in tool._parts() if b >= 0):
            for body in tissue.bodies:
                p.setCollisionFilterPair(part, body, -1, -1, 0, physicsClientId=client)
    for post in scene.posts.values():
        for body in [*tissue.bodies, *suture.bodies, suture.needle_body]:
            p.setCollisionFilterPair(post, body, -1, -1, 0, physicsClientId=client)
    scene.suture = suture
    scene.tissue = tissue
    for tool in scene.tools.values():
        if isinstance(tool, (Grasper, Stitcher)):
            tool.set_thread(suture)
    if holder is not None:
        held = scene.tools[holder]
        assert isinstance(held, Grasper)
        held.grip(len(suture.bodies) - 1)
    return suture
