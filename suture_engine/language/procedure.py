"""A loaded procedure: what the runtime compiles into its automaton.

:func:`suture_engine.language.load_procedure` returns a :class:`Procedure`:
parameters resolved to SI values, every ``${...}`` evaluated, each skill
state's parameters validated against the skill's model, every ``use:`` state
holding its loaded sub-procedure, and every state keeping its source location.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from skills.base import SkillParams
    from suture_engine.language.model import FailurePolicy, Invariant
    from suture_engine.language.scene import Scene

__all__ = ["LoadedState", "Procedure", "SourceLocation"]


@dataclass(frozen=True)
class SourceLocation:
    """Where a node was written.

    Attributes:
        file: the file's path as given.
        line: 1-based line.
        column: 1-based column.
    """

    file: str
    line: int
    column: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"


@dataclass(frozen=True)
class LoadedState:
    """One state of a loaded procedure.

    Attributes:
        name: the state's name.
        location: where the state was written.
        skill: the skill name, for a skill state.
        params: the skill's validated parameters (SI), for a skill state
            (``None`` if they were invalid).
        use: the loaded sub-procedure, for a ``use:`` state (``None`` if it could
            not be loaded).
        invariant: the state's invariant, if any.
        timeout: the state's timeout [s], if any.
        on: event -> target state name or failure policy.
        outcome: ``succeeded``/``failed``/``aborted`` for a terminal state.
        description: free text.
        enabled: False when the state's ``when`` is false: the runtime skips it and
            takes its ``done`` transition at once.
        partial_params: when ``params`` is invalid, the parameters validated with the
            invalid fields left at their defaults, so that the dry-run can still check
            the rest; never used to run.
    """

    name: str
    location: SourceLocation
    skill: str | None = None
    params: SkillParams | None = None
    use: Procedure | None = None
    invariant: Invariant | None = None
    timeout: float | None = None
    on: Mapping[str, str | FailurePolicy] = field(default_factory=dict)
    outcome: str | None = None
    description: str = ""
    enabled: bool = True
    partial_params: SkillParams | None = None

    @property
    def terminal(self) -> bool:
        """True for a state that ends the run with an outcome."""
        return self.outcome is not None


@dataclass(frozen=True)
class Procedure:
    """A loaded procedure.

    Attributes:
        name: the procedure's name.
        version: its version.
        description: free text.
        file: the file it was loaded from.
        scene: the scene (its own, or its caller's for a sub-procedure).
        params: parameter name -> resolved value (quantities in SI).
        roles: role -> robot name.
        initial: the first state's name.
        states: the states by name, in file order.
        source: positions of the file's nodes
            (:class:`suture_engine.language.source.SourceMap`), for located messages.
        backend: the backend the file names for ``suture run`` without ``--backend``, or
            None (``pybullet``).
    """

    name: str
    version: str
    description: str
    file: str
    scene: Scene | None
    params: Mapping[str, Any]
    roles: Mapping[str, str]
    initial: str
    states: Mapping[str, LoadedState]
    source: Any = None
    backend: str | None = None
