"""``wait-for-operator``: hold both robots until the operator confirms (4.6)."""

from __future__ import annotations

from typing import Any, ClassVar

from skills.base import Skill, SkillParams

__all__ = ["WaitForOperator", "WaitForOperatorParams"]


class WaitForOperatorParams(SkillParams):
    """Parameters of ``wait-for-operator``."""

    prompt: str = "confirm to continue"
    """What the operator is asked to check or do."""


class WaitForOperator(Skill):
    """Hold every robot at its pose on entry (the Lock law, 4.44) and keep running.

    The skill itself never reports an event: the operator moves the procedure
    on (``resume`` at another step, or ``abort``), or the state's timeout
    fires. Operator events reach the automaton, not skills.
    """

    name: ClassVar[str] = "wait-for-operator"
    Params: ClassVar[type[SkillParams]] = WaitForOperatorParams
    tools: ClassVar[tuple[str, ...] | None] = None

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._q: dict[str, Any] = {}

    def start(self, ctx: Any) -> None:
        """Capture every robot's joints [rad, m].

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        self._q = {name: r.q for name, r in ctx.start.robots.items()}

    def step(self, ctx: Any, obs: Any) -> Any:
        """Hold all robots; always running.

        Args:
            ctx: the skill context.
            obs: this tick's observation.

        Returns:
            A running :class:`suture_engine.runtime.observation.StepResult`.
        """
        from suture_engine.runtime.observation import Command, RobotCommand, StepResult

        if not self._q:
            self._q = {name: r.q for name, r in obs.robots.items()}
        return StepResult(Command({n: RobotCommand.position(q) for n, q in self._q.items()}))
