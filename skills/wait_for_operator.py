"""``wait-for-operator``: hold both robots until the operator confirms (4.6)."""

from __future__ import annotations

from typing import Any, ClassVar

from skills.base import Skill, SkillNotAvailable, SkillParams

__all__ = ["WaitForOperator", "WaitForOperatorParams"]


class WaitForOperatorParams(SkillParams):
    """Parameters of ``wait-for-operator``."""

    prompt: str = "confirm to continue"
    """What the operator is asked to check or do."""


class WaitForOperator(Skill):
    """Hold still until the operator sends ``resume`` (or aborts)."""

    name: ClassVar[str] = "wait-for-operator"
    Params: ClassVar[type[SkillParams]] = WaitForOperatorParams
    tools: ClassVar[tuple[str, ...] | None] = None

    def step(self, ctx: Any, obs: Any) -> Any:
        """Not available yet: running arrives with the runtime and suturing work."""
        raise SkillNotAvailable(self.name)
