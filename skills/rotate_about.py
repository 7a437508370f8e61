"""``rotate-about``: rotate a tool about an axis through the RCM point (algorithm 1 step 4).

The axis is OP: O the centre of the spherical joint (the robot's RCM), P a
point given in the world frame or named in the scene, or taken relative to
another robot's tool tip. Rotating the whole tool about an axis through O
keeps the tool through the RCM: the tip moves on a circle about OP (its
distance to the axis is constant and its motion orthogonal to the axis) and
the tool frame turns with it, R(theta) = Rot(OP, theta) R(0). The joints come
from the closed-form inverse kinematics (3.14-3.17), the roll q3 from the
turned tool frame (3.11).

Thesis 4.4.1 step 4 also states the step's failure condition: "the angle formed
between the grasper and the stitcher would have to be sufficiently large to
guarantee that the tip of the needle does not hit the stem of the grasper".
With ``clear_of`` set, the skill checks that before moving: it sweeps the
stitcher's needle (its declared geometry, :data:`STITCHER_NEEDLE`) along the
planned rotation and measures its distance to the other tool's stem, the
segment from that tool's tip to its RCM point (:func:`sweep_clearance`).
:func:`stem_contact` finds the step-3 pose that defines P: the stitcher's open
jaw touching the front (or back) of the other tool's stem.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar, Literal, NamedTuple

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Angle, AngularSpeed, Length, Position

__all__ = [
    "STITCHER_BODY",
    "STITCHER_JAW",
    "STITCHER_NEEDLE",
    "SWEPT_PARTS",
    "RotateAbout",
    "RotateAboutParams",
    "StemContact",
    "SweepClearance",
    "axis_rotation",
    "instrument_angle",
    "segment_distance",
    "stem_contact",
    "sweep_clearance",
]


def _needle_points() -> tuple[tuple[float, float, float], ...]:
    import math

    jx, jz, r = -4e-3, 3e-3, 6e-3
    arc = [-0.5 * math.pi + math.pi * k / 8 for k in range(9)]
    return ((jx, 0.0, jz), *((jx + r * math.cos(a), 0.0, jz + r + r * math.sin(a)) for a in arc))


STITCHER_JAW: tuple[float, float, float] = (4e-3, 0.0, 3e-3)
"""Centre of the stitcher's empty (open) jaw in its tool frame [m]: the jaws sit at
+-4 mm along the tool x, 3 mm beyond the tip (the bundled EndoStitch-like tool,
Fig. 4.3); the needle is in the -x jaw."""

STITCHER_NEEDLE: tuple[tuple[float, float, float], ...] = _needle_points()
"""The stitcher's needle jaw centre and nine points of its needle in the tool frame
[m]: a 6 mm half circle from the -x jaw, bulging towards the other jaw, its tip
12 mm beyond the jaw. These are the parts that must not hit the other stem
during the rotation about OP (4.4.1 step 4); the open jaw touches it by design."""


STITCHER_BODY: tuple[tuple[float, float, float], ...] = tuple(
    (x, y, z)
    for x in (-5e-3, -2.5e-3, 0.0, 2.5e-3, 5e-3)
    for y in (-1e-3, 1e-3)
    for z in (-1e-3, 1e-3)
)
"""Points of the stitcher's tip body in its tool frame [m]: the 10 x 2 x 2 mm block
that carries both jaws, centred on the tool tip (corners and edge midpoints)."""

SWEPT_PARTS: dict[str, tuple[tuple[float, float, float], ...]] = {
    "needle-tip": STITCHER_NEEDLE[-1:],
    "needle": STITCHER_NEEDLE,
    "tool": STITCHER_NEEDLE + STITCHER_BODY,
}
"""What ``rotate-about`` checks against the other stem: the needle's tip (the thesis'
condition), the needle and its jaw, or those and the tip body."""


class SweepClearance(NamedTuple):
    """How close the swept tool comes to the other tool's stem (4.4.1 step 4).

    Attributes:
        distance: smallest distance between a swept point and the stem's surface [m]
            (negative: the needle passes through the stem).
        angle: rotation angle about OP where it occurs [rad].
        instrument_angle: angle between the two tools' axes at the start [rad].
    """

    distance: float
    angle: float
    instrument_angle: float


class StemContact(NamedTuple):
    """The step-3 pose of algorithm 1: the open jaw touching the other tool's stem.

    Attributes:
        joints: joints of the rotating robot [rad, rad, rad, m].
        tip: its tool-tip position, world frame [m].
        contact: the open jaw's centre, the point P of the axis OP, world frame [m].
        stem_point: the point of the stem's axis that the jaw touches, world frame [m].
        instrument_angle: angle between the two tools' axes [rad].
    """

    joints: Any
    tip: Any
    contact: Any
    stem_point: Any
    instrument_angle: float


def segment_distance(points: Any, a: Any, b: Any) -> Any:
    """Distance [m] of each point (n x 3) to the segment from ``a`` to ``b`` [m]."""
    import numpy as np

    pts = np.atleast_2d(np.asarray(points, dtype=float))
    a = np.asarray(a, dtype=float)
    ab = np.asarray(b, dtype=float) - a
    s = np.clip((pts - a) @ ab / float(ab @ ab), 0.0, 1.0)
    return np.linalg.norm(pts - (a + np.outer(s, ab)), axis=1)


def instrument_angle(axis_a: Any, axis_b: Any) -> float:
    """Angle [rad] between two tools' axes, each pointing from its RCM into the body."""
    import math

    import numpy as np

    a = np.asarray(axis_a, dtype=float)
    b = np.asarray(axis_b, dtype=float)
    c = float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.acos(max(-1.0, min(1.0, c)))


def sweep_clearance(
    origin: Any,
    axis: Any,
    tip: Any,
    frame: Any,
    angle: float,
    stem: tuple[Any, Any],
    stem_radius: float,
    points: Any = STITCHER_NEEDLE,
    samples: int = 361,
) -> SweepClearance:
    """Clearance of tool points turned by up to ``angle`` about the axis through ``origin``.

    The tool (tip position ``tip`` [m], frame ``frame`` whose columns are its axes)
    turns rigidly by theta in [0, angle] about ``axis`` through ``origin`` (O, the
    RCM point): a tool point x moves to O + R(theta) (tip + frame x - O).

    Args:
        origin: O [m], world frame.
        axis: direction of OP [-].
        tip: tool tip at theta = 0 [m].
        frame: 3x3 tool frame at theta = 0 (columns x, y, z) [-].
        angle: rotation angle [rad].
        stem: (tip, RCM point) of the other tool [m]: its stem is the segment between.
        stem_radius: radius of the other tool's stem [m].
        points: tool points in the tool frame [m] (default: :data:`STITCHER_NEEDLE`).
        samples: angles sampled, ends included.

    Returns:
        The :class:`SweepClearance`; its ``instrument_angle`` is between the tool's z
        axis and the stem's direction from its RCM point to its tip.
    """
    import numpy as np

    o = np.asarray(origin, dtype=float)
    local = np.asarray(frame, dtype=float) @ np.asarray(points, dtype=float).T  # 3 x n
    rel = (np.asarray(tip, dtype=float)[:, None] + local - o[:, None]).T  # n x 3
    best, at = float("inf"), 0.0
    for theta in np.linspace(0.0, angle, max(samples, 2)):
        world = o + rel @ axis_rotation(axis, float(theta)).T
        d = float(np.min(segment_distance(world, stem[0], stem[1]))) - stem_radius
        if d < best:
            best, at = d, float(theta)
    stem_axis = np.asarray(stem[0], dtype=float) - np.asarray(stem[1], dtype=float)
    return SweepClearance(best, at, instrument_angle(np.asarray(frame)[:, 2], stem_axis))


def stem_contact(
    base: Any,
    stem: tuple[Any, Any],
    height: float,
    side: float,
    stem_radius: float,
    jaw: Any = STITCHER_JAW,
    jaw_half_width: float = 1e-3,
    iterations: int = 30,
) -> StemContact:
    """Joints that put the open jaw against the front (``side`` +1) or back (-1) of a stem.

    Algorithm 1 step 3 (4.4.1): the stitcher's open jaw touches the grasper stem at
    P, ``height`` [m] up the stem from its tip. With u the stem's unit axis from its
    tip towards its RCM point, e_over the unit vector from the stem towards this
    robot's RCM point O (orthogonal to u) and e_side = u x e_over (the same frame as
    the ``wrap`` skill), the jaw's centre sits at
    P + side (stem_radius + jaw_half_width) e_side, and the tool's x axis (from the
    needle jaw to the open jaw) points at the stem: -side e_side, made orthogonal
    to the tool axis by the roll (3.11). Solved by fixed-point iteration on the
    closed-form inverse kinematics (3.14-3.17).

    Args:
        base: this robot's (base position [m], row-major 3x3 rotation).
        stem: (tip, RCM point) of the other tool, world frame [m].
        height: distance of P up the stem from its tip [m].
        side: +1 for the front, -1 for the back.
        stem_radius: radius of the stem [m].
        jaw: open jaw centre in the tool frame [m].
        jaw_half_width: half the jaw's thickness along the tool x [m].
        iterations: fixed-point iterations.
    """
    import math

    import numpy as np

    from skills.tool_path import ik_world
    from suture_engine.robot.kinematics import rotation

    pos = np.asarray(base[0], dtype=float)
    r_base = np.asarray(base[1], dtype=float).reshape(3, 3)
    t2, o2 = (np.asarray(v, dtype=float) for v in stem)
    u = (o2 - t2) / np.linalg.norm(o2 - t2)
    p_stem = t2 + height * u
    over = pos - p_stem
    over = over - (over @ u) * u
    over = over / np.linalg.norm(over)
    e_side = np.cross(u, over)
    contact = p_stem + side * (stem_radius + jaw_half_width) * e_side
    jaw_v = np.asarray(jaw, dtype=float)
    tip = contact.copy()
    q = ik_world(tip, 0.0, base)
    for _ in range(iterations):
        q = ik_world(tip, 0.0, base)
        r0 = r_base @ rotation(q)  # roll 0
        q[2] = math.atan2(float(-side * e_side @ r0[:, 1]), float(-side * e_side @ r0[:, 0]))
        tip = contact - r_base @ rotation(q) @ jaw_v
    q = ik_world(tip, float(q[2]), base)
    frame = r_base @ rotation(q)
    angle = instrument_angle(frame[:, 2], -u)
    return StemContact(q, tip, contact, p_stem, angle)


class RotateAboutParams(SkillParams):
    """Parameters of ``rotate-about``."""

    robot: RoleRef
    """The role of the robot that rotates."""
    angle: Angle = Field(ge=-4 * 3.141592653589793, le=4 * 3.141592653589793)
    """Rotation angle about OP [rad]; the mirror image of a knot uses the opposite sign."""
    point: PointRef | Position | None = None
    """P, the second point of the axis: a tissue point or (x, y, z) in the world frame
    [m]; ``None`` uses the contact point left by the previous step."""
    relative_to: RoleRef | None = None
    """When set, ``point`` is an offset [m] from that robot's tool tip."""
    speed: AngularSpeed = Field(default=0.5, gt=0.0, le=5.0)
    """Angular speed [rad/s]."""
    tolerance: Length | None = Field(default=None, gt=0.0, le=5e-3)
    """Tip position tolerance at the goal [m]; ``None`` uses the skill's
    :attr:`TOLERANCE`. A looser one suits a backend whose position control leaves
    a steady error (e.g. heavier mounted tools)."""
    clear_of: RoleRef | None = None
    """When set, the rotating tool's needle (``swept``) must stay ``clearance`` [m]
    off this role's stem along the whole rotation (4.4.1 step 4),
    or the skill fails before moving."""
    clearance: Length = Field(default=1e-3, ge=0.0, le=0.02)
    """Smallest allowed distance between the needle and the stem's surface [m]."""
    stem_radius: Length = Field(default=2.5e-3, gt=0.0, le=0.01)
    """Radius of the ``clear_of`` tool's stem [m] (5 mm laparoscopic tools)."""
    swept: Literal["needle-tip", "needle", "tool"] = "needle-tip"
    """What must clear the stem (:data:`SWEPT_PARTS`): the needle's tip (the thesis'
    condition, 4.4.1 step 4), the whole needle and its jaw
    (:data:`STITCHER_NEEDLE`), or also the stitcher's tip body
    (:data:`STITCHER_BODY`)."""


def axis_rotation(axis: Any, angle: float) -> Any:
    """Rotation matrix of ``angle`` [rad] about the unit ``axis`` (Rodrigues' formula)."""
    import numpy as np

    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    kx = np.array(((0.0, -k[2], k[1]), (k[2], 0.0, -k[0]), (-k[1], k[0], 0.0)))
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * (kx @ kx)


class RotateAbout(Skill):
    """Rotate the tool by ``angle`` [rad] about the axis OP through the RCM point O.

    With ``point`` unset, P is the tool tip at the start (the contact point the
    previous step left). The rotation follows a minimum-jerk profile whose peak
    rate is ``speed``. Fails when the path leaves the joint limits, or when the
    tip is not within :attr:`TOLERANCE` [m] of the goal :attr:`SETTLE_S` [s]
    after the path, or (with ``clear_of``) when the planned sweep brings the needle
    closer than ``clearance`` to the other tool's stem (4.4.1 step 4).
    """

    name: ClassVar[str] = "rotate-about"
    Params: ClassVar[type[SkillParams]] = RotateAboutParams
    tools: ClassVar[tuple[str, ...] | None] = None

    TOLERANCE: ClassVar[float] = 1e-3
    """Tip position tolerance at the goal [m]."""
    SETTLE_S: ClassVar[float] = 1.0
    """Time after the path to reach the tolerance [s]."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._base: Any = None
        self._path: Any = None
        self._failure = ""
        self._t0 = 0.0
        self.axis_point: Any = None
        self.axis: Any = None
        self._goal: Any = None
        self._thetas: Any = [0.0]
        self._rolls: Any = [0.0]
        self.clearance: SweepClearance | None = None
        """The needle's clearance from the ``clear_of`` stem, planned at start."""
        self.limit_violation = ""
        """The planned path's first joint-limit violation (empty when none)."""

    def _point_world(self, ctx: Any) -> Any:
        import numpy as np

        from skills.tool_path import tip_world

        p = self.params
        assert isinstance(p, RotateAboutParams)
        if p.point is None:
            return tip_world(ctx.start.robots[self._robot].q, self._base)
        if isinstance(p.point, str):
            points = ctx.scene.tissue.points if ctx.scene is not None else {}
            if p.point not in points:
                raise KeyError(f"no tissue point named {p.point!r}; known: {sorted(points)}")
            pt = np.array(points[p.point], dtype=float)
        else:
            pt = np.array(p.point, dtype=float)
        if p.relative_to is not None:
            other = ctx.robot(p.relative_to)
            pt = pt + tip_world(ctx.start.robots[other].q, ctx.base_poses.get(other))
        return pt

    def joints_at(self, theta: float, q0: Any, roll_reference: float | None = None) -> Any:
        """Joints [rad, m] after turning the tool by ``theta`` [rad] about OP (3.11, 3.14-3.17).

        Args:
            theta: rotation angle about OP [rad].
            q0: joints at theta = 0 [rad, m].
            roll_reference: the roll [rad] the result is unwrapped towards (continuity);
                default: interpolated from the table made by :meth:`start`.
        """
        import math

        import numpy as np

        from skills.tool_path import unwrap_roll
        from suture_engine.robot.kinematics import forward_kinematics, inverse_kinematics, rotation

        r_base = np.eye(3) if self._base is None else np.asarray(self._base[1]).reshape(3, 3)
        axis_b = r_base.T @ self.axis
        rot = axis_rotation(axis_b, theta)
        if roll_reference is None:
            roll_reference = float(np.interp(theta, self._thetas, self._rolls))
        tip_b = rot @ np.asarray(forward_kinematics(q0).position)
        r_goal = rot @ rotation(q0)
        q = inverse_kinematics(tip_b, 0.0)
        m = rotation(q).T @ r_goal  # Rz(q3), from R = Rx(q1) Ry(q2) Rz(q3) (3.11)
        q[2] = unwrap_roll(math.atan2(m[1, 0], m[0, 0]), roll_reference)
        return q

    def _roll_table(self, angle: float, q0: Any, samples: int = 720) -> None:
        """Unwrap the roll continuously along the rotation (a table of theta -> q3)."""
        import numpy as np

        thetas = np.linspace(0.0, angle, samples + 1)
        rolls = np.empty_like(thetas)
        ref = float(q0[2])
        for i, th in enumerate(thetas):
            ref = float(self.joints_at(float(th), q0, ref)[2])
            rolls[i] = ref
        if angle < 0:
            thetas, rolls = thetas[::-1], rolls[::-1]
        self._thetas, self._rolls = thetas, rolls

    def start(self, ctx: Any) -> None:
        """Find the axis OP and plan the rotation.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        import numpy as np

        from skills.tool_path import ToolPath, joint_box, tip_world

        p = self.params
        assert isinstance(p, RotateAboutParams)
        self._robot = ctx.robot(p.robot)
        self._base = ctx.base_poses.get(self._robot)
        self._t0 = ctx.t0
        self._failure = ""
        q0 = np.array(ctx.start.robots[self._robot].q)
        origin = np.zeros(3) if self._base is None else np.asarray(self._base[0], dtype=float)
        self.axis_point = origin
        op = self._point_world(ctx) - origin
        if float(np.linalg.norm(op)) < 1e-6:
            self._failure = "P coincides with the RCM point O: the axis OP is undefined"
            self.axis = np.array((0.0, 0.0, 1.0))
        else:
            self.axis = op / np.linalg.norm(op)
        self._roll_table(p.angle, q0)
        duration = max(1.875 * abs(p.angle) / p.speed, 0.1)
        self._path = ToolPath(lambda s: self.joints_at(s * p.angle, q0), duration)
        self.limit_violation = self._path.first_violation(joint_box(ctx, self._robot))
        self._failure = self._failure or self.limit_violation
        if p.clear_of is not None:
            self._check_clearance(ctx, q0, ctx.robot(p.clear_of))
        self._goal = tip_world(self._path.joints_at(1.0), self._base)

    def _check_clearance(self, ctx: Any, q0: Any, other: str) -> None:
        """Plan the needle's clearance from ``other``'s stem; fail when it is too small."""
        import math

        import numpy as np

        from skills.tool_path import tip_world
        from suture_engine.robot.kinematics import rotation

        p = self.params
        assert isinstance(p, RotateAboutParams)
        r_base = np.eye(3) if self._base is None else np.asarray(self._base[1]).reshape(3, 3)
        other_base = ctx.base_poses.get(other)
        o2 = np.zeros(3) if other_base is None else np.asarray(other_base[0], dtype=float)
        stem = (tip_world(ctx.start.robots[other].q, other_base), o2)
        self.clearance = sweep_clearance(
            self.axis_point,
            self.axis,
            tip_world(q0, self._base),
            r_base @ rotation(q0),
            p.angle,
            stem,
            p.stem_radius,
            SWEPT_PARTS[p.swept],
        )
        if not self._failure and self.clearance.distance < p.clearance:
            c = self.clearance
            self._failure = (
                f"the {p.swept} comes {c.distance * 1e3:.2f} mm from the {p.clear_of} stem "
                f"at {math.degrees(c.angle):.0f} deg about OP (needs {p.clearance * 1e3:.2f} mm; "
                f"angle between the instruments {math.degrees(c.instrument_angle):.0f} deg)"
            )

    def step(self, ctx: Any, obs: Any) -> Any:
        """Track the rotation; success at the goal.

        Args:
            ctx: the skill context.
            obs: this tick's observation.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        import numpy as np

        from skills.tool_path import hold_command, tip_tolerance, tip_world
        from suture_engine.runtime.observation import (
            Command,
            RobotCommand,
            SkillStatus,
            StepResult,
        )

        if self._failure:
            q = obs.robots[self._robot].q
            return StepResult(hold_command(self._robot, q), SkillStatus.FAILURE, self._failure)
        t = obs.t - self._t0
        q, qd, done = self._path.sample(t)
        cmd = Command({self._robot: RobotCommand.position(q, qd)})
        if not done:
            return StepResult(cmd)
        err = float(np.linalg.norm(tip_world(obs.robots[self._robot].q, self._base) - self._goal))
        if err <= tip_tolerance(self.params, self.TOLERANCE):
            return StepResult(cmd, SkillStatus.SUCCESS)
        if t >= self._path.duration + self.SETTLE_S:
            return StepResult(
                cmd, SkillStatus.FAILURE, f"tool tip {err * 1e3:.2f} mm from the rotated pose"
            )
        return StepResult(cmd)
