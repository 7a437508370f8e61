"""``move-to``: move a robot's tool tip to a point, in free space."""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING, Any, ClassVar

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Angle, Force, Length, Position, Speed

if TYPE_CHECKING:
    from suture_engine.validation.problem import Problem

__all__ = [
    "ARM_VERTICAL_DEG",
    "NOT_TAUT",
    "SLACK_AT_START",
    "TAUT_EARLY",
    "MoveTo",
    "MoveToParams",
    "arm_frame",
]

TAUT_EARLY = "taut-early"
"""Failure event: the strand went taut (``until_tension``) before ``taut_after``."""
NOT_TAUT = "not-taut"
"""Failure event: the strand was not taut within ``taut_within`` of travel."""
SLACK_AT_START = "slack-at-start"
"""Failure event: the strand did not already pull with ``held_at_start`` as the move began."""


@functools.cache
def _step_imports() -> tuple[Any, ...]:
    """The names step() uses, imported once (lazily: validation never imports numpy)."""
    import numpy as np

    from suture_engine.runtime.observation import Command, RobotCommand, SkillStatus, StepResult
    from suture_engine.runtime.trajectory import tool_tip_world

    return np, Command, RobotCommand, SkillStatus, StepResult, tool_tip_world


class MoveToParams(SkillParams):
    """Parameters of ``move-to``."""

    robot: RoleRef
    """The role of the robot that moves."""
    target: PointRef | Position
    """Where the tool tip goes: a named tissue point of the scene, or (x, y, z) in
    the world frame [m]."""
    relative_to: RoleRef | None = None
    """When set, ``target`` is an (x, y, z) offset [m] in the world frame from that
    role's tool tip (e.g. "touch the front of the grasper stem", algorithm 1 step 3);
    such targets are not checked for reachability before running."""
    offset: Position = (0.0, 0.0, 0.0)
    """Added to the target, in the world frame [m] (e.g. to stop above the tissue)."""
    along_arm_of: RoleRef | None = None
    """With ``relative_to``: ``target`` and ``offset`` are (along, across, up) [m] in the
    frame of this role's arm as the step starts (:func:`arm_frame`): along its distal
    segment towards the tool's end (a bent-tip grasper's bent arm from its encoders and
    measured bend, else the shaft), up as near the world's up as is orthogonal to it,
    and across completing a right-handed frame. A move laid out along a tool then stays
    along it however the tool was turned or its base is off. ``None``: world axes."""
    roll: Angle | None = None
    """Tool roll q3 at the target [rad] (3.17); ``None`` keeps the current roll."""
    roll_tolerance: Angle | None = Field(default=None, gt=0.0, le=math.radians(30.0))
    """The roll error [rad] still accepted once the settling time is over (a roll joint
    with more friction than its compensation knows ends a long roll short of its goal).
    The move first waits, as without it, for the roll to come within
    :attr:`MoveTo.ROLL_TOLERANCE` (3 deg). ``None``: no more than that."""
    speed: Speed = Field(default=0.01, gt=0.0, le=0.2)
    """Cruise speed of the tool tip [m/s]."""
    tolerance: Length = Field(default=0.5e-3, gt=0.0)
    """Arrival tolerance of the tool-tip position [m]."""
    until_tension: Force | None = Field(default=None, gt=0.0)
    """A guarded move [N]: stop, done, as soon as the suture tension estimated from the
    base force/torque sensor along the direction of motion (7.6-7.10, tared on the
    step's first tick) reaches this value; the target is then only the furthest the tip
    may go. Reaching the target without the tension is a failure (nothing was taken
    up). Used to take up a slack strand before it is wrapped or pulled."""
    taut_within: Length | None = Field(default=None, gt=0.0)
    """With ``until_tension``: how far the tip may travel along the move [m] (from the
    measured joints, from where the step started) before the guard must be met. Past it
    the move stops where it is and fails: the strand did not go taut where it should
    have (a loop that slipped off a tool takes up much later). ``None``: the whole move."""
    taut_after: Length | None = Field(default=None, gt=0.0)
    """With ``until_tension``: how far the tip must have travelled along the move [m]
    (measured as for ``taut_within``) before the guard may be met. Met earlier, the move
    stops there and fails: the strand was already held by something else (with
    ``taut_within``, a window on where the strand goes taut). ``None``: from the start."""
    free_of: RoleRef | None = None
    """With ``until_tension``: a role whose tool the strand must not be anchored on. When
    the guard is met, that robot's own base-sensor estimate of the pull towards this
    robot's tool (along the line from this tool tip to that one at the step's start,
    tared there) must be at most ``free_share`` times this robot's; more, and the move
    stops there and fails: the strand drawn taut ends on that tool (a loop still round
    it), not beyond it. ``None``: no such check."""
    free_share: float = Field(default=0.3, gt=0.0, le=1.0)
    """With ``free_of``: the largest share of this robot's estimated tension that the
    other robot may take when the guard is met [-]."""
    held_at_start: Force | None = Field(default=None, gt=0.0)
    """The strand must already pull on this robot's tool with at least this force as the
    move begins [N]: the run's own tension estimate (the base sensor's force against its
    reading at the run's rest, ``|f|`` of 7.6-7.9; not the step's tare), averaged over the
    step's first 50 ms (``MoveTo.HELD_WINDOW_S``). Less, and the move stops there and fails
    (``slack-at-start``): nothing held by this tool is drawn against the knot. ``None``:
    no such check."""


class MoveTo(Skill):
    """Move the tool tip to ``target + offset`` at ``speed`` [m/s].

    The goal joints come from the closed-form inverse kinematics (3.14-3.17) of
    the goal expressed in the robot's base frame; the joints follow a
    rest-to-rest minimum-jerk (quintic) trajectory whose duration makes the
    straight-line peak tool speed ``speed``. The skill succeeds once the
    trajectory is over and the measured tool tip is within ``tolerance`` [m] of
    the goal, and fails if it is not there ``SETTLE_S`` [s] later (with a roll, also
    ``ROLL_SETTLE_S``).

    A guarded move's window fails with a named event that a state may route on its own
    (:attr:`events`): ``taut-early`` when the strand goes taut before ``taut_after``,
    ``not-taut`` when it is not taut within ``taut_within``; ``held_at_start`` fails with
    ``slack-at-start`` when the strand does not already pull on the tool as it begins.
    """

    name: ClassVar[str] = "move-to"
    Params: ClassVar[type[SkillParams]] = MoveToParams
    events: ClassVar[tuple[str, ...]] = (TAUT_EARLY, NOT_TAUT, SLACK_AT_START)

    SETTLE_S: ClassVar[float] = 1.0
    """Time allowed after the trajectory's end to reach the tolerance [s]."""
    ROLL_SPEED: ClassVar[float] = 1.0
    """Peak roll rate of the tool [rad/s]: a 180 deg roll takes 5.9 s."""
    ROLL_TOLERANCE: ClassVar[float] = math.radians(3.0)
    """Arrival tolerance of the roll when the move sets one [rad]."""
    HELD_WINDOW_S: ClassVar[float] = 0.05
    """How long ``held_at_start`` averages the base sensor's force from the step's start
    [s]: 50 samples at 1 kHz take the scene's 0.02 N sensor noise to about 0.003 N, while a
    minimum-jerk start moves the tip by micrometres."""
    ROLL_SETTLE_S: ClassVar[float] = 1.0
    """Extra settling time when the move sets a roll [s]: on the surgical scene the roll
    joint of the grasper (its tool loaded by the held thread) ends a 180 deg roll ~4 deg
    behind and closes the last degree ~1.2 s after the trajectory."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._traj: Any = None
        self._goal: Any = None
        self._base: Any = None
        self._t0 = 0.0
        self._est: Any = None
        self._tip0: Any = None
        self._unit: Any = None
        self._other = ""
        self._other_est: Any = None
        self._rest_force: Any = None
        self._held: list[Any] = []

    @classmethod
    def check(cls, params: SkillParams, scene: Any) -> list[Problem]:
        """``taut_within`` and ``taut_after`` need the guard (``until_tension``) they
        bound, and ``taut_after`` must lie below ``taut_within``."""
        from suture_engine.validation.problem import Problem

        assert isinstance(params, MoveToParams)
        problems = []
        for name in ("taut_within", "taut_after"):
            if getattr(params, name) is not None and params.until_tension is None:
                problems.append(
                    Problem(
                        name.replace("_", "-") + "-without-guard",
                        f"{name} bounds where a guarded move's tension must be met: "
                        "give until_tension too",
                        path=name,
                    )
                )
        if params.along_arm_of is not None and params.relative_to is None:
            problems.append(
                Problem(
                    "along-arm-without-relative-to",
                    "along_arm_of gives the axes of an offset from a tool tip: give "
                    "relative_to too",
                    path="along_arm_of",
                )
            )
        if params.along_arm_of is not None and isinstance(params.target, str):
            problems.append(
                Problem(
                    "along-arm-with-a-point",
                    f"along_arm_of needs target as an (along, across, up) offset, not the "
                    f"tissue point {params.target!r}",
                    path="target",
                )
            )
        if params.free_of is not None and params.until_tension is None:
            problems.append(
                Problem(
                    "free-of-without-guard",
                    "free_of is checked when a guarded move's tension is met: "
                    "give until_tension too",
                    path="free_of",
                )
            )
        if params.free_of is not None and params.free_of == params.robot:
            problems.append(
                Problem(
                    "free-of-self",
                    f"free_of must name the other robot's role, not the moving one "
                    f"({params.robot!r})",
                    path="free_of",
                )
            )
        within, after = params.taut_within, params.taut_after
        if within is not None and after is not None and not after < within:
            problems.append(
                Problem(
                    "taut-window-empty",
                    f"taut_after ({after * 1e3:g} mm) must be less than taut_within "
                    f"({within * 1e3:g} mm): no travel could meet both",
                    path="taut_after",
                )
            )
        return problems

    def _target_world(self, ctx: Any) -> tuple[float, float, float]:
        from suture_engine.runtime.trajectory import tool_tip_world

        p = self.params
        assert isinstance(p, MoveToParams)
        if isinstance(p.target, str):
            points = ctx.scene.tissue.points if ctx.scene is not None else {}
            if p.target not in points:
                raise KeyError(f"no tissue point named {p.target!r}; known: {sorted(points)}")
            base = points[p.target]
        else:
            base = p.target
        offset = p.offset
        if p.along_arm_of is not None:
            import numpy as np

            arm = ctx.robot(p.along_arm_of)
            start = ctx.start.robots[arm]
            axes = arm_frame(start.q, ctx.base_poses.get(arm), start.tool.bend)
            b, o = axes @ np.asarray(base, dtype=float), axes @ np.asarray(offset, dtype=float)
            base = (float(b[0]), float(b[1]), float(b[2]))
            offset = (float(o[0]), float(o[1]), float(o[2]))
        if p.relative_to is not None:
            other = ctx.robot(p.relative_to)
            tip = tool_tip_world(ctx.start.robots[other].q, ctx.base_poses.get(other))
            base = tuple(float(tip[i]) + float(base[i]) for i in range(3))
        return (
            float(base[0]) + offset[0],
            float(base[1]) + offset[1],
            float(base[2]) + offset[2],
        )

    def start(self, ctx: Any) -> None:
        """Plan the trajectory from the measured joints to the goal.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.

        Raises:
            UnreachablePose: the goal is at the RCM.
            KeyError: an unknown tissue point or role.
        """
        import numpy as np

        from suture_engine.robot.kinematics import inverse_kinematics
        from suture_engine.runtime.trajectory import (
            MinJerk,
            min_jerk_duration,
            tool_tip_world,
            world_to_base,
        )

        p = self.params
        assert isinstance(p, MoveToParams)
        self._robot = ctx.robot(p.robot)
        self._base = ctx.base_poses.get(self._robot)
        q0 = np.array(ctx.start.robots[self._robot].q)
        self._goal = np.array(self._target_world(ctx))
        roll = float(q0[2]) if p.roll is None else float(p.roll)
        q1 = inverse_kinematics(world_to_base(self._goal, self._base), roll)
        distance = float(np.linalg.norm(self._goal - tool_tip_world(q0, self._base)))
        # the roll turns at most ROLL_SPEED at the quintic's peak (a roll-only move too)
        duration = max(
            min_jerk_duration(distance, p.speed, minimum=0.1),
            min_jerk_duration(abs(float(q1[2]) - float(q0[2])), self.ROLL_SPEED, minimum=0.1),
        )
        self._traj = MinJerk(q0, q1, duration)
        self._t0 = ctx.t0
        self._est = None
        self._tip0 = self._unit = None
        self._rest_force, self._held = None, []
        if p.held_at_start is not None:
            if ctx.rest is None or self._robot not in ctx.rest.robots:
                raise ValueError("held_at_start needs the run's rest observation (its tare)")
            self._rest_force = np.array(ctx.rest.robots[self._robot].base_wrench[:3], float)
        if p.until_tension is not None and distance > 0.0:
            tip0 = tool_tip_world(q0, self._base)
            motion = self._goal - tip0
            self._est = _guard_estimator(ctx, self._robot, motion)
            if p.free_of is not None:
                # The strand anchored on the other tool pulls it towards this one: that
                # tool "pulls" away from this tip, the estimator's direction.
                self._other = ctx.robot(p.free_of)
                other_q0 = ctx.start.robots[self._other].q
                away = tool_tip_world(other_q0, ctx.base_poses.get(self._other)) - tip0
                self._other_est = _guard_estimator(ctx, self._other, away)
            if p.taut_within is not None or p.taut_after is not None:
                self._tip0 = tip0
                self._unit = motion / distance

    def _held_check(self, obs: Any, sample: Any) -> Any:
        """``held_at_start``: None while the window fills or once the strand was found
        pulling; the failure when it was not."""
        np = _step_imports()[0]
        p = self.params
        assert isinstance(p, MoveToParams) and p.held_at_start is not None
        self._held.append(np.array(obs.robots[self._robot].base_wrench[:3], float))
        if obs.t - self._t0 < self.HELD_WINDOW_S:
            return None
        pull = float(np.linalg.norm(self._rest_force - np.mean(self._held, axis=0)))
        self._rest_force, self._held = None, []
        if pull >= p.held_at_start:
            return None
        return self._stopped(
            sample,
            f"the strand pulls on {p.robot}'s tool with {pull:.3f} N as the move begins, "
            f"under {p.held_at_start:.2f} N: nothing it holds is drawn against the knot",
            SLACK_AT_START,
        )

    def _stopped(self, sample: Any, message: str, event: str) -> Any:
        """A failure that holds the tool where the trajectory is now, at rest."""
        _, Command, RobotCommand, SkillStatus, StepResult, _ = _step_imports()
        hold = Command({self._robot: RobotCommand.trusted_position(sample.q, None)})
        return StepResult(hold, SkillStatus.FAILURE, message, event)

    def step(self, ctx: Any, obs: Any) -> Any:
        """Track the trajectory; report success at the goal, failure if it is not reached.

        Args:
            ctx: the skill context.
            obs: this tick's :class:`suture_engine.runtime.observation.Observation`.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        np, Command, RobotCommand, SkillStatus, StepResult, tool_tip_world = _step_imports()
        p = self.params
        assert isinstance(p, MoveToParams)
        t = obs.t - self._t0
        sample = self._traj(t)
        # The sample's arrays are fresh (MinJerk computes new ones per call): handed over.
        command = Command({self._robot: RobotCommand.trusted_position(sample.q, sample.qd)})
        if self._rest_force is not None:
            held = self._held_check(obs, sample)
            if held is not None:
                return held
        if self._est is not None:
            ro = obs.robots[self._robot]
            tension = self._est.update(ro.base_wrench, ro.q).tension
            assert p.until_tension is not None
            other_tension = math.nan
            if self._other_est is not None:  # updated every tick: its filter runs on
                oo = obs.robots[self._other]
                other_tension = self._other_est.update(oo.base_wrench, oo.q).tension
            travel = math.nan
            if self._unit is not None:
                tip = tool_tip_world(ro.q, self._base)
                travel = float((tip - self._tip0) @ self._unit)
            if tension >= p.until_tension:
                # stop where the strand became taut: the trajectory's point now, at rest
                hold = Command({self._robot: RobotCommand.trusted_position(sample.q, None)})
                if p.taut_after is not None and travel < p.taut_after:
                    return StepResult(
                        hold,
                        SkillStatus.FAILURE,
                        f"tension {p.until_tension:.2f} N reached after only {travel * 1e3:.1f} "
                        f"mm of travel (not before {p.taut_after * 1e3:.2f} mm)",
                        TAUT_EARLY,
                    )
                if self._other_est is not None and other_tension > p.free_share * tension:
                    return StepResult(
                        hold,
                        SkillStatus.FAILURE,
                        f"tension {tension:.2f} N reached with {other_tension:.2f} N of it on "
                        f"{p.free_of}'s tool (more than {p.free_share:.2f} of it): the strand "
                        "is anchored there",
                    )
                return StepResult(hold, SkillStatus.SUCCESS)
            if p.taut_within is not None and travel > p.taut_within:
                return self._stopped(
                    sample,
                    f"tension {p.until_tension:.2f} N not reached within "
                    f"{p.taut_within * 1e3:.1f} mm of travel",
                    NOT_TAUT,
                )
        if not sample.done:
            return StepResult(command)
        tip = tool_tip_world(obs.robots[self._robot].q, self._base)
        error = float(np.linalg.norm(tip - self._goal))
        if self._est is not None:
            if error <= p.tolerance or t >= self._traj.duration + self.SETTLE_S:
                return StepResult(
                    command,
                    SkillStatus.FAILURE,
                    f"tension {p.until_tension:.2f} N not reached before the end of the move",
                )
            return StepResult(command)
        roll_error = 0.0 if p.roll is None else abs(float(obs.robots[self._robot].q[2]) - p.roll)
        if error <= p.tolerance and roll_error <= self.ROLL_TOLERANCE:
            return StepResult(command, SkillStatus.SUCCESS)
        settle = self.SETTLE_S + (0.0 if p.roll is None else self.ROLL_SETTLE_S)
        if t >= self._traj.duration + settle:
            late = p.roll_tolerance
            if late is not None and error <= p.tolerance and roll_error <= late:
                return StepResult(command, SkillStatus.SUCCESS)
            return StepResult(
                command,
                SkillStatus.FAILURE,
                f"tool tip {error * 1e3:.2f} mm from the goal "
                f"(tolerance {p.tolerance * 1e3:.2f} mm), roll "
                f"{math.degrees(roll_error):.1f} deg off",
            )
        return StepResult(command)


ARM_VERTICAL_DEG = 5.0
""":func:`arm_frame` refuses an arm within this angle of vertical [deg]."""


def arm_frame(q: Any, base: Any, bend: Any) -> Any:
    """The axes of a tool's arm, as the columns of a rotation matrix (world frame).

    x is the arm's direction towards the tool's end: a bent-tip grasper's bent arm
    R Rx(b0) Ry(b1) e_z (:func:`skills.wrap.bent_arm`), which for a straight tool
    (bend (0, 0)) is the shaft's axis R e_z out of the RCM point. z is the world's up
    e_z with its part along x taken out, normalized; y = z x x.

    Args:
        q: the robot's encoder joints [rad, rad, rad, m].
        base: its base pose (position [m], row-major rotation), or None for the world.
        bend: the measured universal joint angles [rad].

    Returns:
        A 3x3 array [x y z]: world = axes @ (along, across, up).

    Raises:
        ValueError: the arm points within :data:`ARM_VERTICAL_DEG` of straight up or
            down, where "up across the arm" is undefined (a step that starts so fails).
    """
    import numpy as np

    from skills.wrap import bent_arm

    _, x = bent_arm(q, base, bend)
    x = np.asarray(x, dtype=float) / float(np.linalg.norm(x))
    up = np.array([0.0, 0.0, 1.0]) - x[2] * x
    norm = float(np.linalg.norm(up))
    if norm < math.sin(math.radians(ARM_VERTICAL_DEG)):
        raise ValueError(
            f"the arm points {math.degrees(math.acos(min(1.0, abs(float(x[2]))))):.1f} deg "
            f"from vertical (under {ARM_VERTICAL_DEG:g} deg): along_arm_of has no up across it"
        )
    z = up / norm
    return np.column_stack([x, np.cross(z, x), z])


def _guard_estimator(ctx: Any, robot: str, motion_world: Any) -> Any:
    """A tension estimator along the direction of motion, tared on the step's first tick.

    The strand pulled by a move opposes it, so the tension acts on the tip along
    ``-motion``; the estimator's direction is the pulling direction ``motion`` (as in
    ``tension-regulate``).
    """
    from suture_engine.suture.tension import mounted_estimator

    base = ctx.base_poses.get(robot)
    start = ctx.start.robots[robot]
    est, _ = mounted_estimator(
        None if base is None else base[1], motion_world, start.base_wrench, start.q, ctx.dt, 20.0
    )
    return est
