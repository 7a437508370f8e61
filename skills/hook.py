"""``hook``: extend or retract the flexible hook over the grasper hinge (4.4.2)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import RoleRef
from suture_engine.language.units import Length

__all__ = ["Hook", "HookParams"]


class HookParams(SkillParams):
    """Parameters of ``hook``."""

    robot: RoleRef
    """The role of the robot carrying the hook grasper."""
    action: Literal["extend", "retract"]
    """Extend the hook (to snare the suture) or retract it (algorithm 2 steps 2, 4)."""
    travel: Length = Field(default=5e-3, gt=0.0, le=0.02)
    """Stroke of the reciprocating actuator [m]."""


class Hook(Skill):
    """Extend the flexible hook to ``travel`` [m] or retract it to 0 (algorithm 2 steps 2, 4).

    The extension setpoint ramps at :attr:`RATE` [m/s] from the measured
    extension while the robot holds its pose. Success once the measured
    extension is within :attr:`TOLERANCE` [m] of the goal; failure when the
    tool is not a hook grasper or the goal is not reached :attr:`SETTLE_S` [s]
    after the ramp.
    """

    name: ClassVar[str] = "hook"
    Params: ClassVar[type[SkillParams]] = HookParams
    tools: ClassVar[tuple[str, ...] | None] = ("hook-grasper",)

    RATE: ClassVar[float] = 0.01
    """Hook actuator speed [m/s]."""
    TOLERANCE: ClassVar[float] = 2e-4
    """Extension tolerance [m]."""
    SETTLE_S: ClassVar[float] = 0.5
    """Time after the ramp to reach the tolerance [s]."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._q: Any = None
        self._t0 = 0.0
        self._from = 0.0
        self._goal = 0.0
        self._kind = ""

    def start(self, ctx: Any) -> None:
        """Capture the pose and the measured extension [m].

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        p = self.params
        assert isinstance(p, HookParams)
        self._robot = ctx.robot(p.robot)
        robot = ctx.start.robots[self._robot]
        self._q = robot.q
        self._kind = robot.tool.kind
        self._from = float(robot.tool.hook_extension)
        self._goal = p.travel if p.action == "extend" else 0.0
        self._t0 = ctx.t0

    def setpoint(self, t: float) -> float:
        """Extension setpoint [m] at ``t`` [s] after the start."""
        span = self._goal - self._from
        if span == 0.0:
            return self._goal
        frac = min(max(t * self.RATE / abs(span), 0.0), 1.0)
        return self._from + frac * span

    def step(self, ctx: Any, obs: Any) -> Any:
        """Ramp the hook; success when the measured extension reaches the goal.

        Args:
            ctx: the skill context.
            obs: this tick's observation.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        from skills.tool_path import hold_command
        from suture_engine.runtime.observation import SkillStatus, StepResult, ToolCommand

        t = obs.t - self._t0
        cmd = hold_command(self._robot, self._q, ToolCommand(hook_extension=self.setpoint(t)))
        if self._kind != "hook-grasper":
            return StepResult(cmd, SkillStatus.FAILURE, f"tool {self._kind!r} has no hook")
        measured = float(obs.robots[self._robot].tool.hook_extension)
        if abs(measured - self._goal) <= self.TOLERANCE:
            return StepResult(cmd, SkillStatus.SUCCESS)
        ramp = abs(self._goal - self._from) / self.RATE
        if t >= ramp + self.SETTLE_S:
            return StepResult(
                cmd,
                SkillStatus.FAILURE,
                f"hook at {measured * 1e3:.2f} mm, goal {self._goal * 1e3:.2f} mm",
            )
        return StepResult(cmd)
