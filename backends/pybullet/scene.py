"""Assemble the surgical scene in a headless PyBullet world, and scripted tool motions.

:func:`build_scene` takes a plain dict (the scene model's fields; see :data:`DEFAULT_SCENE`)
and a seed and returns a :class:`Scene`: the physics client at 1 kHz (``PHYSICS_RATE``), the
suture, the tissue pad and the tool tips. Robots are not built here yet: the tools are
driven kinematically (scripted tests), and ``Tool.mount`` attaches them to a robot's tool
link once a robot exists. All user-facing quantities are SI at real scale.

:func:`pull_ends` is the scripted (hand-written, not skill-driven) tightening used by the
knot tests: two graspers hold the thread's ends and move apart until both transmit the
target tension, then hold.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
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
from backends.pybullet.tissue import Tissue
from backends.pybullet.tools import Grasper, Stitcher, Tool
from suture_engine.errors import SutureError

__all__ = [
    "DEFAULT_SCENE",
    "PullResult",
    "Scene",
    "SceneError",
    "build_scene",
    "pull_ends",
]

DEFAULT_SCENE: dict[str, Any] = {
    "tools": {"left": "grasper", "right": "grasper"},
    "tissue": {
        "center": [0.0, 0.0, 0.0],
        "entry": [-0.004, 0.0, 0.0],
        "exit": [0.004, 0.0, 0.0],
        "normal": [0.0, 0.0, 1.0],
        "depth": 0.003,
    },
    "suture": {"length": 0.3, "segments": 40, "knot": None, "knot_scale": 0.0025},
}
"""The default scene: two graspers, a tissue pad at the origin, a straight 0.3 m thread."""


class SceneError(SutureError):
    """The scene description is invalid.

    Attributes:
        field: dotted path of the offending field.
        value: the offending value.
        valid: the valid values, if a fixed set.
    """

    code = "invalid-scene"

    def __init__(self, field: str, value: object, valid: list[str] | None = None) -> None:
        hint = f" (valid: {', '.join(valid)})" if valid else ""
        super().__init__(f"scene field {field}={value!r} is invalid{hint}")
        self.field = field
        self.value = value
        self.valid = valid or []


_KNOTS: dict[str, tuple[bool, ...]] = {
    "overhand": (False,),
    "square": (False, True),
    "granny": (False, False),
}


@dataclass
class Scene:
    """A built scene.

    Attributes:
        client: PyBullet physics client id (``p.DIRECT``).
        seed: the seed the scene was built with.
        suture: the thread.
        tissue: the tissue pad, or None.
        tools: tool tips by name.
        time: simulated time since the scene was built [s].
    """

    client: int
    seed: int
    suture: Suture
    tissue: Tissue | None = None
    tools: dict[str, Tool] = field(default_factory=dict)
    time: float = 0.0
    rng: np.random.Generator = field(default_factory=np.random.default_rng)

    def step(self) -> None:
        """Advance the world by one physics step (1 / ``PHYSICS_RATE`` [s])."""
        import pybullet as p

        for tool in self.tools.values():
            tool.step()
        self.suture.pre_step()
        if self.tissue is not None:
            self.tissue.pre_step()
        p.stepSimulation(physicsClientId=self.client)
        self.time += 1.0 / PHYSICS_RATE

    def close(self) -> None:
        """Disconnect the physics client."""
        import pybullet as p

        p.disconnect(physicsClientId=self.client)


def _vec(cfg: dict[str, Any], key: str, where: str) -> tuple[float, float, float]:
    v = cfg.get(key)
    if not (isinstance(v, list | tuple) and len(v) == 3):
        raise SceneError(f"{where}.{key}", v)
    return (float(v[0]), float(v[1]), float(v[2]))


def build_scene(config: dict[str, Any] | None = None, seed: int = 0) -> Scene:
    """Build the scene headless from a plain dict.

    Args:
        config: fields as in :data:`DEFAULT_SCENE` (missing sections take the defaults).
            ``suture.knot`` is None, ``"overhand"``, ``"square"`` or ``"granny"``: a knot laid
            by construction along a hand-built curve (:func:`knotted_path`).
        seed: seeds the scene's random generator (sensor noise, perturbations); the physics
            itself is deterministic.

    Returns:
        The scene; graspers hold nothing yet and sit at the thread's ends.

    Raises:
        SceneError: an unknown tool or knot name, or a malformed vector.
    """
    import pybullet as p

    cfg = copy.deepcopy(DEFAULT_SCENE)
    for key, value in (config or {}).items():
        if key not in cfg:
            raise SceneError(key, value, sorted(cfg))
        # ``tools`` is replaced as a whole; the other sections are merged field by field.
        cfg[key] = dict(value) if key == "tools" else {**cfg[key], **value}
    client = p.connect(p.DIRECT)
    configure_physics(client)

    tissue_cfg = cfg["tissue"]
    tissue = None
    if tissue_cfg:
        tissue = Tissue.create(
            client,
            center=_vec(tissue_cfg, "center", "tissue"),
            entry=_vec(tissue_cfg, "entry", "tissue"),
            exit=_vec(tissue_cfg, "exit", "tissue"),
            normal=_vec(tissue_cfg, "normal", "tissue"),
            depth=float(tissue_cfg.get("depth", 0.003)),
        )

    sut = cfg["suture"]
    length = float(sut["length"])
    params = SutureParams(length=length, n_segments=int(sut["segments"]))
    start = np.array([-length / 2, -0.03, 0.02])
    knot = sut.get("knot")
    if knot is None:
        path = straight_path(tuple(start), (1.0, 0.0, 0.0), length)
    elif knot in _KNOTS:
        path = knotted_path(_KNOTS[knot], (0.0, -0.03, 0.03), float(sut["knot_scale"]), length)
    else:
        raise SceneError("suture.knot", knot, sorted(_KNOTS))
    suture = Suture.create(client, path, params)
    scene = Scene(client=client, seed=seed, suture=suture, tissue=tissue)
    scene.rng = np.random.default_rng(seed)

    ends = suture.centerline()[[0, -1]]
    for (name, kind), end in zip(cfg["tools"].items(), ends, strict=False):
        pos = (float(end[0]), float(end[1]), float(end[2]))
        if kind == "grasper":
            scene.tools[name] = Grasper.create(client, name, pos, suture=suture)
        elif kind == "stitcher":
            scene.tools[name] = Stitcher.create(client, name, pos, needle_body=suture.needle_body)
        else:
            raise SceneError(f"tools.{name}", kind, ["grasper", "stitcher"])
    return scene


class PullResult(NamedTuple):
    """Outcome of :func:`pull_ends`.

    Attributes:
        reached: whether both graspers transmitted the target tension.
        time_to_target: simulated time until then [s] (nan if never).
        final_force: mean grip force at the end of the hold [N].
        min_hold_force: smallest mean grip force during the hold [N].
        max_stretch: largest thread stretch seen during the hold [-].
    """

    reached: bool
    time_to_target: float
    final_force: float
    min_hold_force: float
    max_stretch: float


def pull_ends(
    scene: Scene,
    left: Grasper,
    right: Grasper,
    target: float = 2.0,
    speed: float = 0.02,
    hold: float = 1.0,
    timeout: float = 8.0,
) -> PullResult:
    """Grasp the thread's two ends and pull them apart along x to a tension, then hold.

    A hand-written trajectory: each grasper moves outward at ``speed`` while the thread is
    slack, at a fifth of it once it transmits 0.3 N, and stops when the mean grip force
    reaches ``target``; both then hold still for ``hold`` seconds.

    Args:
        scene: the scene stepping the world.
        left: grasper at the thread's tail (moves to -x).
        right: grasper at the needle end (moves to +x).
        target: tension to reach [N].
        speed: pull speed of each grasper [m/s].
        hold: hold time after reaching the target [s].
        timeout: give up after this simulated time [s].

    Returns:
        What happened (forces from the grasp constraints, stretch from the chain).
    """
    dt = 1.0 / PHYSICS_RATE
    xl = np.array(left.pose()[0])
    xr = np.array(right.pose()[0])
    left.close()
    right.close()
    t = 0.0
    reached_at = float("nan")
    hold_forces: list[float] = []
    stretches: list[float] = []
    while t < timeout:
        force = 0.5 * (left.grip_force() + right.grip_force())
        if np.isnan(reached_at):
            if left.holding and right.holding:
                if force >= target:
                    reached_at = t
                else:
                    v = speed if force < 0.3 else speed / 5
                    xl[0] -= v * dt
                    xr[0] += v * dt
                    left.set_pose((xl[0], xl[1], xl[2]))
                    right.set_pose((xr[0], xr[1], xr[2]))
        else:
            hold_forces.append(force)
            stretches.append(scene.suture.stretch())
            if t - reached_at >= hold:
                break
        scene.step()
        t += dt
    if not hold_forces:
        force = 0.5 * (left.grip_force() + right.grip_force())
        return PullResult(False, reached_at, force, force, scene.suture.stretch())
    # The first steps of the hold still carry the pull's transient; judge the last 90 %.
    tail = hold_forces[len(hold_forces) // 10 :]
    return PullResult(True, reached_at, hold_forces[-1], min(tail), max(stretches))
