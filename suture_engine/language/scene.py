"""The scene: two EndoBots, the tissue with its wound, the suture, physics.

Quantities are SI after load. The scene derives the procedure's tension limit
from the weaker of the suture's knot-pull strength (thesis Table 7.1) and the
tissue's pull-out tension (Table 7.2), times a safety factor.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
    ValidationInfo,
    field_validator,
    model_validator,
)

from suture_engine.faults.model import Fault
from suture_engine.language.units import (
    Angle,
    Damping,
    Duration,
    Force,
    Length,
    LinearDensity,
    Mass,
    Position,
    Rate,
)
from suture_engine.language.units import Stiffness as StiffnessUnit

__all__ = [
    "GRAVITY",
    "GRIP_FRACTION",
    "KNOT_PULL_STRENGTH_KG",
    "ON_SURFACE_TOLERANCE",
    "SUTURE_DIAMETER_MM",
    "TISSUE_PULLOUT_N",
    "UNIT_NORMAL_TOLERANCE",
    "ForcePlant",
    "JointLimits",
    "Physics",
    "Pose",
    "Post",
    "RobotSpec",
    "Scene",
    "Suture",
    "Tissue",
    "ToolType",
    "Wound",
]

GRIP_FRACTION = 0.9
"""A grasper's default grip force, as a fraction of the scene's tension limit [-]."""
UNIT_NORMAL_TOLERANCE = 1e-3
"""Largest accepted deviation of the tissue normal's length from 1 [-]."""
ON_SURFACE_TOLERANCE = 1e-3
"""Largest distance of a wound end or a bite's entry/exit point from the tissue surface [m]."""

GRAVITY = 9.80665
"""Standard gravity [m/s^2], converts the table's kilograms-force to newtons."""

SUTURE_DIAMETER_MM: dict[str, tuple[float, float]] = {
    "0": (0.35, 0.399),
    "2-0": (0.30, 0.339),
    "3-0": (0.20, 0.249),
    "4-0": (0.15, 0.199),
    "5-0": (0.10, 0.149),
    "6-0": (0.07, 0.099),
}
"""USP size -> (min, max) diameter [mm], thesis Table 7.1."""

KNOT_PULL_STRENGTH_KG: dict[str, float] = {
    "0": 2.16,
    "2-0": 1.44,
    "3-0": 0.96,
    "4-0": 0.60,
    "5-0": 0.40,
    "6-0": 0.20,
}
"""USP size -> knot-pull tensile strength [kgf], thesis Table 7.1."""

TISSUE_PULLOUT_N: dict[str, float] = {
    "fat": 1.96,
    "muscle": 12.45,
    "skin": 17.85,
    "fascia": 36.98,
}
"""Tissue type -> suture pull-out tension [N], thesis Table 7.2."""

ToolType = Literal["grasper", "hook-grasper", "bent-tip-grasper", "stitcher"]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True)


class Pose(_Model):
    """A base pose in the world frame."""

    position: Position = (0.0, 0.0, 0.0)
    """Origin of the robot's base frame = its remote centre of motion [m]."""
    rpy: tuple[Angle, Angle, Angle] = (0.0, 0.0, 0.0)
    """Roll, pitch, yaw of the base frame (fixed axes x, y, z) [rad]."""


class JointLimits(_Model):
    """Joint limits of an EndoBot: yaw q1, pitch q2, roll q3 [rad], insertion q4 [m]."""

    yaw: tuple[Angle, Angle] = (-math.radians(70), math.radians(70))
    """q1 range, rotation about x [rad]."""
    pitch: tuple[Angle, Angle] = (-math.radians(70), math.radians(70))
    """q2 range, rotation about y [rad]."""
    roll: tuple[Angle, Angle] = (-math.pi, math.pi)
    """q3 range, rotation about the tool axis z [rad]."""
    insertion: tuple[Length, Length] = (0.02, 0.30)
    """q4 range, extension along the tool axis [m]."""

    @model_validator(mode="after")
    def _ordered(self) -> JointLimits:
        for name in ("yaw", "pitch", "roll", "insertion"):
            lo, hi = getattr(self, name)
            if lo >= hi:
                raise ValueError(f"{name}: lower limit {lo:g} must be below upper limit {hi:g}")
        return self


class RobotSpec(_Model):
    """One EndoBot: base pose, joint limits and the tool it carries."""

    base: Pose = Field(default_factory=Pose)
    """Base pose; the base origin is the RCM (incision point)."""
    joint_limits: JointLimits = Field(default_factory=JointLimits)
    """Joint limits."""
    tool: ToolType
    """The tool: ``grasper``, ``hook-grasper`` (flexible hook, 4.4.2),
    ``bent-tip-grasper`` (algorithm 3) or ``stitcher`` (two jaws passing the needle)."""
    grip_force: Force | None = Field(default=None, gt=0.0)
    """Largest pull a grasper's jaws hold the thread with [N]; pulled harder, the thread
    slides through them, so the pull through the grasp stays under it. At most the scene's
    tension limit. ``None``: ``GRIP_FRACTION`` (0.9) times the tension limit. Graspers only:
    the stitcher latches its needle, which cannot slide through the jaw."""


class Wound(_Model):
    """The wound line on the tissue surface."""

    start: Position
    """One end of the wound [m]."""
    end: Position
    """The other end of the wound [m]."""
    gap: Length | None = Field(default=None, ge=0.0)
    """The wound's opening between its two edges at the surface [m]; 0: the edges apposed.
    ``None``: the simulator's default (the PyBullet pad's 1 mm slit,
    :data:`backends.pybullet.tissue.WOUND_GAP`). A simulator refuses an opening that leaves
    a bite's entry or exit point in it (the PyBullet pad does, when the run starts)."""


class Tissue(_Model):
    """The tissue: its type, surface normal, wound and named points."""

    type: Literal["fat", "muscle", "skin", "fascia"]
    """Tissue type; gives the suture pull-out tension (Table 7.2)."""
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    """Outward surface normal in the world frame [-]."""
    wound: Wound
    """The wound line [m]."""
    points: dict[str, Position] = Field(default_factory=dict)
    """Named points (entry and exit points of the bites, knot site) [m]."""
    stiffness: StiffnessUnit = Field(default=200.0, gt=0.0)
    """Tissue stiffness normal to the surface [N/m]."""

    @property
    def pullout_tension(self) -> float:
        """The suture pull-out tension of this tissue [N] (Table 7.2)."""
        return TISSUE_PULLOUT_N[self.type]

    @field_validator("normal")
    @classmethod
    def _nonzero(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        norm = math.hypot(*v)
        if norm < 1e-12:
            raise ValueError("the normal must be non-zero")
        if abs(norm - 1.0) > UNIT_NORMAL_TOLERANCE:
            raise ValueError(f"the normal must be a unit vector, its length is {norm:.6g}")
        return v

    def height(self, point: tuple[float, float, float]) -> float:
        """Signed distance of ``point`` from the tissue surface along the normal [m].

        The surface is the plane through the wound's start with the tissue's normal.
        """
        pairs = zip(point, self.wound.start, self.normal, strict=True)
        return sum((p - s) * n for p, s, n in pairs)

    @field_validator("wound")
    @classmethod
    def _wound_on_surface(cls, v: Wound, info: ValidationInfo) -> Wound:
        normal = info.data.get("normal")
        if normal is None:  # the normal itself is wrong: reported on its own
            return v
        pairs = zip(v.end, v.start, normal, strict=True)
        end = sum((p - s) * n for p, s, n in pairs)
        if abs(end) > ON_SURFACE_TOLERANCE:
            raise ValueError(
                f"the wound's end is {end * 1e3:.3g} mm off the tissue surface "
                "(the plane through its start with the tissue normal)"
            )
        return v


class Suture(_Model):
    """The suture: USP size and length."""

    usp: Literal["0", "2-0", "3-0", "4-0", "5-0", "6-0"]
    """USP size (Table 7.1)."""
    length: Length = Field(gt=0.0)
    """Length of the suture [m]."""
    start: Literal["needle", "tail-held", "stitched"] | None = None
    """Start state in a simulator with a stitcher: ``needle`` (the thread hangs from the
    needle in the stitcher's jaw; the default), ``tail-held`` (the needle is in the
    stitcher's jaw and the thread lies on the tissue surface from a free end 30 mm out of
    the entry point, away from the exit, to below the needle; the scene's first grasper,
    as an assistant would, holds that free end, so that the stitch leaves the tail
    straight where the knot procedures take it; a simulator without the thread starts
    that grasper there too) or ``stitched`` (the stitch is already made: the thread runs
    through the tissue with a 30 mm tail out of the entry point, and on from the exit
    point to the needle in the stitcher's jaw)."""
    segment: Length | None = Field(default=None, ge=1e-3, le=20e-3)
    """Length of one simulated capsule of the thread [m] (simulators that model the thread
    as a chain; at least 40 capsules are used). ``None``: 7.5 mm. Shorter capsules bend
    round smaller tools (a hook, a jaw) at a cost in physics time roughly proportional to
    their number."""
    contact_stiffness: StiffnessUnit | None = Field(default=None, gt=0.0)
    """Each simulated capsule's contact as a spring of this stiffness [N/m] (simulators
    whose thread is thicker than the real one to keep strands from passing through each
    other: a spring in that sheath costs at most its stiffness times the overlap, where a
    rigid contact pushes an overlap out with whatever force it takes). Two capsules meet
    as springs in series, at half of it. ``None``: rigid contacts."""
    contact_damping: Damping = Field(default=5.0, ge=0.0)
    """The damping of those contacts [N*s/m]; used with ``contact_stiffness`` only."""
    smooth_joints: StrictBool = False
    """Simulators that model the thread as a chain of capsules: centre each capsule's
    rounded ends on its joints, so the chain's surface is a round tube through every joint.
    ``false``: the capsules meet tip to tip, and each joint is a groove as deep as the
    capsule's radius, in which a crossing strand can wedge the joint open."""
    damping: Rate | None = Field(default=None, ge=0.0)
    """Simulators that give the thread more mass than the real one (to keep a chain of
    capsules stable): how fast its free motion dies away [1/s]. Each capsule is slowed by
    its simulated mass times this rate times its velocity, times (1 + its speed in m/s),
    and its spin likewise. The real thread is so light that the pad's friction stops it
    almost at once; a heavier one slowed too little coasts on the energy its stretch gives
    back, and a knot pulled taut and let go flings its ends apart. ``None``: 0.5 /s."""
    weight: LinearDensity | None = Field(default=None, gt=0.0)
    """Simulators that give the thread more mass than the real one: the mass per length
    whose weight it keeps [kg/m]; the rest of its weight is cancelled, so that the tools
    carry about the real thread's. A thread damped at ``damping`` falls at most at
    ``g * weight / (simulated mass per length * damping)``: a heavier weight lets a
    well-damped thread still fall off a tool's open jaws. ``None``: 0.1 g/m, about the
    real 2-0 thread's."""

    @field_validator("usp", mode="before")
    @classmethod
    def _usp_text(cls, v: object) -> object:
        return str(v) if isinstance(v, int) and not isinstance(v, bool) else v

    @property
    def diameter(self) -> float:
        """Nominal diameter [m]: the middle of Table 7.1's range."""
        lo, hi = SUTURE_DIAMETER_MM[self.usp]
        return 0.5 * (lo + hi) * 1e-3

    @property
    def knot_pull_strength(self) -> float:
        """Knot-pull tensile strength [N] (Table 7.1, kgf times standard gravity)."""
        return KNOT_PULL_STRENGTH_KG[self.usp] * GRAVITY


class Post(_Model):
    """A rigid calibration post standing on the table, along the world's z.

    Its surface is a capsule: the points within ``radius`` of the segment from
    ``position`` to ``height`` above it. The robots touch it to register their bases
    (skill ``register``): the thesis calibrated them with a 3D digitizer (Fig. 4.31).
    """

    position: Position
    """Foot of the post's axis, world frame [m]."""
    height: Length = Field(default=0.04, gt=0.0, le=0.2)
    """Length of the axis [m]; the top is ``radius`` higher."""
    radius: Length = Field(default=0.002, gt=0.0, le=0.02)
    """Radius [m]."""


class ForcePlant(_Model):
    """The mass-damper-spring seen by the force controller (7.23-7.25)."""

    mass: Mass = Field(default=1.0, gt=0.0)
    """m [kg]."""
    damping: Damping = Field(default=1.0, ge=0.0)
    """b [N*s/m]."""
    stiffness: StiffnessUnit = Field(default=10.0, gt=0.0)
    """k, environment (suture and tissue) stiffness [N/m]."""


class Physics(_Model):
    """Simulation and sensor settings."""

    timestep: Duration = Field(default=1e-3, gt=0.0, le=0.01)
    """Physics and control period [s] (1 kHz by default)."""
    measurement_delay: Duration = Field(default=0.0, ge=0.0, le=1.0)
    """Delay of the force measurement [s]; used by the force-gain check (7.41, 7.43)."""
    force_noise: Force = Field(default=0.0, ge=0.0)
    """Standard deviation of the base force sensor's noise [N]."""
    force_plant: ForcePlant = Field(default_factory=ForcePlant)
    """The force-control plant."""
    seed: int = 0
    """Random seed."""


class Scene(_Model):
    """The scene of a procedure."""

    name: str = ""
    """A short name."""
    description: str = ""
    """Free text."""
    robots: dict[str, RobotSpec]
    """The two EndoBots by name (``endobot_1``, ``endobot_2``)."""
    tissue: Tissue
    """The tissue."""
    suture: Suture
    """The suture."""
    physics: Physics = Field(default_factory=Physics)
    """Physics and sensor settings."""
    posts: dict[str, Post] = Field(default_factory=dict)
    """Rigid calibration posts by name, at known positions (see ``register``)."""
    safety_factor: float = Field(default=0.5, gt=0.0, le=1.0)
    """Fraction of the weaker of suture strength and pull-out allowed [-]."""
    faults: list[Fault] = Field(default_factory=list)
    """Faults to inject while the procedure runs (sensor noise, bias, delay, dropout;
    grasp slip; suture snag; joint lock or weakness; physics blow-up), each with its
    trigger (``at``, ``when`` a state is entered, or random with a seed). The same
    vocabulary as ``suture run --fault``."""

    @field_validator("robots")
    @classmethod
    def _two(cls, v: dict[str, RobotSpec]) -> dict[str, RobotSpec]:
        if len(v) != 2:
            raise ValueError(f"a scene has exactly two EndoBots, found {len(v)}")
        return v

    @model_validator(mode="after")
    def _grip_forces(self) -> Scene:
        for name, spec in self.robots.items():
            if spec.grip_force is None:
                continue
            if spec.tool == "stitcher":
                raise ValueError(
                    f"robots.{name}.grip_force: a stitcher latches its needle and has no "
                    "grip force (graspers only)"
                )
            if spec.grip_force > self.tension_limit:
                raise ValueError(
                    f"robots.{name}.grip_force: {spec.grip_force:g} N is above the scene's "
                    f"tension limit {self.tension_limit:.3g} N (the jaws would pull the "
                    "thread past it)"
                )
        return self

    def grip_force(self, robot: str) -> float:
        """The grip force of ``robot``'s grasper [N] (its own, or ``GRIP_FRACTION`` times
        the tension limit)."""
        own = self.robots[robot].grip_force
        return GRIP_FRACTION * self.tension_limit if own is None else own

    @field_validator("faults")
    @classmethod
    def _fault_robots(cls, v: list[Fault], info: ValidationInfo) -> list[Fault]:
        robots = info.data.get("robots")
        if robots is None:  # the robots themselves are wrong: reported on their own
            return v
        for i, fault in enumerate(v):
            if fault.robot is not None and fault.robot not in robots:
                raise ValueError(
                    f"faults[{i}]: robot {fault.robot!r} is not a scene robot ({', '.join(robots)})"
                )
        return v

    @property
    def tension_limit(self) -> float:
        """min(knot-pull strength, pull-out tension) * safety factor [N]."""
        return min(self.suture.knot_pull_strength, self.tissue.pullout_tension) * self.safety_factor
