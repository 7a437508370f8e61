"""The suture: a chain of capsule bodies joined point to point, with a needle at one end.

The thread is modelled at true scale (metres, newtons, seconds; no scene scaling) as
``n_segments`` separate capsule rigid bodies. Neighbouring capsules are joined tip to tip by
``JOINT_POINT2POINT`` constraints, so the chain bends and twists freely and resists only
stretch. Non-adjacent capsules collide with each other (self-collision, needed for a knot to
hold) and with everything else; adjacent pairs are excluded from collision.

Two departures from the real thread keep the simulation stable and fast, and are explicit
parameters of :class:`SutureParams`:

* **mass scaling**: each capsule weighs ``segment_mass`` (1 g by default) instead of the few
  micrograms of real silk, and its rotational inertia is inflated by ``inertia_scale``. A
  real 2-0 thread is so light that a 0.5 N pull gives accelerations the solver cannot
  resolve. The thread's weight is cancelled by an upward force applied in
  :meth:`Suture.pre_step` (call it before every ``stepSimulation``), so the chain sags as
  the (almost weightless) real thread does.
* **contact radius**: the capsules' collision radius is ``collision_radius`` (0.9 mm by
  default, six times the radius of USP 2-0), so crossing strands do not creep through each
  other under sustained load. Measured with the scripted 2 N tightening of a laid square
  knot (80 segments): at 0.7 mm one throw slipped through after about 1 s of holding;
  at 0.9 mm the square knot held 5 s and the granny knot 6 s (settling to 1.82 N).
  Knots are therefore bulkier than real ones; knot-holding at 2 N is a property of this
  tuning, not a margin.

The physics rate is the runtime's control rate, 1 kHz; at 240 Hz a true-scale chain is
unstable. With 40 segments, 50 solver iterations and a constraint ERP of 0.8 (set by
:func:`configure_physics`) the stretch is about 0.2 % under a 0.5 N pull and 1-2.5 % under
2 N (``benchmarks/scene_rtf.py``, ``tests/test_suture_physics.py``).

Everything here that reads the simulator's state of the thread (centerline, tension,
contacts, knot position) is ground truth for traces and evaluation only; skills never see
it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.arithmetic import cos, row_dot, sin
from suture_engine.errors import SutureError

__all__ = [
    "CONTACT_DAMPING",
    "PHYSICS_RATE",
    "CapsuleFrame",
    "InvalidSutureParams",
    "Suture",
    "SutureContact",
    "SutureGroundTruth",
    "SutureParams",
    "capsule_axis",
    "configure_physics",
    "knotted_path",
    "straight_path",
]

PHYSICS_RATE = 1000.0
"""Physics rate the scene is built for [Hz] (the runtime's control rate)."""
CONTACT_DAMPING = 5.0
"""Damping of the thread's contacts made springs [N*s/m] (:meth:`Suture.soften_contacts`)
when none is given; the language's ``suture.contact_damping`` defaults to the same."""

_GRAVITY = 9.81
_NEEDLE_SIM_MASS = 2e-3
"""Simulated needle mass [kg] (mass-scaled like the thread)."""
_NEEDLE_REAL_MASS = 5e-5
"""Weight the needle keeps after the lift [kg] (a small curved suture needle)."""

FloatArray = NDArray[np.float64]
Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


def capsule_axis(orientation: Quat) -> Vec3:
    """A capsule's unit axis, tail to needle [-]: its orientation's third matrix column."""
    import pybullet as p

    return p.getMatrixFromQuaternion(orientation)[2::3]  # type: ignore[no-any-return]


class CapsuleFrame(NamedTuple):
    """The thread's capsule poses as the simulator gives them, read once per step.

    Each capsule's unit axis (:func:`capsule_axis`) is computed on first use and kept:
    most steps read the axes of the few capsules near the tissue only.

    Attributes:
        positions: each capsule's centre, world frame [m].
        orientations: each capsule's quaternion (x, y, z, w).
        axis_cache: the axes computed so far (None: not yet).
    """

    positions: list[Vec3]
    orientations: list[Quat]
    axis_cache: list[Vec3 | None]

    def axis(self, i: int) -> Vec3:
        """Capsule ``i``'s unit axis, tail to needle [-]."""
        axis = self.axis_cache[i]
        if axis is None:
            axis = self.axis_cache[i] = capsule_axis(self.orientations[i])
        return axis

    def axes(self) -> list[Vec3]:
        """Every capsule's unit axis, tail to needle [-]."""
        return [self.axis(i) for i in range(len(self.positions))]


class InvalidSutureParams(SutureError):
    """A suture parameter is out of its valid range.

    Attributes:
        name: the parameter's name.
        value: the offending value.
        bound: a text description of the valid range.
    """

    code = "invalid-suture-params"

    def __init__(self, name: str, value: object, bound: str) -> None:
        super().__init__(f"suture parameter {name}={value!r} is invalid: must be {bound}")
        self.name = name
        self.value = value
        self.bound = bound


@dataclass(frozen=True)
class SutureParams:
    """Physical and numerical parameters of the simulated suture.

    Attributes:
        length: thread length [m].
        n_segments: number of capsule bodies (at least 40 for knotting).
        diameter: real thread diameter [m] (USP 2-0: 0.3 mm, Table 7.1); recorded, not
            simulated.
        collision_radius: capsule contact radius [m], larger than ``diameter / 2``.
        segment_mass: simulated mass of one capsule [kg] (mass-scaled, see module doc).
        real_mass_per_length: the mass per length whose weight the thread keeps [kg/m]
            (the real thread's by default; a scene's ``suture.weight``); the weight
            beyond it is cancelled in :meth:`Suture.pre_step`.
        inertia_scale: factor on each capsule's rotational inertia [-].
        friction: Coulomb friction coefficient of thread on thread and on tools [-].
        linear_damping: each capsule's (and the needle's) damping rate [1/s]: PyBullet
            slows a body with no links by its mass times this rate times
            ``(1 + |v|)`` times its velocity ``v`` [m/s], so slow motion dies away as
            ``exp(-rate * t)``. The default 0.5 /s lets a released knot coast (the
            scene's ``suture.damping``).
        angular_damping: the same for spin [1/s], on the rotational inertia.
        max_link_force: largest force a joint between capsules may apply [N].
        needle: whether to attach a needle body to the last capsule.
        needle_radius: radius of the curved (half-circle) needle [m].
        bending_stiffness: the thread's flexural rigidity EI [N*m^2]; each joint between
            capsules then resists bending with a torque EI / segment_length times the
            sine of its bend angle (applied in :meth:`Suture.pre_step`). 0 (the default)
            is the limp thread the knot tests are tuned with.
        smooth_joints: centre each capsule's end spheres on its two joints (its collision
            cylinder spans the whole segment), so the chain's surface is a round tube
            through every joint. False (the default, the procedures' tuning): the
            capsules meet tip to tip and each joint is a groove ``collision_radius``
            deep; a crossing capsule pressed into it pushes the two caps apart along the
            thread, against the joint, and the joint's force then reads far above any
            pull (:meth:`collision_height`).
    """

    length: float = 0.3
    n_segments: int = 40
    diameter: float = 0.3e-3
    collision_radius: float = 0.9e-3
    segment_mass: float = 1e-3
    real_mass_per_length: float = 1e-4
    inertia_scale: float = 10.0
    friction: float = 0.8
    linear_damping: float = 0.5
    angular_damping: float = 0.5
    max_link_force: float = 1000.0
    needle: bool = True
    needle_radius: float = 6e-3
    bending_stiffness: float = 0.0
    smooth_joints: bool = False

    def __post_init__(self) -> None:
        if self.n_segments < 3:
            raise InvalidSutureParams("n_segments", self.n_segments, ">= 3")
        if not self.length > 0:
            raise InvalidSutureParams("length", self.length, "> 0 [m]")
        if not 0 < self.collision_radius < self.segment_length / 2:
            raise InvalidSutureParams(
                "collision_radius",
                self.collision_radius,
                f"in (0, {self.segment_length / 2:g}) [m] (half a segment)",
            )
        for name in ("segment_mass", "inertia_scale", "max_link_force", "needle_radius"):
            if not getattr(self, name) > 0:
                raise InvalidSutureParams(name, getattr(self, name), "> 0")
        if self.friction < 0:
            raise InvalidSutureParams("friction", self.friction, ">= 0")
        if not self.bending_stiffness >= 0:
            raise InvalidSutureParams("bending_stiffness", self.bending_stiffness, ">= 0")

    @property
    def segment_length(self) -> float:
        """Rest length of one capsule, joint to joint [m]."""
        return self.length / self.n_segments

    def collision_height(self) -> float:
        """The capsule's cylinder between its end spheres' centres [m]: the segment's
        length with ``smooth_joints`` (the spheres centred on the joints, each capsule
        reaching ``collision_radius`` past them into its neighbours, with which it does
        not collide), else the segment less the two caps (tip to tip)."""
        seg = self.segment_length
        return seg if self.smooth_joints else seg - 2 * self.collision_radius


class SutureContact(NamedTuple):
    """One contact point of the thread (ground truth).

    Attributes:
        segment: index of the thread capsule in contact.
        other_body: PyBullet body id of the other body.
        other_segment: capsule index if the other body is the thread itself, else -1.
        position: contact point on the thread, world frame [m].
        normal_force: normal contact force [N].
    """

    segment: int
    other_body: int
    other_segment: int
    position: tuple[float, float, float]
    normal_force: float


class SutureGroundTruth(NamedTuple):
    """A snapshot of the thread's true state, for traces and evaluation only (never skills).

    Attributes:
        centerline: (n_segments + 1)×3 joint points, tail to needle [m].
        tensions: (n_segments - 1) tension at each joint [N].
        stretch: relative elongation [-].
        knot_position: centroid of the thread-on-thread contacts [m], or None.
        contacts: every contact of the thread in the last step.
    """

    centerline: FloatArray
    tensions: FloatArray
    stretch: float
    knot_position: tuple[float, float, float] | None
    contacts: tuple[SutureContact, ...]


def configure_physics(client: int, rate: float = PHYSICS_RATE) -> None:
    """Set the engine parameters the suture is tuned for.

    Args:
        client: PyBullet physics client id.
        rate: physics rate [Hz].
    """
    import pybullet as p

    p.setGravity(0, 0, -_GRAVITY, physicsClientId=client)
    p.setPhysicsEngineParameter(
        fixedTimeStep=1.0 / rate,
        numSolverIterations=50,
        erp=0.8,
        contactERP=0.4,
        frictionERP=0.2,
        physicsClientId=client,
    )


def straight_path(
    start: tuple[float, float, float], direction: tuple[float, float, float], length: float
) -> FloatArray:
    """A straight polyline from ``start`` along ``direction`` [m] (2×3 array)."""
    s = np.asarray(start, dtype=float)
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    return np.stack([s, s + length * d])


def _open_trefoil(mirror: bool, samples: int) -> FloatArray:
    """A trefoil cut open at its outer lobe tip, traversed from the -x side to the +x side.

    Unit scale: the lobe tip is at (0, -3, 0); the cut ends leave it along -(1, 0, ±1) and
    +(1, 0, ±1). ``mirror`` flips z, which mirrors the knot (left and right trefoils).
    """
    delta = 0.35
    t = np.linspace(3 * math.pi - delta, math.pi + delta, samples)
    x = sin(t) + 2 * sin(2 * t)
    y = cos(t) - 2 * cos(2 * t)
    z = -sin(3 * t)
    pts = np.stack([x, y, z], axis=1)
    if mirror:
        pts[:, 2] *= -1
    return pts


def knotted_path(
    throws: tuple[bool, ...],
    center: tuple[float, float, float],
    scale: float,
    length: float,
    samples: int = 200,
) -> FloatArray:
    """A hand-built, loosely knotted open curve for laying a pre-knotted thread [m].

    Each throw is an overhand knot (an open trefoil); several throws are joined in sequence
    along +x, which forms their connected sum. ``throws[i]`` is True for a mirrored throw.
    One throw is the overhand knot (trefoil); ``(False, True)`` is a square (reef) knot
    (trefoil # mirror trefoil); ``(False, False)`` is a granny knot (trefoil # trefoil).
    The knot is tied by construction, not by tool motion.

    Args:
        throws: mirror flag per throw.
        center: where the knotted part is centred [m].
        scale: size of one throw [m] (a throw spans about 6 ``scale`` and uses about
            28 ``scale`` of thread).
        length: total curve length [m]; the two straight tails along -x and +x share
            what the throws leave.
        samples: points per throw.

    Returns:
        K×3 polyline from the -x tail end to the +x tail end.

    Raises:
        InvalidSutureParams: the throws need more than ``length``.
    """
    pieces: list[FloatArray] = []
    pitch = 7.0
    n = len(throws)
    for i, mirror in enumerate(throws):
        k = _open_trefoil(mirror, samples)
        k[:, 0] += (i - (n - 1) / 2) * pitch
        pieces.append(k)
    # Straight runs between throws and out to the tails stay on the lobe-tip line y = -3.
    body = np.vstack(pieces)
    first, last = body[0], body[-1]
    inner = np.vstack([[first[0] - 1.2, -3.0, 0.0], body, [last[0] + 1.2, -3.0, 0.0]])
    used = float(np.linalg.norm(np.diff(inner, axis=0), axis=1).sum()) * scale
    tail = (length - used) / 2
    if tail <= 0:
        raise InvalidSutureParams("length", length, f"> {used:.4g} [m] for these throws")
    left = np.array([[inner[0, 0] - tail / scale, -3.0, 0.0]])
    right = np.array([[inner[-1, 0] + tail / scale, -3.0, 0.0]])
    pts = np.vstack([left, inner, right]) * scale
    return pts + np.asarray(center, dtype=float)


def _resample(path: FloatArray, n: int, seg: float) -> FloatArray:
    """``n + 1`` points along ``path`` spaced by arc length ``seg`` [m].

    The path is extended straight past its end if it is shorter than ``n * seg``.
    """
    path = np.asarray(path, dtype=float)
    # Always continue the path straight past its end, far enough for every chord: the
    # points then end on the extension exactly as on the path (a path only just long
    # enough used to end with a differently placed point).
    tail = path[-1] - path[-2]
    tail = tail / np.linalg.norm(tail)
    path = np.vstack([path, path[-1] + tail * (n + 1) * seg])
    # Walk the polyline placing points a chord ``seg`` apart, so the capsules' tips meet.
    pts = [path[0]]
    k = 0
    for _ in range(n):
        prev = pts[-1]
        while k < len(path) - 1 and np.linalg.norm(path[k + 1] - prev) < seg:
            k += 1
        if k >= len(path) - 1:
            direction = path[-1] - path[-2]
            pts.append(prev + seg * direction / np.linalg.norm(direction))
            continue
        # Intersect the segment path[k] -> path[k+1] with the sphere |x - prev| = seg.
        a, b = path[k], path[k + 1]
        u = b - a
        w = a - prev
        qa, qb, qc = u @ u, 2 * u @ w, w @ w - seg * seg
        disc = max(qb * qb - 4 * qa * qc, 0.0)
        t = (-qb + math.sqrt(disc)) / (2 * qa)
        pts.append(a + min(max(t, 0.0), 1.0) * u)
    return np.array(pts)


def _quat_z_to(v: FloatArray) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) rotating +z onto the unit vector ``v``."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(z @ v)
    if c < -1 + 1e-9:
        return (1.0, 0.0, 0.0, 0.0)
    axis = np.cross(z, v)
    w = 1.0 + c
    q = np.array([axis[0], axis[1], axis[2], w])
    q = q / np.linalg.norm(q)
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


@dataclass
class Suture:
    """A suture thread in a PyBullet world (capsule chain, needle at the last capsule).

    Build it with :meth:`Suture.create`. Segment 0 is the free tail; segment
    ``n_segments - 1`` carries the needle.

    Attributes:
        client: PyBullet physics client id.
        params: the thread's parameters.
        bodies: body id of each capsule, tail to needle.
        links: constraint id of each joint between capsules ``i`` and ``i + 1``.
        needle_body: body id of the needle, or -1.
    """

    client: int
    params: SutureParams
    bodies: list[int] = field(default_factory=list)
    links: list[int] = field(default_factory=list)
    needle_body: int = -1
    _needle_link: int = -1
    _lift: float = 0.0
    _step_poses: CapsuleFrame | None = None
    _settled: bool = False
    _frame: CapsuleFrame | None = None

    @classmethod
    def create(cls, client: int, path: Any, params: SutureParams | None = None) -> Suture:
        """Lay a new thread along a polyline and add it to the world.

        Args:
            client: PyBullet physics client id.
            path: K×3 polyline [m] the thread follows from its tail; extended straight if
                shorter than the thread. A hand-built knotted curve lays a knotted thread.
            params: thread parameters (defaults: 0.3 m, 40 segments).

        Returns:
            The suture, resting (zero velocity) along the path.
        """
        import pybullet as p

        prm = params or SutureParams()
        seg = prm.segment_length
        pts = _resample(np.asarray(path, dtype=float), prm.n_segments, seg)
        r = prm.collision_radius
        height = prm.collision_height()
        shape = p.createCollisionShape(
            p.GEOM_CAPSULE, radius=r, height=height, physicsClientId=client
        )
        visual = p.createVisualShape(
            p.GEOM_CAPSULE,
            radius=r,
            length=height,
            rgbaColor=[0.15, 0.3, 0.9, 1.0],
            physicsClientId=client,
        )
        self = cls(client=client, params=prm)
        inertia = prm.inertia_scale * prm.segment_mass * seg * seg / 12.0
        for i in range(prm.n_segments):
            a, b = pts[i], pts[i + 1]
            axis = (b - a) / np.linalg.norm(b - a)
            body = p.createMultiBody(
                baseMass=prm.segment_mass,
                baseCollisionShapeIndex=shape,
                baseVisualShapeIndex=visual,
                basePosition=((a + b) / 2).tolist(),
                baseOrientation=_quat_z_to(axis),
                physicsClientId=client,
            )
            p.changeDynamics(
                body,
                -1,
                lateralFriction=prm.friction,
                linearDamping=prm.linear_damping,
                angularDamping=prm.angular_damping,
                localInertiaDiagonal=[inertia] * 3,
                physicsClientId=client,
            )
            self.bodies.append(body)
        for i in range(prm.n_segments - 1):
            c = p.createConstraint(
                self.bodies[i],
                -1,
                self.bodies[i + 1],
                -1,
                p.JOINT_POINT2POINT,
                [0, 0, 0],
                [0, 0, seg / 2],
                [0, 0, -seg / 2],
                physicsClientId=client,
            )
            p.changeConstraint(c, maxForce=prm.max_link_force, physicsClientId=client)
            p.setCollisionFilterPair(
                self.bodies[i], self.bodies[i + 1], -1, -1, 0, physicsClientId=client
            )
            self.links.append(c)
        real_mass = prm.real_mass_per_length * seg
        self._lift = max(prm.segment_mass - real_mass, 0.0) * _GRAVITY
        if prm.needle:
            self._add_needle()
        return self

    def _add_needle(self) -> None:
        """Attach a half-circle needle (rigid, 5 capsules) at the last capsule's tip, by a
        ball joint at the needle's swaged end (its frame origin)."""
        import pybullet as p

        prm, c = self.params, self.client
        rn = prm.needle_radius
        k = 5
        shapes: list[int] = []
        positions: list[list[float]] = []
        orientations: list[tuple[float, float, float, float]] = []
        chord = 2 * rn * math.sin(math.pi / (2 * k))
        # Needle frame: swaged end at the origin, the arc bulges along +x in the x-z plane,
        # the tip ends at z = 2 rn.
        for j in range(k):
            a0 = -math.pi / 2 + math.pi * j / k
            a1 = a0 + math.pi / k
            p0 = np.array([rn * math.cos(a0), 0.0, rn + rn * math.sin(a0)])
            p1 = np.array([rn * math.cos(a1), 0.0, rn + rn * math.sin(a1)])
            positions.append(((p0 + p1) / 2).tolist())
            orientations.append(_quat_z_to((p1 - p0) / np.linalg.norm(p1 - p0)))
            shapes.append(p.GEOM_CAPSULE)
        radius = 0.35e-3
        col = p.createCollisionShapeArray(
            shapeTypes=shapes,
            radii=[radius] * k,
            lengths=[chord] * k,
            collisionFramePositions=positions,
            collisionFrameOrientations=orientations,
            physicsClientId=c,
        )
        pos, orn = p.getBasePositionAndOrientation(self.bodies[-1], physicsClientId=c)
        rot = np.array(p.getMatrixFromQuaternion(orn)).reshape(3, 3)
        tip = np.array(pos) + rot[:, 2] * prm.segment_length / 2
        self.needle_body = p.createMultiBody(
            baseMass=_NEEDLE_SIM_MASS,
            baseCollisionShapeIndex=col,
            basePosition=tip.tolist(),
            baseOrientation=orn,
            physicsClientId=c,
        )
        p.changeDynamics(
            self.needle_body,
            -1,
            linearDamping=prm.linear_damping,
            angularDamping=prm.angular_damping,
            physicsClientId=c,
        )
        # Swaged: the thread swivels freely at the needle's back end (a ball joint), so a
        # needle held in a jaw does not make the last capsule a rigid stick on the tool.
        self._needle_link = p.createConstraint(
            self.bodies[-1],
            -1,
            self.needle_body,
            -1,
            p.JOINT_POINT2POINT,
            [0, 0, 0],
            [0, 0, prm.segment_length / 2],
            [0, 0, 0],
            physicsClientId=c,
        )
        p.changeConstraint(self._needle_link, maxForce=prm.max_link_force, physicsClientId=c)
        for b in self.bodies:  # the needle does not snag its own thread
            p.setCollisionFilterPair(b, self.needle_body, -1, -1, 0, physicsClientId=c)

    def pre_step(self) -> None:
        """Cancel the mass-scaled part of the thread's and needle's weight (call every step)."""
        import pybullet as p

        if self.needle_body >= 0:
            pos, _ = p.getBasePositionAndOrientation(self.needle_body, physicsClientId=self.client)
            p.applyExternalForce(
                self.needle_body,
                -1,
                [0.0, 0.0, (_NEEDLE_SIM_MASS - _NEEDLE_REAL_MASS) * _GRAVITY],
                pos,
                p.WORLD_FRAME,
                physicsClientId=self.client,
            )
        stiff = self.params.bending_stiffness > 0.0
        frame = self._read_frame() if self._lift > 0.0 or stiff else None
        self._step_poses = frame
        self._settled = False  # the step about to run moves the bodies
        self._frame = None
        if frame is None:
            return
        c = self.client
        if self._lift > 0.0:
            lift = [0.0, 0.0, self._lift]
            for b, pos in zip(self.bodies, frame.positions, strict=True):
                p.applyExternalForce(b, -1, lift, pos, p.WORLD_FRAME, physicsClientId=c)
        if stiff:
            self._bend(np.array(frame.axes()))

    def stepped(self) -> None:
        """Say that a physics step has just run (call it right after ``stepSimulation``).

        Until the next :meth:`pre_step` nothing moves the thread's bodies, so the poses
        read once (by the ground truth, or by that pre-step) serve every reader. Without
        this call every reader asks the simulator itself."""
        self._settled = True
        self._frame = None

    def _read_frame(self) -> CapsuleFrame:
        """Each capsule's centre [m] and orientation (its unit axis on demand), as the
        simulator gives them; read once per step after :meth:`stepped`."""
        import pybullet as p

        frame = self._frame
        if frame is not None and self._settled:
            return frame
        c = self.client
        pose = p.getBasePositionAndOrientation
        poses = [pose(b, physicsClientId=c) for b in self.bodies]
        frame = CapsuleFrame([x for x, _ in poses], [q for _, q in poses], [None] * len(poses))
        if self._settled:
            self._frame = frame
        return frame

    def take_step_poses(self) -> CapsuleFrame | None:
        """The capsules' poses that :meth:`pre_step` read this step (no body has moved
        since), handed over once; None when it read none."""
        poses, self._step_poses = self._step_poses, None
        return poses

    def _bend(self, axes: FloatArray) -> None:
        """Bending stiffness: at each joint, torques +-k (a_i x a_(i+1)), k = EI / segment
        length [N*m/rad], turn the two capsules' axes towards each other."""
        import pybullet as p

        k = self.params.bending_stiffness / self.params.segment_length
        torque = k * np.cross(axes[:-1], axes[1:])
        total = np.zeros_like(axes)
        total[:-1] += torque
        total[1:] -= torque
        for b, t in zip(self.bodies, total, strict=True):
            p.applyExternalTorque(b, -1, t.tolist(), p.WORLD_FRAME, physicsClientId=self.client)

    # ---- ground truth (evaluation only) -------------------------------------------------

    def _poses(self) -> tuple[FloatArray, FloatArray]:
        frame = self._read_frame()
        return np.array(frame.positions, dtype=float), np.array(frame.axes(), dtype=float)

    def centerline(self) -> FloatArray:
        """The thread's centerline, tail to needle (ground truth).

        Returns:
            (n_segments + 1)×3 array of joint points [m]: the tail tip, the midpoints of the
            (slightly separated) tips of neighbouring capsules, and the needle-end tip.
        """
        pos, axis = self._poses()
        h = self.params.segment_length / 2
        tips_lo = pos - h * axis
        tips_hi = pos + h * axis
        inner = (tips_hi[:-1] + tips_lo[1:]) / 2
        return np.vstack([tips_lo[:1], inner, tips_hi[-1:]])

    def link_gaps(self) -> FloatArray:
        """Separation of each joint's two capsule tips [m] (the constraint error)."""
        pos, axis = self._poses()
        h = self.params.segment_length / 2
        gaps: FloatArray = np.linalg.norm(
            (pos[:-1] + h * axis[:-1]) - (pos[1:] - h * axis[1:]), axis=1
        )
        return gaps

    def stretch(self) -> float:
        """Relative elongation of the thread [-]: (stretched length - rest length) / rest.

        The stretched length is the capsules' rest lengths plus the gaps the joints open.
        """
        return float(self.link_gaps().sum() / self.params.length)

    def tensions(self) -> FloatArray:
        """Tension at each joint between capsules (ground truth) [N].

        Returns:
            (n_segments - 1) array: the force the joint constraint applied in the last step
            (``getConstraintState``), projected on the thread's local direction (from capsule
            ``i`` to capsule ``i + 1``), clipped at zero: a thread pulls, it does not push.
        """
        import pybullet as p

        pos = np.array(self._read_frame().positions, dtype=float)
        # np.diff, np.linalg.norm(axis=1) and np.clip(x, 0, None) by the ufunc calls they
        # make (the same bits without their Python overhead)
        u = pos[1:] - pos[:-1]
        u /= np.sqrt(np.add.reduce(u * u, axis=1, keepdims=True))
        state, client = p.getConstraintState, self.client
        force = np.array([state(c, physicsClientId=client)[:3] for c in self.links])
        # PyBullet reports the joint force acting on the child (capsule i + 1).
        axial: FloatArray = np.maximum(-row_dot(force, u), 0.0)
        return axial

    def peak_tension(self) -> tuple[float, int]:
        """The thread's largest joint tension and where it acts (ground truth).

        Returns:
            ``(tension, point)``: the largest of :meth:`tensions` [N] and the index of its
            joint among the :meth:`centerline`'s points (``1`` to ``n_segments - 1``: the
            joint between capsules ``point - 1`` and ``point``). ``(0.0, 0)`` for a
            thread of one capsule.
        """
        tensions = self.tensions()
        if not len(tensions):
            return 0.0, 0
        i = int(np.argmax(tensions))
        return float(tensions[i]), i + 1

    def contacts(self) -> list[SutureContact]:
        """Every contact point of the thread in the last step (ground truth)."""
        import pybullet as p

        index = {b: i for i, b in enumerate(self.bodies)}
        out: list[SutureContact] = []
        for i, b in enumerate(self.bodies):
            for cp in p.getContactPoints(bodyA=b, physicsClientId=self.client):
                other = cp[2]
                j = index.get(other, -1)
                if j != -1 and j < i:
                    continue  # self-contacts once, from the lower index
                out.append(SutureContact(i, other, j, tuple(cp[5]), float(cp[9])))
        return out

    def knot_position(self) -> tuple[float, float, float] | None:
        """Centroid of the thread-on-thread contacts [m] (ground truth), None without any."""
        pts = [c.position for c in self.contacts() if c.other_segment >= 0]
        if not pts:
            return None
        m = np.mean(np.array(pts), axis=0)
        return (float(m[0]), float(m[1]), float(m[2]))

    def ground_truth(self) -> SutureGroundTruth:
        """Everything the trace records about the thread, in one snapshot (ground truth)."""
        contacts = tuple(self.contacts())
        selfs = [c.position for c in contacts if c.other_segment >= 0]
        knot = None
        if selfs:
            m = np.mean(np.array(selfs), axis=0)
            knot = (float(m[0]), float(m[1]), float(m[2]))
        return SutureGroundTruth(self.centerline(), self.tensions(), self.stretch(), knot, contacts)

    def soften_contacts(self, stiffness: float, damping: float) -> None:
        """Make every contact of the thread's capsules a spring-damper [N/m, N*s/m].

        The capsules' collision radius is six times the real thread's (module doc), so the
        outer 0.75 mm of each capsule is a sheath no real thread fills. Rigid contacts push
        any overlap in it out at the contact ERP's rate whatever force that takes; where a
        knot or a slit jams capsules into one another, that force goes into the chain's
        joints and reads as a tension no tool applied (17.68 N in a knot drawn at 0.6 N).
        A spring-damper contact costs at most ``stiffness`` times the overlap instead.

        PyBullet combines the two bodies' values of a contact as springs in series and
        dampers in parallel: a thread-on-thread contact gets ``stiffness / 2`` and
        ``2 * damping``; a contact with a rigid body (tools, pad) ``stiffness`` and about
        ``damping``. The needle keeps rigid contacts.

        Args:
            stiffness: each capsule's contact stiffness [N/m], > 0.
            damping: each capsule's contact damping [N*s/m], >= 0.

        Raises:
            InvalidSutureParams: stiffness not > 0 or damping < 0.
        """
        import pybullet as p

        if not stiffness > 0:
            raise InvalidSutureParams("contact_stiffness", stiffness, "> 0 [N/m]")
        if not damping >= 0:
            raise InvalidSutureParams("contact_damping", damping, ">= 0 [N*s/m]")
        for body in self.bodies:
            p.changeDynamics(
                body,
                -1,
                contactStiffness=float(stiffness),
                contactDamping=float(damping),
                physicsClientId=self.client,
            )

    def park(self, at: Sequence[float]) -> None:
        """Take the thread out of play without removing its bodies: its joints and the
        needle's swage go, and every capsule and the needle become static and touch
        nothing (no collision group or mask), moved to ``at`` [m] far from the scene.

        PyBullet gives a removed body's id to the next new body, and a collision filter
        pair set on the old body then applied to the new one (a reloaded thread's tail
        fell through a new tissue pad whose id had been the old needle's). Parked, the
        bodies keep their ids, so no new body inherits their pairs.
        """
        import pybullet as p

        c = self.client
        for cons in [*self.links, self._needle_link]:
            if cons >= 0:
                p.removeConstraint(cons, physicsClientId=c)
        where = [float(v) for v in at]
        for body in (b for b in [*self.bodies, self.needle_body] if b >= 0):
            p.changeDynamics(body, -1, mass=0.0, physicsClientId=c)
            p.setCollisionFilterGroupMask(body, -1, 0, 0, physicsClientId=c)
            p.resetBasePositionAndOrientation(body, where, [0, 0, 0, 1], physicsClientId=c)
        self.bodies.clear()
        self.links.clear()
        self.needle_body = self._needle_link = -1
        self._settled = False
        self._frame = self._step_poses = None

    def remove(self) -> None:
        """Remove the thread's bodies and constraints from the world."""
        import pybullet as p

        for c in [*self.links, self._needle_link]:
            if c >= 0:
                p.removeConstraint(c, physicsClientId=self.client)
        for b in [*self.bodies, self.needle_body]:
            if b >= 0:
                p.removeBody(b, physicsClientId=self.client)
        self.bodies.clear()
        self.links.clear()
        self.needle_body = self._needle_link = -1
        self._settled = False
        self._frame = self._step_poses = None
