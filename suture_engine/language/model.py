"""The procedure language's document models (pydantic, ``extra="forbid"``).

A procedure is a YAML state machine of parameterised skills (DESIGN section 4,
thesis 4.6). These models describe the document as written; quantities are
converted to SI when the models are validated. Skill parameters under
``with`` are validated separately against each skill's own model, and a
``use:`` state's ``with`` against the sub-procedure's ``params``.

Example::

    procedure: square-knot
    version: "1"
    scene: scenes/bench.yaml
    params:
      algorithm: {type: int, default: 2, choices: [1, 2, 3]}
    roles: {stitcher: endobot_1, grasper: endobot_2}
    initial: first
    states:
      first:
        use: knot-algorithm-2.yaml
        on: {done: second, failed: {retry: 2, then: lock}}
      second:
        use: knot-algorithm-2.yaml
        with: {mirror: true}
        on: {done: finished}
      finished: {outcome: succeeded}
"""

from __future__ import annotations

import re
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from suture_engine.language.units import Angle, Duration, Force, Position

__all__ = [
    "MAX_RETRY",
    "OUTCOMES",
    "PROCEDURE_NAME_PATTERN",
    "FailurePolicy",
    "Invariant",
    "ParamSpec",
    "ProcedureDocument",
    "StateDocument",
    "Workspace",
]

MAX_RETRY = 10
"""The largest retry count a failure policy may give."""

OUTCOMES = ("succeeded", "failed", "aborted")
"""The outcomes a terminal state may carry."""

BASE_EVENTS = ("done", "failed")
"""The events every non-terminal state may route: its planned event and any failure
(a skill's named failure events and ``timeout`` come on top)."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True, defer_build=True)


class ParamSpec(_Model):
    """A typed procedure parameter.

    ``type: quantity`` needs a ``unit`` (``mm``, ``deg``, ``N``, ``N*s/m``), which
    fixes the dimension; values are stored in SI. ``min``/``max`` are inclusive
    bounds, ``choices`` the allowed values.
    """

    type: Literal["bool", "int", "float", "str", "quantity"]
    """The parameter's type."""
    unit: str | None = None
    """The unit that fixes a quantity's dimension."""
    default: Any = None
    """Default value (a quantity is written with its unit). It may use ``${...}`` over the
    parameters declared before this one (``${algorithm == 3}``, ``alg-${algorithm}``),
    evaluated when the file loads; a value set for the parameter replaces it."""
    min: Any = None
    """Inclusive lower bound."""
    max: Any = None
    """Inclusive upper bound."""
    choices: list[Any] | None = None
    """Allowed values."""
    requires: str | None = None
    """A condition the value must meet together with the parameters declared before it,
    written ``${...}`` (``${not secure or algorithm == 2}``). Broken, it is one problem
    where the caller set this value or one the condition names (``--set``, a ``use:``'s
    ``with``), else at the ``requires`` itself."""
    description: str = ""
    """Free text."""


class FailurePolicy(_Model):
    """What to do on a failure event: retry the previous step, then lock or abort.

    The thesis' unpredictable-event handling (4.6, Figs. 4.22-4.25): the
    NOT-BE state of a step retries the previous step up to ``retry`` times
    (e-hat_{i-1}), then locks and waits for the operator or aborts.
    """

    retry: int | str = 0
    """How many times to retry the previous step (0-10). Anything unbounded
    (``forever``, a negative number) is a problem."""
    then: Literal["lock", "abort"] = "lock"
    """After the retries: ``lock`` (hold and wait for the operator) or ``abort``."""


class Workspace(_Model):
    """An axis-aligned box the tool tips must stay in (world frame)."""

    min: Position
    """Lower corner [m]."""
    max: Position
    """Upper corner [m]."""


class Invariant(_Model):
    """The invariant Inv of a state (4.42-4.45), watched by the safety monitor."""

    max_tension: Force | None = Field(default=None, gt=0.0)
    """Suture tension bound [N]; may not exceed the scene's tension limit."""
    max_force: Force | None = Field(default=None, gt=0.0)
    """Bound of the base force-sensor magnitude [N]."""
    singularity_margin: Angle | None = Field(default=None, ge=0.0)
    """Least distance of the pitch q2 from +-90 deg (3.23) [rad]."""
    workspace: Workspace | None = None
    """Box the tool tips must stay in."""


class StateDocument(_Model):
    """One state: a skill (``skill`` + ``with``), a sub-procedure (``use`` + ``with``),
    or a terminal state (``outcome``)."""

    description: str = ""
    """Free text."""
    skill: str | None = None
    """The registered skill this state runs."""
    use: str | None = None
    """A sub-procedure file, relative to this file."""
    with_: dict[str, Any] = Field(default_factory=dict, alias="with")
    """Parameters of the skill or sub-procedure (quantities with units, ``${...}``)."""
    when: bool = True
    """When false (usually an expression, ``${stitch}``), the state is skipped: it
    raises ``done`` at once without running its skill. A skipped state that nothing
    reaches is not reported as unreachable."""
    invariant: Invariant | None = None
    """The state's invariant."""
    timeout: Duration | None = Field(default=None, gt=0.0)
    """Time after which the state raises the ``timeout`` event [s]."""
    on: dict[str, str | FailurePolicy] = Field(default_factory=dict)
    """Event -> next state, or a failure policy. ``done`` (the planned event) and
    ``failed`` (any failure: a state or a policy) on every state; on a skill state also
    the skill's named failure events (move-to's ``taut-early`` and ``not-taut``), and
    ``timeout`` when the state has one, each to a state: such a failure goes there, and
    one not routed follows ``failed``. On a ``use:`` state ``done`` is where the
    sub-procedure's ``succeeded`` terminals lead; its ``failed`` terminals end the run
    unless ``failed:`` names a state (they lead there) or gives a policy (they fail as a
    step would: ``retry`` runs the sub-procedure again from its first step, then lock or
    abort)."""
    outcome: Literal["succeeded", "failed", "aborted"] | None = None
    """Marks a terminal state and the outcome it ends the run with."""

    @model_validator(mode="after")
    def _one_kind(self) -> StateDocument:
        kinds = [k for k in ("skill", "use", "outcome") if getattr(self, k) is not None]
        if len(kinds) != 1:
            found = " and ".join(kinds) if kinds else "none of them"
            raise ValueError(f"a state has exactly one of skill, use, outcome; found {found}")
        if self.outcome is not None and (self.on or self.with_):
            raise ValueError("a terminal state (outcome) has no `on` and no `with`")
        return self


PROCEDURE_NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,99}$"
"""A procedure name: a safe file-name component (no ``/``, no leading ``.``), <= 100 chars."""


class ProcedureDocument(_Model):
    """A procedure file."""

    procedure: str = Field(json_schema_extra={"pattern": PROCEDURE_NAME_PATTERN})
    """The procedure's name: letters, digits, ``-``, ``_``, ``.``, starting with a letter or
    digit (it names run folders, so never a path)."""
    version: str | int | float = "1"
    """The procedure's version."""
    description: str = ""
    """Free text."""
    scene: str | dict[str, Any] | None = None
    """A scene file (relative to this file) or an inline scene; sub-procedures
    may leave it out and inherit their caller's."""
    backend: str | None = None
    """The backend ``suture run`` uses for this procedure when no ``--backend`` is given
    (a registered name, e.g. ``pybullet-surgical`` for a procedure that needs the thread
    and the tissue); without it, ``pybullet``. Read from the top-level file only; ``${...}``
    sees the parameters, as ``scene`` does."""
    includes_outside: bool = False
    """Allow ``use:`` and ``scene`` paths that leave this file's folder tree."""
    params: dict[str, ParamSpec] = Field(default_factory=dict)
    """Typed parameters."""
    roles: dict[str, str] = Field(default_factory=dict)
    """Role -> robot name of the scene (``stitcher: endobot_1``)."""
    initial: str
    """The first state."""
    states: dict[str, StateDocument]
    """The states by name."""

    @field_validator("procedure")
    @classmethod
    def _safe_name(cls, v: str) -> str:
        if not re.match(PROCEDURE_NAME_PATTERN, v):
            raise ValueError(
                "a procedure name is letters, digits, '-', '_' and '.', starting with a letter "
                "or digit, at most 100 characters (it names run folders)"
            )
        return v
