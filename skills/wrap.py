"""``wrap``: loop the suture around the other tool (algorithms 2 and 3).

Algorithm 2 moves the stitcher over the extended hook so that the suture hangs
over it; algorithm 3 moves the needle holder around the bent grasper tip. The
mirror image of a knot wraps in the opposite direction.

The other tool's shaft is the line from its RCM point O' through its tip T'
(both known from its encoders and base pose). The loop lies in the plane
orthogonal to the shaft at :attr:`Wrap.HEIGHT` up the shaft from T', on a
circle of ``radius`` about it. "Over" the other tool is the side of the shaft
facing this robot's RCM point O: there this robot's tool ends before it reaches
the other shaft, so the tools do not meet, and the suture hanging from the tip
drapes over the other tool. With e_over the unit vector from the shaft towards
O (orthogonal to it) and e_side = shaft x e_over, the *front* is +e_side. The
tip moves to the start of the arc through a waypoint two radii over the
shaft, then along the arc: ``front-to-back`` from +e_side over e_over to
-e_side, ``back-to-front`` the other way, through
pi (2 turns - 1) [rad]: one turn is the half loop over the hook of algorithm 2
step 2; every further turn also passes the far side of the other shaft, where
the tools' shafts cross.

With ``around_segment: tip`` (algorithm 3, 4.4.3) the loop goes around the bent-tip
grasper's bent arm instead: the line from its universal joint U, :data:`BENT_ARM` [m]
behind the tool tip T' on the shaft, to the jaw centre J = U + BENT_ARM R Rx(b0)
Ry(b1) z, with R the tool frame from the encoders and (b0, b1) the measured bend
(``ToolState.bend``). The loop's plane is orthogonal to the arm, ``height`` from U.
A full turn clears both of the other tool's segments (O'->U and the arm) only when
the arm's end lies inside the cone that this tool's shaft sweeps from its RCM point O
over the loop, i.e. when the arm points towards O: the loop plane then separates the
arm's end (on O's side) from U and the other shaft (on the far side), and the shafts
never cross; ``shaft_clearance`` checks it on the planned path.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import RoleRef
from suture_engine.language.units import Angle, Length, Speed

__all__ = ["BENT_ARM", "BENT_JAW_END", "Wrap", "WrapParams", "bent_arm", "segment_gap"]

BENT_ARM = 12e-3
"""Distance from the bent-tip grasper's universal joint to its jaw centre [m]; the joint
sits this far behind the tool tip that the robot's kinematics reports (the tool's
declared geometry)."""
BENT_JAW_END = 16e-3
"""Distance from the universal joint to the end of the bent jaws [m] (jaw centre plus
half the 8 mm jaw)."""


def bent_arm(q: Any, base: Any, bend: Any) -> tuple[Any, Any]:
    """The bent arm of a bent-tip grasper: universal joint U [m] and unit direction a.

    Args:
        q: the robot's encoder joints [rad, rad, rad, m].
        base: its base pose (position [m], row-major rotation), or None for the world.
        bend: the measured universal joint angles (about x, then the turned y) [rad].

    Returns:
        (U, a), world frame: U = T' - BENT_ARM z_tool, a = R_tool Rx(b0) Ry(b1) e_z.
    """
    import numpy as np

    from skills.tool_path import tip_world
    from suture_engine.robot.kinematics import rotation

    rot = np.asarray(rotation(q), dtype=float)
    if base is not None:
        rot = np.asarray(base[1], dtype=float).reshape(3, 3) @ rot
    b0, b1 = float(bend[0]), float(bend[1])
    c0, s0, c1, s1 = math.cos(b0), math.sin(b0), math.cos(b1), math.sin(b1)
    # Rx(b0) Ry(b1) e_z = Rx(b0) (sin b1, 0, cos b1)
    local = np.array([s1, -s0 * c1, c0 * c1])
    joint = tip_world(q, base) - BENT_ARM * rot[:, 2]
    return joint, rot @ local


def segment_gap(p1: Any, q1: Any, p2: Any, q2: Any) -> float:
    """Smallest distance [m] between the segments p1-q1 and p2-q2 [m]
    (:func:`suture_engine.robot.registration.segment_closest`)."""
    from suture_engine.robot.registration import segment_closest

    return segment_closest(p1, q1, p2, q2).distance


class WrapParams(SkillParams):
    """Parameters of ``wrap``."""

    robot: RoleRef
    """The role of the robot that carries the suture around."""
    around: RoleRef
    """The role of the robot whose tool the loop goes around."""
    around_segment: Literal["shaft", "tip"] = "shaft"
    """What the loop goes around: ``shaft``, the other tool's shaft O'->T';
    ``tip``, a bent-tip grasper's bent arm from its universal joint to its jaws
    (algorithm 3), from its encoders and measured bend."""
    height: Length | None = Field(default=None, gt=0.0, le=0.05)
    """Distance of the loop's plane along the segment [m]: up the shaft from T'
    (``shaft``, default :attr:`Wrap.HEIGHT`) or along the arm from the universal
    joint (``tip``, default :attr:`Wrap.ARM_HEIGHT`)."""
    direction: Literal["front-to-back", "back-to-front"] = "front-to-back"
    """Direction of the loop; a mirrored knot uses ``back-to-front``."""
    turns: int = Field(default=1, ge=1, le=3)
    """Number of loops (2 for the first throw of a surgeon's knot)."""
    radius: Length = Field(default=8e-3, gt=0.0, le=0.05)
    """Radius of the loop around the other tool [m]."""
    sweep: Angle | None = Field(default=None, gt=0.0, le=6.0 * math.pi)
    """Angle swept about the other shaft [rad]; ``None``: pi (2 turns - 1), the half
    turn over the hook that the needle pass completes (algorithm 2). Beyond pi the tip
    passes the far side of the other shaft, where this tool's shaft crosses it (on
    pybullet-surgical a full turn at 10 mm up and 12 mm out shoved the other tool)."""
    speed: Speed = Field(default=0.01, gt=0.0, le=0.2)
    """Tool-tip speed [m/s]."""
    shaft_clearance: Length | None = Field(default=None, gt=0.0, le=0.05)
    """When set, the smallest allowed distance between the two tools' shaft axes
    (each the segment from the RCM point to the tool tip) along the planned path
    [m]; two 5 mm shafts touch at 5 mm. The skill then fails before moving when the
    path would cross the other shaft (a full turn about a straight shaft does:
    algorithm 3 needs the bent arm, 4.4.3). ``None``: not checked."""
    tolerance: Length | None = Field(default=None, gt=0.0, le=5e-3)
    """Tip position tolerance at the goal [m]; ``None`` uses the skill's
    :attr:`TOLERANCE`. A looser one suits a backend whose position control leaves
    a steady error (e.g. heavier mounted tools)."""


class Wrap(Skill):
    """Carry the suture over the other tool in ``direction`` (see the module docstring).

    Three phases, each a rest-to-rest minimum-jerk path through the inverse
    kinematics: the two straight legs of the approach to the arc's start, via the
    waypoint over the other tool (peak tip speed ``speed``, at least
    :attr:`APPROACH_SPEED`), then at peak tip speed ``speed`` the arc of
    pi (2 turns - 1) [rad] about the other shaft. The roll is kept. Fails when a
    path leaves the joint limits, when the carrying robot is the one wrapped
    around or the shafts are aligned, when (with ``shaft_clearance``) the path
    brings the two shafts closer than that, or when the tip is not within
    :attr:`TOLERANCE` [m] of the arc's end :attr:`SETTLE_S` [s] after the path.
    """

    name: ClassVar[str] = "wrap"
    Params: ClassVar[type[SkillParams]] = WrapParams
    tools: ClassVar[tuple[str, ...] | None] = (
        "stitcher",
        "grasper",
        "hook-grasper",
        "bent-tip-grasper",
    )

    HEIGHT: ClassVar[float] = 0.01
    """Height of the loop's plane up the other tool's shaft from its tip [m]."""
    ARM_HEIGHT: ClassVar[float] = 6e-3
    """Distance of the loop's plane along the bent arm from the universal joint [m]."""
    APPROACH_SPEED: ClassVar[float] = 0.02
    """Smallest peak tip speed of the free-space approach to the arc [m/s]."""
    TOLERANCE: ClassVar[float] = 1e-3
    """Tip position tolerance at the end [m]."""
    SETTLE_S: ClassVar[float] = 1.0
    """Time after the path to reach the tolerance [s]."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._base: Any = None
        self._paths: list[Any] = []
        self._failure = ""
        self._t0 = 0.0
        self._goal: Any = None
        self.centre: Any = None
        self.axis: Any = None
        self.sign = 1.0
        self._e1: Any = None
        self._e2: Any = None
        self.segments: list[tuple[Any, Any]] = []
        """The other tool's segments the clearance is checked against [m]."""
        self.shaft_gap = float("inf")
        """Smallest distance between the two shaft axes on the planned paths [m]
        (computed when ``shaft_clearance`` is set)."""

    def loop_point(self, s: float) -> Any:
        """Tip position on the loop [m] at fraction ``s`` of it."""
        import math

        p = self.params
        assert isinstance(p, WrapParams)
        phi = self.sign * (0.5 * math.pi - self.sweep * s)
        return self.centre + p.radius * (math.cos(phi) * self._e1 + math.sin(phi) * self._e2)

    @property
    def sweep(self) -> float:
        """Angle swept about the other shaft, pi (2 turns - 1) [rad]."""
        import math

        p = self.params
        assert isinstance(p, WrapParams)
        if p.sweep is not None:
            return float(p.sweep)
        return math.pi * (2 * p.turns - 1)

    def _segment(self, a: Any, b: Any, roll: float) -> Any:
        """``s -> q``: joints along the straight tip segment from ``a`` to ``b`` [m]."""
        from skills.tool_path import ik_world

        def joints_at(s: float) -> Any:
            return ik_world(a + s * (b - a), roll, self._base)

        return joints_at

    def start(self, ctx: Any) -> None:
        """Locate the other tool's shaft and plan the approach and the loop.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """

        import itertools

        import numpy as np

        from skills.tool_path import ToolPath, duration_for, ik_world, joint_box, tip_world

        p = self.params
        assert isinstance(p, WrapParams)
        self._robot = ctx.robot(p.robot)
        other = ctx.robot(p.around)
        self._base = ctx.base_poses.get(self._robot)
        self._t0 = ctx.t0
        self._failure = ""
        failure = ""
        self.sign = 1.0 if p.direction == "front-to-back" else -1.0
        q0 = np.array(ctx.start.robots[self._robot].q)
        roll = float(q0[2])
        other_base = ctx.base_poses.get(other)
        o2 = np.zeros(3) if other_base is None else np.asarray(other_base[0], dtype=float)
        other_obs = ctx.start.robots[other]
        t2 = tip_world(other_obs.q, other_base)
        # the other tool as segments (for the clearance) and the loop's axis and centre
        if p.around_segment == "tip":
            if other_obs.tool.kind != "bent-tip-grasper":
                failure = f"tool {other_obs.tool.kind!r} has no bent arm to wrap around"
            joint, arm = bent_arm(other_obs.q, other_base, other_obs.tool.bend)
            self.segments = [(o2, joint), (joint, joint + BENT_JAW_END * arm)]
            self.axis = arm
            height = self.ARM_HEIGHT if p.height is None else p.height
            self.centre = joint + height * self.axis
        else:
            self.segments = [(o2, t2)]
            axis = o2 - t2
            self.axis = axis / np.linalg.norm(axis)
            height = self.HEIGHT if p.height is None else p.height
            self.centre = t2 + height * self.axis
        tip = tip_world(q0, self._base)
        own = np.zeros(3) if self._base is None else np.asarray(self._base[0], dtype=float)
        over = own - self.centre
        over = over - (over @ self.axis) * self.axis
        if float(np.linalg.norm(over)) < 1e-9:
            failure = failure or (
                "the two shafts are aligned: no side is over the other tool"
                if p.around_segment == "shaft"
                else "the bent arm points at this robot's RCM point: no side is over it"
            )
            over = np.cross(self.axis, (1.0, 0.0, 0.0))
        self._e1 = over / np.linalg.norm(over)
        self._e2 = np.cross(self.axis, self._e1)
        # approach through a waypoint over the other tool (2 radii towards O), so the
        # straight legs stay on this robot's side of the other shaft; each leg is
        # rest-to-rest, so the tip does not turn the corner at speed (an impulsive
        # acceleration the base force sensor reads as a tension spike)
        legs = [tip, self.centre + 2.0 * p.radius * self._e1, self.loop_point(0.0)]
        approach_speed = max(p.speed, self.APPROACH_SPEED)
        self._paths = []
        for a, b in itertools.pairwise(legs):
            length = float(np.linalg.norm(b - a))
            if length < 1e-6:
                continue
            self._paths.append(
                ToolPath(self._segment(a, b, roll), duration_for(length, approach_speed))
            )
        loop = ToolPath(
            lambda s: ik_world(self.loop_point(s), roll, self._base),
            duration_for(self.sweep * p.radius, p.speed),
        )
        self._paths.append(loop)
        self._goal = self.loop_point(1.0)
        if self._robot == other:
            self._failure = "a tool cannot wrap around itself"
        self._failure = self._failure or failure
        box = joint_box(ctx, self._robot)
        for path in self._paths:
            self._failure = self._failure or path.first_violation(box)
        if p.shaft_clearance is not None:
            self.shaft_gap = self._shaft_gap(own)
        if p.shaft_clearance is not None and self.shaft_gap < p.shaft_clearance:
            self._failure = self._failure or (
                f"the shafts come {self.shaft_gap * 1e3:.2f} mm apart on the loop (needs "
                f"{p.shaft_clearance * 1e3:.2f} mm): the tool would cross the other "
                + ("shaft" if p.around_segment == "shaft" else "tool's shaft or bent arm")
            )

    def _shaft_gap(self, own: Any) -> float:
        """Smallest distance [m] between this tool's shaft axis and the other tool's
        segments (its shaft, and with ``tip`` its bent arm) along the planned paths."""
        from skills.tool_path import tip_world

        gap = float("inf")
        for path in self._paths:
            for q in path.table:
                tip = tip_world(q, self._base)
                for a, b in self.segments:
                    gap = min(gap, segment_gap(own, tip, a, b))
        return gap

    def step(self, ctx: Any, obs: Any) -> Any:
        """Track the approach then the arc; success at the arc's end.

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
        *approach, loop = self._paths
        for leg in approach:
            if t < leg.duration:
                q, qd, _ = leg.sample(t)
                return StepResult(Command({self._robot: RobotCommand.position(q, qd)}))
            t -= leg.duration
        t_loop = t
        q, qd, done = loop.sample(t_loop)
        cmd = Command({self._robot: RobotCommand.position(q, qd)})
        if not done:
            return StepResult(cmd)
        err = float(np.linalg.norm(tip_world(obs.robots[self._robot].q, self._base) - self._goal))
        if err <= tip_tolerance(self.params, self.TOLERANCE):
            return StepResult(cmd, SkillStatus.SUCCESS)
        if t_loop >= loop.duration + self.SETTLE_S:
            return StepResult(cmd, SkillStatus.FAILURE, f"tool tip {err * 1e3:.2f} mm off the loop")
        return StepResult(cmd)
