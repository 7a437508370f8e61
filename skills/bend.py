"""``bend``: turn the bent-tip grasper's universal joint (algorithm 3, 4.4.3).

The grasper of algorithm 3 carries "an additional universal joint" behind its jaws,
so that the needle holder wraps the suture around the bent arm and the loop does not
slip off. The joint has two axes: the jaws turn by ``angles[0]`` about the shaft's x
(the outer axis), then by ``angles[1]`` about the turned y (the inner axis), i.e. the
jaw frame is Rx(a0) Ry(a1) in the shaft frame. Its encoders report the angles in the
tool state (:attr:`suture_engine.runtime.observation.ToolState.bend`).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, ClassVar

from pydantic import Field, field_validator

from skills.base import Skill, SkillParams
from suture_engine.language.refs import RoleRef
from suture_engine.language.units import Angle, Duration, Unit

__all__ = ["Bend", "BendParams"]

MAX_BEND = math.radians(120.0)
"""Largest angle of either universal joint axis [rad]."""


class BendParams(SkillParams):
    """Parameters of ``bend``."""

    robot: RoleRef
    """The role of the robot carrying the bent-tip grasper."""
    angles: Annotated[tuple[float, float], Unit("rad")]
    """The universal joint's goal: about the shaft's x, then about the turned y [rad];
    (0, 0) straightens the jaws."""
    travel: Duration | None = Field(default=None, gt=0.0, le=10.0)
    """Time of the joint's move [s]; ``None``: at :attr:`Bend.RATE`."""
    tolerance: Angle = Field(default=math.radians(1.0), gt=0.0, le=math.radians(10.0))
    """Largest error of either axis at the goal [rad]."""

    @field_validator("angles")
    @classmethod
    def _in_range(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not all(math.isfinite(a) and abs(a) <= MAX_BEND for a in value):
            raise ValueError(
                f"each bend angle must be within +-{math.degrees(MAX_BEND):g} deg, got "
                f"{[round(math.degrees(a), 3) for a in value]} deg"
            )
        return value


class Bend(Skill):
    """Move the universal joint to ``angles`` [rad] while the robot holds its pose.

    The setpoint ramps linearly from the measured bend to the goal in ``travel`` [s]
    (or at :attr:`RATE` [rad/s] on the axis that moves most). Success once both
    measured angles are within ``tolerance`` of the goal; failure when the tool has no
    universal joint or the goal is not reached :attr:`SETTLE_S` [s] after the ramp.
    """

    name: ClassVar[str] = "bend"
    Params: ClassVar[type[SkillParams]] = BendParams
    tools: ClassVar[tuple[str, ...] | None] = ("bent-tip-grasper",)

    RATE: ClassVar[float] = 1.0
    """Setpoint speed of the axis that moves most, when ``travel`` is not given [rad/s]."""
    SETTLE_S: ClassVar[float] = 0.5
    """Time after the ramp to reach the tolerance [s]."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._q: Any = None
        self._t0 = 0.0
        self._from = (0.0, 0.0)
        self._goal = (0.0, 0.0)
        self._kind = ""
        self.ramp = 0.0
        """Duration of the setpoint's ramp [s]."""

    def start(self, ctx: Any) -> None:
        """Capture the pose and the measured bend [rad].

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        p = self.params
        assert isinstance(p, BendParams)
        self._robot = ctx.robot(p.robot)
        robot = ctx.start.robots[self._robot]
        self._q = robot.q
        self._kind = robot.tool.kind
        self._from = (float(robot.tool.bend[0]), float(robot.tool.bend[1]))
        self._goal = (float(p.angles[0]), float(p.angles[1]))
        span = max(abs(g - f) for g, f in zip(self._goal, self._from, strict=True))
        self.ramp = float(p.travel) if p.travel is not None else span / self.RATE
        self._t0 = ctx.t0

    def setpoint(self, t: float) -> tuple[float, float]:
        """The joint setpoint [rad, rad] at ``t`` [s] after the start."""
        frac = 1.0 if self.ramp <= 0.0 else min(max(t / self.ramp, 0.0), 1.0)
        return (
            self._from[0] + frac * (self._goal[0] - self._from[0]),
            self._from[1] + frac * (self._goal[1] - self._from[1]),
        )

    def step(self, ctx: Any, obs: Any) -> Any:
        """Ramp the joint; success when the measured bend reaches the goal.

        Args:
            ctx: the skill context.
            obs: this tick's observation.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        from skills.tool_path import hold_command
        from suture_engine.runtime.observation import SkillStatus, StepResult, ToolCommand

        p = self.params
        assert isinstance(p, BendParams)
        t = obs.t - self._t0
        cmd = hold_command(self._robot, self._q, ToolCommand(bend=self.setpoint(t)))
        if self._kind != "bent-tip-grasper":
            return StepResult(
                cmd, SkillStatus.FAILURE, f"tool {self._kind!r} has no universal joint"
            )
        measured = obs.robots[self._robot].tool.bend
        err = max(abs(float(m) - g) for m, g in zip(measured, self._goal, strict=True))
        if err <= p.tolerance:
            # the last setpoint is the goal itself: the joint settles there afterwards
            done = hold_command(self._robot, self._q, ToolCommand(bend=self._goal))
            return StepResult(done, SkillStatus.SUCCESS)
        if t >= self.ramp + self.SETTLE_S:
            return StepResult(
                cmd,
                SkillStatus.FAILURE,
                "bend at [{:.1f}, {:.1f}] deg, goal [{:.1f}, {:.1f}] deg".format(
                    *(math.degrees(float(a)) for a in (*measured, *self._goal))
                ),
            )
        return StepResult(cmd)
