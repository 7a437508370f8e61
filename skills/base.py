"""The Skill base class: one parameterised activity of a procedure's state.

A skill is what a state of the procedure runs (thesis 4.6: the activities
Phi of the hybrid automaton). It has a name, a pydantic parameter model whose
quantities are in SI after load, a static :meth:`Skill.check` used by the
dry-run, and :meth:`Skill.start` / :meth:`Skill.step` called by the runtime.
The tick loop and the modes (Lock, Manual, Autonomous), retries and
invariants belong to the interpreter, not to skills.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, ClassVar

from pydantic import BaseModel, ConfigDict

from suture_engine.errors import SutureError

if TYPE_CHECKING:
    from suture_engine.validation.problem import Problem

__all__ = ["Skill", "SkillNotAvailable", "SkillParams"]


class SkillParams(BaseModel):
    """Base of every skill's parameter model.

    Unknown keys are errors (``extra="forbid"``); instances are immutable.
    Quantities are plain floats in SI units once loaded; each field's
    docstring gives its unit in brackets.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True)


class SkillNotAvailable(SutureError):
    """Raised by :meth:`Skill.step` of a skill that cannot run yet.

    Attributes:
        skill: the skill's registered name.
    """

    code = "skill-not-available"

    def __init__(self, skill: str, detail: str = "") -> None:
        message = (
            f"skill {skill!r} cannot run yet: its parameters are checked by "
            "`suture validate`, running it arrives with the runtime and suturing work"
        )
        super().__init__(message + (f" ({detail})" if detail else ""))
        self.skill = skill


class Skill(ABC):
    """A parameterised activity run by one state of a procedure.

    Subclasses set :attr:`name` and :attr:`Params`, implement :meth:`step`
    and may override :meth:`check` (static dry-run checks) and :meth:`start`.

    Attributes:
        name: the registered name used in YAML (``"move-constrained"``).
        Params: the pydantic parameter model (``extra="forbid"``).
        tools: the tool types the skill's ``robot`` must carry (``None``: any);
            checked by the dry-run.
        events: the named failure events the skill may report
            (:attr:`suture_engine.runtime.observation.StepResult.event`). A state running
            the skill may send each to a state of its own (``on: {EVENT: STATE}``); one it
            does not route is a plain failure (the ``failed`` policy).
        params: this instance's validated parameters.
    """

    name: ClassVar[str]
    Params: ClassVar[type[SkillParams]]
    tools: ClassVar[tuple[str, ...] | None] = None
    events: ClassVar[tuple[str, ...]] = ()
    scene_request: tuple[str, dict[str, Any]] | None = None
    """A change of the world the skill asks the runtime for: ``(backend method, keyword
    arguments)``, carried out by the interpreter (which then sets it to None) on the tick
    it is set; None (the class default) asks for nothing (:mod:`skills.reload`)."""

    def __init__(self, params: SkillParams) -> None:
        """Keep the validated parameters.

        Args:
            params: an instance of :attr:`Params`; a mapping is validated into one.
        """
        if not isinstance(params, self.Params):
            params = self.Params.model_validate(params)
        self.params = params

    @classmethod
    def check(cls, params: SkillParams, scene: Any) -> list[Problem]:
        """Static checks for the dry-run, without a backend.

        Args:
            params: validated parameters (SI units).
            scene: the procedure's scene (:class:`suture_engine.language.scene.Scene`).

        Returns:
            Problems found; each ``path`` is relative to the state's ``with``.
            The default finds none.
        """
        return []

    def start(self, ctx: Any) -> None:  # noqa: B027 - optional hook, empty on purpose
        """Optional hook called when the state is entered.

        Args:
            ctx: the runtime context (defined by the runtime).
        """

    @abstractmethod
    def step(self, ctx: Any, obs: Any) -> Any:
        """Compute one tick's command.

        Args:
            ctx: the runtime context.
            obs: the measured observation of this tick.

        Returns:
            The command for this tick (type defined by the runtime).
        """

    def __repr__(self) -> str:
        fields = ", ".join(f"{k}={v!r}" for k, v in self.params.model_dump().items())
        return f"{type(self).__name__}({fields})"
