"""``release``: open a grasper or a stitcher jaw."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from skills.base import Skill, SkillParams
from suture_engine.language.refs import RoleRef

__all__ = ["Release", "ReleaseParams"]


class ReleaseParams(SkillParams):
    """Parameters of ``release``."""

    robot: RoleRef
    """The role of the robot that releases."""
    what: Literal["suture-tail", "suture", "needle", "tissue", "any"] = "any"
    """What is released."""


class Release(Skill):
    """Open the (first) jaw while holding the pose; success once the tool reports it open.

    A stitcher keeps its second jaw as it is, so the needle stays in one jaw.
    Fails when the jaw does not report open within :attr:`OPEN_S` [s].
    """

    name: ClassVar[str] = "release"
    Params: ClassVar[type[SkillParams]] = ReleaseParams
    tools: ClassVar[tuple[str, ...] | None] = None

    OPEN_S: ClassVar[float] = 0.5
    """Time for the jaw to report open [s]."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._q: Any = None
        self._t0 = 0.0

    def start(self, ctx: Any) -> None:
        """Capture the pose to hold [rad, m].

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        p = self.params
        assert isinstance(p, ReleaseParams)
        self._robot = ctx.robot(p.robot)
        self._q = ctx.start.robots[self._robot].q
        self._t0 = ctx.t0

    def step(self, ctx: Any, obs: Any) -> Any:
        """Command the jaw open; report success when it is measured open.

        Args:
            ctx: the skill context.
            obs: this tick's observation.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        from skills.tool_path import hold_command
        from suture_engine.runtime.observation import SkillStatus, StepResult, ToolCommand

        cmd = hold_command(self._robot, self._q, ToolCommand(jaw_closed=False))
        if not obs.robots[self._robot].tool.jaw_closed:
            return StepResult(cmd, SkillStatus.SUCCESS)
        if obs.t - self._t0 >= self.OPEN_S:
            return StepResult(cmd, SkillStatus.FAILURE, "the jaw did not report open")
        return StepResult(cmd)
