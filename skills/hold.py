"""``hold``: keep a robot at its current pose (the Lock mode's law, thesis 4.44)."""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import RoleRef
from suture_engine.language.units import Duration

__all__ = ["Hold", "HoldParams"]


class HoldParams(SkillParams):
    """Parameters of ``hold``."""

    robot: RoleRef
    """The role of the robot that holds its pose (``stitcher``, ``grasper``)."""
    duration: Duration | None = Field(default=None, ge=0.0)
    """How long to hold [s]; ``None`` holds until the state's next event."""


class Hold(Skill):
    """Hold the current joint positions (4.44) for ``duration`` [s] or until an event."""

    name: ClassVar[str] = "hold"
    Params: ClassVar[type[SkillParams]] = HoldParams

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._q: Any = None
        self._command: Any = None
        self._t0 = 0.0

    def start(self, ctx: Any) -> None:
        """Capture the robot's current joint positions x_cp [rad, m] (4.44).

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        p = self.params
        assert isinstance(p, HoldParams)
        from suture_engine.runtime.observation import Command, RobotCommand

        self._robot = ctx.robot(p.robot)
        self._q = ctx.start.robots[self._robot].q
        self._t0 = ctx.t0
        # The same set point every tick: one frozen command, built once.
        self._command = Command({self._robot: RobotCommand.position(self._q)})

    def step(self, ctx: Any, obs: Any) -> Any:
        """Regulate the captured pose; succeed once ``duration`` [s] has passed.

        Args:
            ctx: the skill context.
            obs: this tick's :class:`suture_engine.runtime.observation.Observation`.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        from suture_engine.runtime.observation import SkillStatus, StepResult

        p = self.params
        assert isinstance(p, HoldParams)
        command = self._command
        if p.duration is not None and obs.t - self._t0 >= p.duration - 0.5 * ctx.dt:
            return StepResult(command, SkillStatus.SUCCESS)
        return StepResult(command)
