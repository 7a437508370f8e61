"""Assemble the surgical scene in a headless PyBullet world, and scripted tool motions.

:func:`build_scene` takes either the scene model of the procedure language
(:class:`suture_engine.language.scene.Scene`) or a plain dict (see :data:`DEFAULT_SCENE`)
and a seed, and returns a :class:`Scene`: the physics client at 1 kHz (``PHYSICS_RATE``),
the suture, the tissue pad and the tool tips. All user-facing quantities are SI at real
scale.

* From the **model**: each EndoBot (``EndoBotSim``) stands at its calibrated base pose
  (Fig. 4.31) with its tool mounted on its tool link (``grasper``, ``hook-grasper``,
  ``bent-tip-grasper``, ``stitcher``); the tissue's stitch runs from the point named
  ``entry`` (or the first ``entry_*``) to ``exit`` (or the first ``exit_*``), or across the
  wound's middle if none is named. With a stitcher the needle starts locked in its jaw and
  the thread hangs from it; otherwise the thread starts stitched through the tissue, its
  tails lying on the surface. Until a controller drives them, :meth:`Scene.step` holds the
  robots at their start joints (gravity compensation (3.41) plus a PD term).
* From a **dict**: no robots; graspers at the thread's ends, driven kinematically (scripted
  tests), and a thread laid straight or along a hand-built knotted curve.

:func:`pull_ends` is the scripted (hand-written, not skill-driven) tightening used by the
knot tests: two graspers hold the thread's ends and move apart until both transmit the
target tension, then hold.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from backends.pybullet.suture import (
    PHYSICS_RATE,
    Suture,
    SutureParams,
    _resample,
    configure_physics,
    knotted_path,
    straight_path,
)
from backends.pybullet.tissue import WOUND_GAP, Tissue
from backends.pybullet.tools import Grasper, Stitcher, Tool
from suture_engine.errors import SutureError

__all__ = [
    "DEFAULT_SCENE",
    "DEFAULT_TAIL",
    "PAD_SIZE",
    "PARKED",
    "START_STATES",
    "PullResult",
    "Scene",
    "SceneError",
    "build_scene",
    "carrier_jaw",
    "channel_depth",
    "hanging_path",
    "model_tissue",
    "needle_holder",
    "needle_path",
    "pull_ends",
    "remove_posts",
    "stitch_points",
    "stitched_path",
    "suture_params",
    "tail_assistant",
    "tail_held_grip",
    "tail_held_joints",
]

PARKED = (50.0, 50.0, -50.0)
"""Where bodies taken out of play are parked, far from the scene [m]: cut threads and their
pads (:meth:`Suture.park`), calibration posts (:func:`remove_posts`). Static, they touch
nothing there, each other included: one place serves."""

DEFAULT_SCENE: dict[str, Any] = {
    "tools": {"left": "grasper", "right": "grasper"},
    "tissue": {
        "center": [0.0, 0.0, 0.0],
        "entry": [-0.004, 0.0, 0.0],
        "exit": [0.004, 0.0, 0.0],
        "normal": [0.0, 0.0, 1.0],
        "depth": 0.003,
    },
    "suture": {
        "length": 0.3,
        "segments": 40,
        "knot": None,
        "knot_scale": 0.0025,
        "smooth_joints": False,
    },
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


_KP = np.array([40.0, 40.0, 2.0, 400.0])
"""Holding stiffness per joint [N*m/rad, N*m/rad, N*m/rad, N/m]."""
_KD = np.array([2.0, 2.0, 0.05, 20.0])
"""Holding damping per joint [N*m*s/rad, N*m*s/rad, N*m*s/rad, N*s/m]."""
_Q0 = (0.0, 0.0, 0.0, 0.08)

STITCHED_PULL = 0.04
"""In the stitched start, how far the stitch's pull (4.3) left the stitcher's tip from the
exit point along the tissue normal, l_d [m]: the stitcher starts there, holding the needle,
with the thread running from the exit to its jaw."""
"""Start joints of the robots [rad, rad, rad, m]."""

START_STATES = ("needle", "tail-held", "stitched")
"""Start states of a scene with a stitcher: the thread hangs from the needle in the
stitcher's jaw, or the stitch is already made (:func:`stitched_path`)."""
DEFAULT_TAIL = 0.03
"""Tail out of the entry point in the stitched start state [m]."""
PAD_SIZE = (0.24, 0.24, 0.01)
"""Tissue pad of a scene model: length across the wound, width along it, thickness [m].
Wide enough that the thread's slack (the stitched start lays ~160 mm of it on the
surface, out to ~90 mm from the wound) stays on the pad instead of sinking past its edge
and snagging under it; the instruments pass through the pad."""

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
        suture: the thread; None once cut and until the next is loaded
            (:mod:`backends.pybullet.reload`).
        tissue: the tissue pad, or None.
        tools: tool tips by name.
        time: simulated time since the scene was built [s].
        posts: the scene's calibration posts: name -> body id.
    """

    client: int
    seed: int
    suture: Suture | None
    tissue: Tissue | None = None
    tools: dict[str, Tool] = field(default_factory=dict)
    time: float = 0.0
    rng: np.random.Generator = field(default_factory=np.random.default_rng)
    robots: dict[str, Any] = field(default_factory=dict)
    hold: dict[str, tuple[float, float, float, float]] = field(default_factory=dict)
    torques: dict[str, Any] = field(default_factory=dict)
    posts: dict[str, int] = field(default_factory=dict)

    def step(self) -> None:
        """Advance the world by one physics step (1 / ``PHYSICS_RATE`` [s]).

        Each robot gets the joint torques in :attr:`torques` [N*m, N*m, N*m, N] if given,
        else it is held at :attr:`hold` (its start joints) by gravity compensation plus PD.
        """
        import pybullet as p

        for name, robot in self.robots.items():
            tau = self.torques.get(name)
            robot.apply(tau if tau is not None else self._hold_torque(name, robot))
        for tool in self.tools.values():
            tool.step()
        if self.suture is not None:
            self.suture.pre_step()
        if self.tissue is not None:
            self.tissue.pre_step()
        p.stepSimulation(physicsClientId=self.client)
        if self.suture is not None:
            self.suture.stepped()
        self.time += 1.0 / PHYSICS_RATE

    def _hold_torque(self, name: str, robot: Any) -> Any:
        from suture_engine.robot.endobot import gravity_vector

        state = robot.true_state()
        q = np.asarray(state.q, dtype=float)
        qd = np.asarray(state.qd, dtype=float)
        target = np.asarray(self.hold[name], dtype=float)
        return gravity_vector(q, robot.model_params) + _KP * (target - q) - _KD * qd

    def close(self) -> None:
        """Disconnect the physics client."""
        import pybullet as p

        p.disconnect(physicsClientId=self.client)


def _vec(cfg: dict[str, Any], key: str, where: str) -> tuple[float, float, float]:
    v = cfg.get(key)
    if not (isinstance(v, list | tuple) and len(v) == 3):
        raise SceneError(f"{where}.{key}", v)
    return (float(v[0]), float(v[1]), float(v[2]))


def build_scene(
    config: Any = None,
    seed: int = 0,
    start: str | None = None,
    tail: float = DEFAULT_TAIL,
    stitch: tuple[str, str] | None = None,
    base_error: Mapping[str, Any] | None = None,
    bending_stiffness: float = 0.0,
    wound_gap: float = WOUND_GAP,
    wound_depth: float | None = None,
) -> Scene:
    """Build the scene headless from the scene model or a plain dict.

    Args:
        config: a :class:`suture_engine.language.scene.Scene` model, or a dict with the
            fields of :data:`DEFAULT_SCENE` (missing sections take the defaults).
            ``suture.knot`` is None, ``"overhand"``, ``"square"`` or ``"granny"``: a knot laid
            by construction along a hand-built curve (:func:`knotted_path`).
        seed: seeds the scene's random generator (sensor noise, perturbations); the physics
            itself is deterministic.
        start: with a scene model and a stitcher: ``"needle"`` (the thread hangs from
            the needle in the stitcher's jaw), ``"tail-held"`` (the needle in the
            stitcher's jaw, the thread on the surface from a free end ``tail`` out of the
            entry point, held there by the first grasper: :func:`needle_path`),
            ``"stitched"`` (the stitch is already made: see :func:`stitched_path`), or
            None for the model's ``suture.start`` (default ``"needle"``).
        tail: the tail out of the entry point [m]: left by the stitch (``"stitched"``),
            or where the thread's free end is held (``"tail-held"``).
        stitch: names of the bite's entry and exit points; None for :func:`stitch_points`'
            choice.
        base_error: with a scene model: robot name -> displacement [m] of the robot's
            actual base from its declared position (a calibration error).
        bending_stiffness: the thread's flexural rigidity EI [N*m^2]
            (:class:`~backends.pybullet.suture.SutureParams`).
        wound_gap: with a scene model: the wound's width between the pad's halves, as
            the thread's contacts meet it [m] (:data:`WOUND_GAP`).
        wound_depth: with a scene model: how deep the wound stays open under the surface
            [m], a floor below (None: through the pad; see :data:`WOUND_GAP`).

    Returns:
        The scene; graspers hold nothing yet and sit at the thread's ends. A scene
        model's graspers let the thread slide through their jaws above the model's grip
        force (``Scene.grip_force``); a plain dict's hold it at any force.

    Raises:
        SceneError: an unknown tool or knot name, or a malformed vector.
    """
    import pybullet as p

    if config is not None and hasattr(config, "robots"):
        return _from_model(
            config, seed, start, tail, stitch, base_error, bending_stiffness, wound_gap,
            wound_depth,
        )  # fmt: skip
    cfg = copy.deepcopy(DEFAULT_SCENE)
    for key, value in (config or {}).items():
        if key not in cfg:
            raise SceneError(key, value, sorted(cfg))
        # ``tools`` is replaced as a whole; the other sections are merged field by field.
        cfg[key] = dict(value) if key == "tools" else {**cfg[key], **value}
    client = p.connect(p.DIRECT)
    try:
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
        params = SutureParams(
            length=length,
            n_segments=int(sut["segments"]),
            smooth_joints=bool(sut["smooth_joints"]),
        )
        origin = (-length / 2, -0.03, 0.02)
        knot = sut.get("knot")
        if knot is None:
            path = straight_path(origin, (1.0, 0.0, 0.0), length)
        elif knot in _KNOTS:
            path = knotted_path(_KNOTS[knot], (0.0, -0.03, 0.03), float(sut["knot_scale"]), length)
        else:
            raise SceneError("suture.knot", knot, sorted(_KNOTS))
        suture = Suture.create(client, path, params)
        scene = Scene(client=client, seed=seed, suture=suture, tissue=tissue)
        scene.rng = np.random.default_rng(seed)

        ends = suture.centerline()[[0, -1]]
        if len(cfg["tools"]) > 2:
            raise SceneError("tools", sorted(cfg["tools"]), ["at most two tools, one per end"])
        for (name, kind), end in zip(cfg["tools"].items(), ends, strict=False):
            pos = (float(end[0]), float(end[1]), float(end[2]))
            if kind == "grasper":
                scene.tools[name] = Grasper.create(client, name, pos, suture=suture)
            elif kind == "stitcher":
                # The stitcher holds the needle: it stands at the needle's end of the thread.
                tip = suture.centerline()[-1]
                scene.tools[name] = Stitcher.create(
                    client,
                    name,
                    (float(tip[0]), float(tip[1]), float(tip[2])),
                    needle_body=suture.needle_body,
                )
            else:
                raise SceneError(f"tools.{name}", kind, ["grasper", "stitcher"])
        return scene
    except SutureError:
        p.disconnect(physicsClientId=client)
        raise


def _grip_force(model: Any, robot: str) -> float:
    """The grip force of ``robot``'s grasper [N] from the scene model (inf if the model
    gives none)."""
    get = getattr(model, "grip_force", None)
    return float(get(robot)) if callable(get) else math.inf


def _quaternion(rpy: Any) -> tuple[float, float, float, float]:
    """(x, y, z, w) of roll-pitch-yaw about fixed x, y, z [rad]."""
    import pybullet as p

    q = p.getQuaternionFromEuler([float(a) for a in rpy])
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def stitch_points(tissue: Any, names: tuple[str, str] | None = None) -> tuple[Any, Any]:
    """Entry and exit points of the stitch [m].

    Args:
        tissue: the scene model's tissue.
        names: the entry and exit points' names; None for the points named ``entry`` and
            ``exit``, else the numbered pair (``entry_k``, ``exit_k``) whose middle is
            nearest the wound's middle, else 4 mm either side of the wound's middle.

    Raises:
        SceneError: a named point is not in the tissue's points.
    """
    points = dict(tissue.points)
    if names is not None:
        for field_name, key in zip(("entry", "exit"), names, strict=True):
            if key not in points:
                raise SceneError(f"tissue.points.{field_name}", key, sorted(points))
        return np.asarray(points[names[0]], float), np.asarray(points[names[1]], float)
    a, b = np.asarray(tissue.wound.start, float), np.asarray(tissue.wound.end, float)
    mid = (a + b) / 2
    if "entry" in points and "exit" in points:
        return np.asarray(points["entry"], float), np.asarray(points["exit"], float)
    pairs = [
        (np.asarray(points[k], float), np.asarray(points["exit_" + k[6:]], float))
        for k in sorted(points)
        if k.startswith("entry_") and "exit_" + k[6:] in points
    ]
    if pairs:
        return min(pairs, key=lambda pq: float(np.linalg.norm((pq[0] + pq[1]) / 2 - mid)))
    n = np.asarray(tissue.normal, float)
    across = np.cross(n, b - a)
    across = across / np.linalg.norm(across) * 4e-3
    return mid - across, mid + across


def channel_depth(bite: float) -> float:
    """Depth of the stitch channel at mid-span [m] for a bite ``bite`` [m] long.

    A sixteenth of the bite, at most 3 mm: the scene's thread is made of 7.5 mm capsules
    that cannot follow a channel curved more tightly than that (with an 8 mm bite 3 mm
    deep, the guidance dragged the tail 8 mm into the tissue while settling).
    """
    return min(3e-3, bite / 16)


def _polyline_length(points: Any) -> float:
    return float(np.linalg.norm(np.diff(np.asarray(points, float), axis=0), axis=1).sum())


NEEDLE_TAIL_BEND = 0.01
"""In the tail-held start, how far out of the entry point the thread leaves the tail's line
for the needle [m] (see :func:`needle_path`)."""


def needle_path(
    entry: Any,
    exit_: Any,
    normal: Any,
    lift: float,
    tail: float,
    jaw: Any,
    leg: Any,
    length: float,
    segment: float,
) -> Any:
    """The polyline of a thread hanging from the needle before the stitch [m] (free end
    first), its free end held by the assistant grasper ``tail`` [m] out of the entry
    point (away from the exit), where the stitch will leave its tail.

    From the free end the thread lies on the surface (``lift`` [m] above it) towards the
    entry point, leaves that line ``NEEDLE_TAIL_BEND`` or more out of it and runs on the
    surface to below the needle, then up to it (a thread too short for that rises
    straight from the line to the needle): its last ``leg`` [m] runs straight into
    the jaw at ``jaw`` (the direction the needle is laid in). The bend is placed so that
    the route is as long as the thread. Laid capsule tip to capsule tip from the needle's
    end, so that the needle sits in its jaw.

    A thread too long for the surface route (the bend at ``NEEDLE_TAIL_BEND``) has its
    bend moved sideways on the surface, away from below the needle; one too short to lie
    to below the needle runs on the surface part of the way from the bend, then up.

    The bite and the pull (4.3) draw the thread into the entry point; the held end keeps
    the tail on its line, straight out of the entry point, where the knot procedures
    take it (the robots do not measure the thread).

    Raises:
        SceneError: the thread is too short for this route.
    """
    n = np.asarray(normal, float)
    entry = np.asarray(entry, float)
    out = _tail_out(entry, exit_, n)
    jaw = np.asarray(jaw, float)
    bend = jaw + np.asarray(leg, float)
    below = bend - n * float(n @ (bend - entry)) + n * lift
    end = entry + n * lift + out * tail

    def route(a: float, on_surface: bool) -> Any:
        """The route with the bend ``a`` [m] out of the entry point, on the surface to
        below the needle, or straight up from the bend to the needle."""
        corner = [entry + n * lift + out * a] if a < tail - 1e-6 else []
        return np.vstack([end, *corner, *([below] if on_surface else []), bend, jaw])

    def partway(t: float) -> Any:
        """From the bend at ``NEEDLE_TAIL_BEND`` on the surface the fraction ``t`` of the
        way to below the needle, then up to it (between the two routes above)."""
        corner = entry + n * lift + out * NEEDLE_TAIL_BEND
        return np.vstack([end, corner, corner + t * (below - corner), bend, jaw])

    def detour(w: float) -> Any:
        """The surface route with its bend moved ``w`` [m] sideways, away from below the
        needle (a thread longer than the surface route)."""
        corner = entry + n * lift + out * NEEDLE_TAIL_BEND
        side = np.cross(n, out)
        if float(side @ (below - corner)) > 0.0:
            side = -side
        return np.vstack([end, corner + side * w, below, bend, jaw])

    def solve(family: Any, lo: float, hi: float) -> Any:
        """The member of ``family`` as long as the thread (its route grows longer with
        its parameter, from ``lo`` to ``hi``)."""
        for _ in range(60):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if _polyline_length(family(mid)) < length else (lo, mid)
        return family(hi)

    bend_at, held_at = NEEDLE_TAIL_BEND, tail
    air = (lambda u: route(bend_at + held_at - u, False), bend_at, held_at)
    surface = (lambda u: route(bend_at + held_at - u, True), bend_at, held_at)

    def spans(family: Any) -> bool:
        """The thread is between the lengths of the family's two ends."""
        f, lo, hi = family
        return bool(_polyline_length(f(lo)) <= length <= _polyline_length(f(hi)))

    if length < _polyline_length(air[0](air[1])):
        shortest = _polyline_length(air[0](air[1]))
        raise SceneError("suture.length", length, [f">= {shortest:.3g} m"])
    # On the surface to below the needle where the thread allows, else straight up from
    # the bend, else part of the way and up; the sideways bend only for what is left. Air,
    # part-way and sideways follow one another, from the shortest route to the longest.
    candidates = [surface, air, (partway, 0.0, 1.0), (detour, 0.0, length)]
    family = next((f for f in candidates if spans(f)), candidates[-1])
    path = solve(*family)[::-1]
    return _resample(path, round(length / segment), segment)[::-1]


def tail_held_grip(
    model: Any, stitch: tuple[str, str] | None = None, tail: float = DEFAULT_TAIL
) -> Any:
    """Where the first grasper's jaws hold the thread's free end in the tail-held start
    [m]: on the end capsule, 1 mm above its axis, with the free end ``tail`` [m] out of
    the entry point of a scene model's stitch, away from the exit. From the model alone: a
    backend without a thread starts the grasper here, about where one with it does
    (:func:`needle_path`'s chain, laid from the needle, cuts the route's corners, so its
    free end lies up to a few mm further out)."""
    entry, exit_ = stitch_points(model.tissue, stitch)
    n = np.asarray(model.tissue.normal, float)
    n = n / np.linalg.norm(n)
    params = suture_params(model, 0.0)
    lift = params.collision_radius + 0.5e-3
    return (
        entry + n * (lift + 1e-3) + _tail_out(entry, exit_, n) * (tail - params.segment_length / 2)
    )


def tail_held_joints(
    model: Any, stitch: tuple[str, str] | None = None, tail: float = DEFAULT_TAIL
) -> dict[str, tuple[float, float, float, float]]:
    """The tail-held start's assistant (:func:`tail_assistant`) and the joints that put
    its jaws at :func:`tail_held_grip`; empty without an assistant or when the point is
    outside its joint limits."""
    assistant = tail_assistant(model.robots)
    if assistant is None:
        return {}
    q = _pulled_out_joints(model.robots[assistant], tail_held_grip(model, stitch, tail))
    return {} if q is None else {assistant: q}


def tail_assistant(robots: Mapping[str, Any]) -> str | None:
    """The robot that holds the thread's free end in the tail-held start: the first (by
    name) whose tool is a grasper of any kind; None when there is none."""
    return next((n for n, spec in sorted(robots.items()) if "grasper" in spec.tool), None)


def needle_holder(robots: Mapping[str, Any]) -> str | None:
    """The robot whose plain grasper holds the thread's needle end in the stitched start
    when no robot has a stitcher (algorithm 3's needle holder): the first by name whose
    tool is ``grasper``; None when there is none."""
    return next((n for n, spec in sorted(robots.items()) if spec.tool == "grasper"), None)


def carrier_jaw(robot: Any, stitcher: bool) -> tuple[Any, Any]:
    """Where the stitched start puts the thread's needle end on the robot that carries it,
    and the direction the thread leaves it [m, unit], world frame, from the robot's true
    tool pose: a stitcher's holding jaw (half the jaw gap along the tip's -x, 3 mm along
    its z), or a needle holder's tool tip; the thread leaves along the tip's x, clear of
    the shaft."""
    import pybullet as p

    tip, orn = robot.true_tool_pose()
    offset = [-Stitcher.gap / 2, 0.0, 3e-3] if stitcher else [0.0, 0.0, 0.0]
    tip_l = [float(v) for v in tip]
    orn_l = [float(v) for v in orn]
    jaw, _ = p.multiplyTransforms(tip_l, orn_l, offset, [0.0, 0.0, 0.0, 1.0])
    axis = np.array(p.getMatrixFromQuaternion(orn_l)).reshape(3, 3)[:, 0]
    return np.asarray(jaw, float), axis


def _tail_out(entry: Any, exit_: Any, normal: Any) -> Any:
    """Unit direction on the surface (``normal`` a unit vector) from the exit point to the
    entry point: the way the tail leaves the entry point."""
    out = np.asarray(entry, float) - np.asarray(exit_, float)
    out = out - normal * float(normal @ out)
    return out / np.linalg.norm(out)


def suture_params(model: Any, bending_stiffness: float) -> SutureParams:
    """The simulated thread of a scene model (at least 40 capsules), damped at the scene's
    ``suture.damping`` and keeping the weight of its ``suture.weight`` when it declares
    them."""
    damping, weight = model.suture.damping, model.suture.weight
    rate = SutureParams.linear_damping if damping is None else float(damping)
    kept = SutureParams.real_mass_per_length if weight is None else float(weight)
    return SutureParams(
        length=float(model.suture.length),
        n_segments=max(40, round(model.suture.length / (model.suture.segment or 7.5e-3))),
        diameter=float(model.suture.diameter),
        bending_stiffness=bending_stiffness,
        smooth_joints=model.suture.smooth_joints,
        linear_damping=rate,
        angular_damping=rate,
        real_mass_per_length=kept,
    )


def stitched_path(
    channel: Any,
    normal: Any,
    lift: float,
    tail: float,
    jaw: Any,
    jaw_axis: Any,
    length: float,
    segment: float,
) -> Any:
    """The polyline of a thread whose stitch is made [m] (tail end first).

    The tail lies on the surface (``lift`` [m] above it) for ``tail`` [m] out of the
    entry point, away from the exit; the thread follows the stitch ``channel`` (entry to
    exit) and then runs to the needle's swaged end at ``jaw`` [m], its last ``segment``
    [m] along ``jaw_axis``. What is left over lies in a slack loop
    ``lift`` above the surface: first straight on past the exit, then back under the jaw,
    then up to it. The thread is almost weightless (the mass-scaled weight is cancelled),
    so it stays where it is laid.

    Args:
        channel: M×3 stitch channel from the entry to the exit point [m].
        normal: outward unit surface normal.
        lift: height of the thread's axis above the surface [m].
        tail: tail length out of the entry point [m].
        jaw: the needle's swaged end [m] (in the stitcher's jaw).
        jaw_axis: unit direction of the thread's last segment, into the jaw.
        length: thread length [m].
        segment: one capsule's length [m].

    Raises:
        SceneError: the thread is too short to reach the jaw with this tail.
    """
    channel = np.asarray(channel, float)
    n = np.asarray(normal, float)
    up = n * lift
    entry, exit_ = channel[0], channel[-1]
    along = exit_ - entry
    along = along - n * float(n @ along)
    along = along / np.linalg.norm(along)
    # The thread dips to the channel over the last capsule length before the entry and
    # rises from it over the first after the exit (those capsules pass through the pad).
    stitched = np.vstack(
        [
            entry + up - along * tail,
            entry + up - along * segment,
            channel,
            exit_ + up + along * segment,
        ]
    )
    rest = length - _polyline_length(stitched) - 2 * segment
    start = stitched[-1]
    # The last two capsule lengths run straight into the jaw, so that the capsules laid
    # tip to tip end on that straight leg whatever the slack (see ``short``).
    axis = np.asarray(jaw_axis, float)
    leg = 2 * segment
    j1 = np.asarray(jaw, float) - axis * leg
    below = j1 - n * float(n @ (j1 - start))
    if rest < float(np.linalg.norm(j1 - start)) - 1e-9:
        raise SceneError("tail", tail, [f"<= {length - _polyline_length(stitched):.3g} m"])

    side = np.cross(n, along)
    side = side * float(side @ (below - start))

    def route(k: float) -> Any:
        """Detours of increasing length: k in [0, 1] bends towards ``below``, k > 1 goes
        k - 1 [m] on past the exit first, then across, then back to ``below``. No acute
        corners: the capsules laid tip to tip along it then move continuously with k."""
        if k <= 1.0:
            return np.vstack([start, (1 - k) * (start + j1) / 2 + k * below, j1])
        far = start + along * (k - 1.0)
        return np.vstack([start, far, far + side, below, j1])

    count = round(length / segment)
    end = np.asarray(jaw, float)

    def short(k: float) -> bool:
        """Whether the capsules laid tip to tip along the route pass the jaw (they cut
        the route's corners, so the route must be longer than the thread)."""
        full = np.vstack([stitched, route(k)[1:], end])
        last = _resample(full, count, segment)[-1] - end
        on_leg = float(np.linalg.norm(np.cross(last, axis))) < 1e-9 and float(last @ axis) > -leg
        return on_leg and float(last @ axis) >= 0.0

    lo, hi = 0.0, 1.0
    if short(1.0):
        lo, hi = 1.0, 1.0 + rest
    for _ in range(40):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if short(mid) else (lo, mid)
    return np.vstack([stitched, route(hi)[1:], end])


def model_tissue(
    client: int,
    model: Any,
    entry: Any,
    exit_: Any,
    wound_gap: float = WOUND_GAP,
    wound_depth: float | None = None,
) -> Tissue:
    """The scene model's tissue pad with its stitch channel from ``entry`` to ``exit_``
    [m], centred on the wound, in the world of ``client``; its halves ``wound_gap`` [m]
    apart, the wound open ``wound_depth`` [m] deep (None: through; :data:`WOUND_GAP`)."""
    normal = np.asarray(model.tissue.normal, float)
    normal = normal / np.linalg.norm(normal)
    a, b = np.asarray(entry, float), np.asarray(exit_, float)
    return Tissue.create(
        client,
        center=tuple((np.asarray(model.tissue.wound.start) + model.tissue.wound.end) / 2),
        entry=tuple(a),
        exit=tuple(b),
        normal=tuple(normal),
        depth=channel_depth(float(np.linalg.norm(b - a))),
        size=PAD_SIZE,
        wound_gap=wound_gap,
        wound_depth=wound_depth,
    )


def hanging_path(tip: Any, entry: Any, exit_: Any, normal: Any, length: float) -> Any:
    """A thread hanging from the needle at ``tip`` [m] (the needle start): ``length`` [m]
    laid straight out from it, away from the stitch (entry to exit, across ``normal``)."""
    end = np.asarray(tip, float)
    back = np.cross(np.asarray(normal, float), np.asarray(exit_, float) - np.asarray(entry, float))
    back = back / np.linalg.norm(back)
    return np.vstack([end + back * length, end])


def _from_model(
    model: Any,
    seed: int,
    start: str | None = None,
    tail: float = DEFAULT_TAIL,
    stitch: tuple[str, str] | None = None,
    base_error: Mapping[str, Any] | None = None,
    bending_stiffness: float = 0.0,
    wound_gap: float = WOUND_GAP,
    wound_depth: float | None = None,
) -> Scene:
    """Build the scene from the language's scene model (robots, tissue, suture)."""
    import pybullet as p

    if start is None:
        start = getattr(model.suture, "start", None) or "needle"
    if start not in START_STATES:
        raise SceneError("suture.start", start, list(START_STATES))
    entry, exit_ = stitch_points(model.tissue, stitch)
    errors = {name: np.zeros(3) for name in model.robots}
    for name, vector in (base_error or {}).items():
        if name not in errors:
            raise SceneError("base_error", name, sorted(errors))
        v = np.asarray(vector, dtype=float)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise SceneError(f"base_error.{name}", vector)
        errors[name] = v
    client = p.connect(p.DIRECT)
    try:
        return _build_model(
            client, model, seed, start, tail, entry, exit_, errors, bending_stiffness,
            wound_gap, wound_depth,
        )  # fmt: skip
    except BaseException:
        p.disconnect(physicsClientId=client)
        raise


def _pulled_out_joints(spec: Any, point: Any) -> tuple[float, float, float, float] | None:
    """The joints that put a robot's tool tip at ``point`` [m] (roll 0), or None when the
    point is outside its joint limits (the robot then starts at :data:`_Q0`)."""
    import pybullet as p

    from suture_engine.robot.kinematics import inverse_kinematics

    rot = np.array(p.getMatrixFromQuaternion(_quaternion(spec.base.rpy))).reshape(3, 3)
    local = rot.T @ (np.asarray(point, float) - np.asarray(spec.base.position, float))
    q = inverse_kinematics(local, 0.0)
    limits = getattr(spec, "joint_limits", None)
    if limits is not None:
        for value, name in zip(q, ("yaw", "pitch", "roll", "insertion"), strict=True):
            bound = getattr(limits, name, None)
            if bound is not None and not bound[0] <= float(value) <= bound[1]:
                return None
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def _build_model(
    client: int,
    model: Any,
    seed: int,
    start: str,
    tail: float,
    entry: Any,
    exit_: Any,
    base_error: Mapping[str, Any],
    bending_stiffness: float,
    wound_gap: float,
    wound_depth: float | None,
) -> Scene:
    import pybullet as p

    from backends.pybullet.robot import EndoBotSim
    from backends.pybullet.tools import BentTipGrasper

    configure_physics(client)
    robots: dict[str, Any] = {}
    hold: dict[str, tuple[float, float, float, float]] = {}
    for i, (name, spec) in enumerate(sorted(model.robots.items())):
        robots[name] = EndoBotSim(
            client,
            base_position=tuple(np.asarray(spec.base.position, float) + base_error[name]),
            base_orientation=_quaternion(spec.base.rpy),
            q0=_Q0,
            seed=seed * 1000 + i,
        )
        hold[name] = _Q0
    configure_physics(client)  # the robot sets its own time step; keep the suture's settings

    normal = np.asarray(model.tissue.normal, float)
    normal = normal / np.linalg.norm(normal)
    tissue = model_tissue(client, model, entry, exit_, wound_gap, wound_depth)
    params = suture_params(model, bending_stiffness)
    stitchers = [n for n, spec in sorted(model.robots.items()) if spec.tool == "stitcher"]
    # Without a stitcher, the stitched start puts the needle's end of the thread in the
    # jaws of the first plain grasper (the needle holder, algorithm 3).
    holder = needle_holder(model.robots) if not stitchers and start == "stitched" else None
    lift = normal * (params.collision_radius + 0.5e-3)
    holds_tail = None
    threaded = not stitchers or start == "stitched"
    carrier = stitchers[0] if stitchers else holder
    if carrier is not None and start != "needle":
        if start == "stitched":
            # where the stitch's pull (4.3) ends: the tip l_d along the normal from the exit
            q_start = _pulled_out_joints(model.robots[carrier], exit_ + normal * STITCHED_PULL)
        else:
            q_start = None
        if q_start is not None:
            robots[carrier].reset(q_start)
            hold[carrier] = q_start
        jaw, axis = carrier_jaw(robots[carrier], stitcher=bool(stitchers))
        if start == "stitched":
            path = stitched_path(
                tissue.channel,
                normal,
                float(np.linalg.norm(lift)),
                tail,
                np.asarray(jaw, float),
                axis,
                params.length,
                params.segment_length,
            )
        else:
            path = needle_path(
                entry,
                exit_,
                normal,
                float(np.linalg.norm(lift)),
                tail,
                np.asarray(jaw, float),
                -axis * 2 * params.segment_length,
                params.length,
                params.segment_length,
            )
            # The assistant grasper holds the free end (its jaws on the end capsule).
            assistant = tail_assistant(model.robots)
            if assistant is not None:
                # on the end capsule as laid (the chain cuts the route's corners, so its
                # end lies up to a few mm from tail_held_grip's nominal point)
                grip = (path[0] + path[1]) / 2 + normal * 1e-3
                q_held = _pulled_out_joints(model.robots[assistant], grip)
                if q_held is not None:
                    robots[assistant].reset(q_held)
                    hold[assistant] = q_held
                    holds_tail = assistant
    elif stitchers:
        tip, _ = robots[stitchers[0]].true_tool_pose()
        path = hanging_path(tip, entry, exit_, normal, params.length)
    else:
        along = (exit_ - entry) / np.linalg.norm(exit_ - entry)
        half = (params.length - 0.02) / 2
        path = np.vstack(
            [
                entry + lift - along * half,
                entry + lift - along * 1e-3,
                tissue.channel,
                exit_ + lift + along * 1e-3,
                exit_ + lift + along * half,
            ]
        )
    suture = Suture.create(client, path, params)
    if threaded:
        tissue.thread(suture)
    # The needle punctures the tissue (Tissue.track); the robots' instruments pass
    # through the pad too (its surface is where the stitch is made, not an obstacle).
    tissue.track(suture)
    # The needle does not push the instruments either (it sweeps between the stitcher's
    # jaws, under the shaft's end).
    for robot in robots.values():
        for link in range(-1, p.getNumJoints(robot.body_id, physicsClientId=client)):
            for body in [*tissue.bodies, suture.needle_body]:
                p.setCollisionFilterPair(robot.body_id, body, link, -1, 0, physicsClientId=client)
    scene = Scene(client=client, seed=seed, suture=suture, tissue=tissue, robots=robots, hold=hold)
    scene.rng = np.random.default_rng(seed)
    # the jaws let the thread slide through above the scene's grip force (under its limit)
    grip = {name: _grip_force(model, name) for name in model.robots}
    for name, spec in sorted(model.robots.items()):
        robot = robots[name]
        tip, orn = robot.true_tool_pose()
        pos = (float(tip[0]), float(tip[1]), float(tip[2]))
        quat = (float(orn[0]), float(orn[1]), float(orn[2]), float(orn[3]))
        tool: Tool
        if spec.tool == "stitcher":
            tool = Stitcher.create(
                client,
                name,
                pos,
                quat,
                needle_body=suture.needle_body,
                place_needle=start == "needle",
            )
        elif spec.tool == "bent-tip-grasper":
            tool = BentTipGrasper.create(
                client, name, pos, quat, suture=suture, hook=False, grip_limit=grip[name]
            )
        else:
            hook = spec.tool == "hook-grasper"
            # the hook grasper's jaws are solid (a loop rests on them, algorithm 2)
            tool = Grasper.create(
                client,
                name,
                pos,
                quat,
                suture=suture,
                hook=hook,
                solid=hook,
                grip_limit=grip[name],
            )
            if name == holder:
                tool.grip(len(suture.bodies) - 1)
            if name == holds_tail:
                tool.grip(0)
        tool.mount(robot.body_id, robot.tool_link)
        if isinstance(tool, Stitcher):
            tool.collide_with(suture)
        # The tool's parts pass through the pad and never touch their own instrument.
        links = range(-1, p.getNumJoints(robot.body_id, physicsClientId=client))
        for part in (b for b in tool._parts() if b >= 0):
            for body in tissue.bodies:
                p.setCollisionFilterPair(part, body, -1, -1, 0, physicsClientId=client)
            for link in links:
                p.setCollisionFilterPair(part, robot.body_id, -1, link, 0, physicsClientId=client)
        scene.tools[name] = tool
    scene.posts = _make_posts(client, model, [*tissue.bodies, *suture.bodies, suture.needle_body])
    return scene


def _make_posts(client: int, model: Any, ignore: Sequence[int]) -> dict[str, int]:
    """The scene's calibration posts: fixed capsules along z (``Scene.posts``), which
    the robots and their tools touch and the thread, needle and tissue pass through."""
    import pybullet as p

    out: dict[str, int] = {}
    for name, post in sorted((getattr(model, "posts", None) or {}).items()):
        col = p.createCollisionShape(
            p.GEOM_CAPSULE, radius=post.radius, height=post.height, physicsClientId=client
        )
        vis = p.createVisualShape(
            p.GEOM_CAPSULE,
            radius=post.radius,
            length=post.height,
            rgbaColor=[0.3, 0.5, 0.8, 1.0],
            physicsClientId=client,
        )
        centre = np.asarray(post.position, float) + np.array([0.0, 0.0, post.height / 2])
        body = p.createMultiBody(0.0, col, vis, centre.tolist(), physicsClientId=client)
        for other in ignore:
            p.setCollisionFilterPair(body, other, -1, -1, 0, physicsClientId=client)
        out[name] = body
    return out


def remove_posts(scene: Scene) -> list[str]:
    """Take the scene's calibration posts out of play: the assistant lifts the calibration
    jig off the bench once the robots are registered (``remove-posts``).

    The posts' bodies stay in the world, parked at :data:`PARKED`, static and touching
    nothing (as a cut thread's, :func:`backends.pybullet.reload.cut_thread`, for the same
    reason: a removed body's id would go to the next new body). ``scene.posts`` is
    emptied, so a thread loaded later is not filtered against them.

    Returns:
        The names of the posts taken away, sorted.

    Raises:
        SceneError: the scene has no posts in play (none declared, or already removed).
    """
    import pybullet as p

    if not scene.posts:
        raise SceneError("posts", None, ["calibration posts in play (removed once)"])
    names = sorted(scene.posts)
    for body in scene.posts.values():
        p.resetBasePositionAndOrientation(
            body, PARKED, (0.0, 0.0, 0.0, 1.0), physicsClientId=scene.client
        )
    scene.posts = {}
    return names


class PullResult(NamedTuple):
    """Outcome of :func:`pull_ends`.

    Attributes:
        reached: whether both graspers transmitted the target tension.
        time_to_target: simulated time until then [s] (nan if never).
        final_force: mean grip force at the end of the hold [N].
        min_hold_force: smallest mean grip force during the hold [N] (after its first
            10 %, the pull's transient).
        settled_force: smallest mean grip force over the hold's last half [N].
        max_stretch: largest thread stretch seen during the hold [-].
    """

    reached: bool
    time_to_target: float
    final_force: float
    min_hold_force: float
    settled_force: float
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
    suture = scene.suture
    if suture is None:
        raise SceneError("suture", None, ["a thread to pull"])
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
            stretches.append(suture.stretch())
            if t - reached_at >= hold:
                break
        scene.step()
        t += dt
    if not hold_forces:
        force = 0.5 * (left.grip_force() + right.grip_force())
        return PullResult(False, reached_at, force, force, force, suture.stretch())
    # The first steps of the hold still carry the pull's transient; judge the last 90 %.
    tail = hold_forces[len(hold_forces) // 10 :]
    settled = hold_forces[len(hold_forces) // 2 :]
    return PullResult(True, reached_at, hold_forces[-1], min(tail), min(settled), max(stretches))
