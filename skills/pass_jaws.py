"""``pass-jaws``: close the stitcher and pass the needle to its other jaw (4.4)."""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import RoleRef
from suture_engine.language.units import Duration, Force

__all__ = ["PassJaws", "PassJawsParams"]


class PassJawsParams(SkillParams):
    """Parameters of ``pass-jaws``."""

    robot: RoleRef
    """The role of the stitcher."""
    close_force: Force = Field(default=5.0, gt=0.0, le=30.0)
    """Force closing the jaws on the needle [N]."""
    dwell: Duration = Field(default=0.3, ge=0.0, le=5.0)
    """How long both jaws stay closed on the needle before the giving jaw opens [s]: the
    hand-over itself takes time (about 0.2 s in the simulated stitcher), and a jaw
    reported closed says nothing about the needle being locked in it."""


class PassJaws(Skill):
    """Pass the needle to the stitcher's other jaw (algorithm 1 step 6).

    The jaw holding the needle is the one measured closed at the start. The
    skill closes the other jaw, keeps both closed for ``dwell`` [s] once it is
    measured closed (the needle changes jaws meanwhile), then opens the first;
    it succeeds when the first is measured open. It fails when the tool is not
    a stitcher, when the holder is ambiguous (both or neither jaw closed), or
    when a jaw does not respond within :attr:`JAW_S` [s]. The close force is
    not forwarded: the runtime's tool command carries open/closed only.
    """

    name: ClassVar[str] = "pass-jaws"
    Params: ClassVar[type[SkillParams]] = PassJawsParams
    tools: ClassVar[tuple[str, ...] | None] = ("stitcher",)

    JAW_S: ClassVar[float] = 0.5
    """Time allowed for each jaw to respond [s]."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._q: Any = None
        self._from = 0
        self._phase = "close"
        self._t_phase = 0.0
        self._failure = ""

    def start(self, ctx: Any) -> None:
        """Find which jaw holds the needle and capture the pose.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        p = self.params
        assert isinstance(p, PassJawsParams)
        self._robot = ctx.robot(p.robot)
        robot = ctx.start.robots[self._robot]
        self._q = robot.q
        self._phase = "close"
        self._t_phase = ctx.t0
        tool = robot.tool
        self._failure = ""
        if tool.kind != "stitcher":
            self._failure = f"tool {tool.kind!r} is not a stitcher"
        elif tool.jaw_closed == tool.jaw2_closed:
            state = "both jaws closed" if tool.jaw_closed else "both jaws open"
            self._failure = f"cannot tell which jaw holds the needle ({state})"
        self._from = 1 if tool.jaw_closed else 2

    @property
    def receiving_jaw(self) -> int:
        """The jaw the needle is passed to (1 or 2)."""
        return 2 if self._from == 1 else 1

    def _tool(self, jaw: int, closed: bool) -> Any:
        from suture_engine.runtime.observation import ToolCommand

        return ToolCommand(jaw_closed=closed) if jaw == 1 else ToolCommand(jaw2_closed=closed)

    @staticmethod
    def _closed(tool: Any, jaw: int) -> bool:
        return bool(tool.jaw_closed if jaw == 1 else tool.jaw2_closed)

    def step(self, ctx: Any, obs: Any) -> Any:
        """Close the receiving jaw, then open the giving jaw.

        Args:
            ctx: the skill context.
            obs: this tick's observation.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        from skills.tool_path import hold_command
        from suture_engine.runtime.observation import SkillStatus, StepResult

        if self._failure:
            return StepResult(
                hold_command(self._robot, self._q), SkillStatus.FAILURE, self._failure
            )
        tool = obs.robots[self._robot].tool
        p = self.params
        assert isinstance(p, PassJawsParams)
        if self._phase == "close":
            cmd = hold_command(self._robot, self._q, self._tool(self.receiving_jaw, True))
            if self._closed(tool, self.receiving_jaw):
                self._phase = "dwell"
                self._t_phase = obs.t
            elif obs.t - self._t_phase >= self.JAW_S:
                return StepResult(
                    cmd,
                    SkillStatus.FAILURE,
                    f"jaw {self.receiving_jaw} did not close on the needle (the hand-over "
                    "stopped short of it, or the jaw is stuck)",
                )
            else:
                return StepResult(cmd)
        if self._phase == "dwell":
            if obs.t - self._t_phase < p.dwell:
                return StepResult(hold_command(self._robot, self._q))
            self._phase = "open"
            self._t_phase = obs.t
            return StepResult(hold_command(self._robot, self._q, self._tool(self._from, False)))
        cmd = hold_command(self._robot, self._q, self._tool(self._from, False))
        if not self._closed(tool, self._from):
            return StepResult(cmd, SkillStatus.SUCCESS)
        if obs.t - self._t_phase >= self.JAW_S:
            return StepResult(cmd, SkillStatus.FAILURE, f"jaw {self._from} did not open")
        return StepResult(cmd)
