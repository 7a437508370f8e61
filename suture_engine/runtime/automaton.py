"""The supervisory hybrid automaton H = (S, X, E, Phi, Inv) of thesis 4.6 (4.42).

A validated procedure compiles (:mod:`suture_engine.runtime.plan`) into a
:class:`Plan`; :class:`Automaton` turns the plan into a hierarchical
``transitions`` machine:

- the high-level modes of Fig. 4.23: ``lock``, ``manual`` and ``autonomous``;
- inside ``autonomous``, each procedure step ``s_i`` with its activity (a
  skill, Phi) and invariant (Inv), and its NOT-BE state ``~s_i`` (Fig. 4.25),
  named ``autonomous/<step>`` and ``autonomous/<step>~notbe``;
- terminal states, each with an outcome (succeeded, failed, aborted), plus the
  reserved ``ABORTED`` and ``FAILED`` terminals of the operator and policies.

Events (E): the planned event ``advance`` (e_i, the skill finished), the
unpredictable event ``fault`` (e~_i: invariant violated, skill failure,
timeout, sensor fault, operator interrupt) into the step's NOT-BE state; from
there the step's :class:`FailurePolicy` fires ``retry`` (e^_{i-1}: the previous
step once more, at most N times), ``lock`` (wait for the operator), ``abort``
or ``fail``; a skill's named failure event (``taut-early``) that the step
routes (``on: {taut-early: free-loop}``) fires ``recover`` to that state instead.
The operator may at any tick ``lock``, take ``manual``,
``resume`` (at the interrupted step or a named one) or ``abort``.

Modes, retries and invariants live here and in the interpreter; skills stay
pure. ``transitions`` does not roll back a state change when ``on_enter``
raises, so a step's skill is created and started in the transition's
``before`` callback: if that raises, the machine stays where it was and the
failure is handled as an unpredictable event of the current state.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from transitions.extensions.nesting import HierarchicalMachine, NestedState

from suture_engine.errors import SutureError

__all__ = [
    "ABORTED",
    "FAILED",
    "SKIPPED",
    "Automaton",
    "AutomatonError",
    "FailurePolicy",
    "Mode",
    "Outcome",
    "Plan",
    "StepSpec",
    "Then",
    "TransitionRecord",
]

ABORTED = "ABORTED"
"""Reserved terminal reached by an operator abort or an ``abort`` policy."""
FAILED = "FAILED"
"""Reserved terminal reached by a ``fail`` policy."""
NOTBE_SUFFIX = "~notbe"


class Mode(enum.Enum):
    """High-level mode of an EndoBot (thesis Fig. 4.23)."""

    IDLE = "idle"
    """Not started yet."""
    LOCK = "lock"
    """Regulates the pose captured on entry (4.44)."""
    MANUAL = "manual"
    """Gravity compensation (5.1) plus the operator's motion; workspace invariant (4.45)."""
    AUTONOMOUS = "autonomous"
    """The procedure's steps run."""
    TERMINAL = "terminal"
    """The run is over; the robots keep the Lock law."""


# Members bound once for the per-tick queries: ``Mode.X`` on the class costs ~60 ns in
# CPython 3.11, a module global ~10 ns.
_AUTONOMOUS, _LOCK, _TERMINAL = Mode.AUTONOMOUS, Mode.LOCK, Mode.TERMINAL


class Outcome(enum.Enum):
    """How a run ended."""

    SUCCEEDED = "succeeded"
    """A terminal state with outcome succeeded was reached."""
    FAILED = "failed"
    """A terminal state with outcome failed was reached, or a policy gave up."""
    ABORTED = "aborted"
    """The operator or a policy aborted the run."""


class Then(enum.Enum):
    """What a failure policy does once its retries are used up."""

    LOCK = "lock"
    """Lock the robots and wait for the operator (resume, manual or abort)."""
    ABORT = "abort"
    """End the run with outcome aborted."""
    FAIL = "fail"
    """End the run with outcome failed."""


@dataclass(frozen=True)
class FailurePolicy:
    """Reaction to an unpredictable event in a step (thesis Fig. 4.25).

    Attributes:
        retry: how many times the previous step (e^_{i-1}) is run again from NOT-BE.
        then: what happens when the retries are used up.
        goto: instead of ``then``, go to this step or terminal (``on: {failed: NAME}``).
        retry_from: the step a retry enters (None: the previous step, e^_{i-1}); a
            sub-procedure's retry enters its first step.
    """

    retry: int = 0
    then: Then = Then.LOCK
    goto: str | None = None
    retry_from: str | None = None

    def __post_init__(self) -> None:
        if self.retry < 0:
            raise ValueError("retry must be >= 0")


@dataclass(frozen=True)
class StepSpec:
    """One procedure state s_i: its activity, invariant and events.

    Attributes:
        name: the state's name in the procedure.
        make_skill: builds a fresh skill instance each time the step is entered.
        on_done: the state the planned event e_i leads to (a step or a terminal).
        policy: reaction to unpredictable events.
        timeout_s: the step's timeout [s] (None: none).
        invariant: the step's invariant for the monitor (4.43), or None.
        robots: the robots the step drives (others hold their pose).
        roles: role -> robot of the (sub-)procedure the step comes from.
        enabled: False when the state's ``when:`` is false: entering the step skips it
            (no skill is built; it completes at once with its planned event, the
            transition's reason saying it was skipped).
        on_event: named failure event -> the step or terminal it leads to
            (``on: {taut-early: free-loop}``); a failure with another event, or none,
            follows :attr:`policy`.
    """

    name: str
    make_skill: Callable[[], Any]
    on_done: str
    policy: FailurePolicy = field(default_factory=FailurePolicy)
    timeout_s: float | None = None
    invariant: Any = None
    robots: tuple[str, ...] = ()
    roles: Mapping[str, str] = field(default_factory=dict)
    enabled: bool = True
    on_event: Mapping[str, str] = field(default_factory=dict)


SKIPPED = "skipped"
"""Reason prefix of the planned event that completes a skipped step (``when:`` false)."""


@dataclass(frozen=True)
class Plan:
    """A compiled procedure.

    Attributes:
        procedure: the procedure's name.
        initial: the first step.
        steps: the steps by name.
        terminals: terminal state name -> outcome.
        robots: all robot names, e.g. ("endobot_1", "endobot_2").
    """

    procedure: str
    initial: str
    steps: Mapping[str, StepSpec]
    terminals: Mapping[str, Outcome]
    robots: tuple[str, ...] = ("endobot_1", "endobot_2")


@dataclass(frozen=True)
class TransitionRecord:
    """One discrete transition, for the trace.

    Attributes:
        source: state before.
        dest: state after.
        event: the trigger ("advance", "fault", "retry", "lock", ...).
        kind: "planned", "unpredictable", "policy" or "operator".
        reason: why (e.g. "invariant:tension", "timeout", "skill-failure").
    """

    source: str
    dest: str
    event: str
    kind: str
    reason: str = ""


class AutomatonError(SutureError):
    """A plan cannot be compiled, or an event is not allowed in the current state.

    Attributes:
        state: the current state (or the offending name when compiling).
        event: the event asked for ("" when compiling).
    """

    code = "automaton-error"

    def __init__(self, message: str, state: str = "", event: str = "") -> None:
        super().__init__(message)
        self.state = state
        self.event = event


class _State(NestedState):
    separator = "/"


class _Machine(HierarchicalMachine):
    state_cls = _State


class _Model:
    state: str


def notbe(step: str) -> str:
    """Name of step ``step``'s NOT-BE state inside ``autonomous``."""
    return f"{step}{NOTBE_SUFFIX}"


class Automaton:
    """The supervisory hybrid automaton of one run.

    Args:
        plan: the compiled procedure.
        start_skill: ``start_skill(step, skill)`` starts a freshly built skill
            (the interpreter passes its context); it may raise.
    """

    def __init__(self, plan: Plan, start_skill: Callable[[StepSpec, Any], None]) -> None:
        self.plan = plan
        self._start_skill = start_skill
        self._check(plan)
        self.active_skill: Any = None
        self.active_step: StepSpec | None = None
        self.retries: dict[str, int] = {name: 0 for name in plan.steps}
        self.retries_total = 0
        self.interrupted_step: str | None = None
        self.interrupted_skill: Any = None
        self.waiting_for_operator = False
        self.outcome: Outcome | None = None
        self.history: list[TransitionRecord] = []
        self._previous: dict[str, str | None] = {}
        self._target = ""
        self._pending: tuple[StepSpec, Any] | None = None
        self._model = _Model()
        self._mode_state = ""
        self._mode = Mode.IDLE
        self.machine = _Machine(
            model=self._model,
            states=self._states(),
            initial="idle",
            auto_transitions=False,
            send_event=True,
            ignore_invalid_triggers=False,
        )
        self._add_transitions()

    # ----------------------------------------------------------------- compile
    @staticmethod
    def _check(plan: Plan) -> None:
        names = set(plan.steps) | set(plan.terminals)
        reserved = {ABORTED, FAILED, "idle", "lock", "manual", "autonomous"}
        for name in names:
            if "/" in name or name.endswith(NOTBE_SUFFIX) or name in reserved:
                raise AutomatonError(f"state name {name!r} is reserved or contains '/'", name)
        overlap = set(plan.steps) & set(plan.terminals)
        if overlap:
            raise AutomatonError(f"{sorted(overlap)} are both steps and terminals", min(overlap))
        if plan.initial not in plan.steps:
            raise AutomatonError(f"initial state {plan.initial!r} is not a step", plan.initial)
        for step in plan.steps.values():
            if step.on_done not in names:
                raise AutomatonError(
                    f"step {step.name!r}: done leads to unknown state {step.on_done!r}", step.name
                )
            goto = step.policy.goto
            if goto is not None and goto not in names:
                raise AutomatonError(
                    f"step {step.name!r}: failed leads to unknown state {goto!r}", step.name
                )
            for event, dest in step.on_event.items():
                if dest not in names:
                    raise AutomatonError(
                        f"step {step.name!r}: event {event!r} leads to unknown state {dest!r}",
                        step.name,
                    )
        for step in plan.steps.values():
            seen: list[str] = []
            name = step.name
            while name in plan.steps and not plan.steps[name].enabled:
                if name in seen:
                    raise AutomatonError(
                        f"steps {seen} are all skipped (when: false) and lead to each other",
                        name,
                    )
                seen.append(name)
                name = plan.steps[name].on_done

    def _states(self) -> list[Any]:
        children: list[str] = []
        for name in self.plan.steps:
            children += [name, notbe(name)]
        terminals = [*self.plan.terminals, ABORTED, FAILED]
        return ["idle", "lock", "manual", {"name": "autonomous", "children": children}, *terminals]

    def _add_transitions(self) -> None:
        m = self.machine
        steps = list(self.plan.steps)
        live = ["lock", "manual"] + [f"autonomous/{s}" for s in steps]
        live += [f"autonomous/{notbe(s)}" for s in steps]
        for s in steps:
            dest = self.plan.steps[s].on_done
            full = f"autonomous/{dest}" if dest in self.plan.steps else dest
            m.add_transition("advance", f"autonomous/{s}", full, before=self._before_enter)
            m.add_transition("fault", f"autonomous/{s}", f"autonomous/{notbe(s)}")
        for j in steps:
            cond = self._is_target(j)
            dest = f"autonomous/{j}"
            m.add_transition("start", "idle", dest, conditions=cond, before=self._before_enter)
            for s in steps:
                src = f"autonomous/{notbe(s)}"
                m.add_transition("retry", src, dest, conditions=cond, before=self._before_enter)
            for src in ["lock", "manual"] + [f"autonomous/{notbe(s)}" for s in steps]:
                m.add_transition("resume", src, dest, conditions=cond, before=self._before_enter)
        for s in steps:
            # a named failure event's route first, each taken only for its own target;
            # then the step's unconditional `failed:` state, if any
            for dest in dict.fromkeys(self.plan.steps[s].on_event.values()):
                full = f"autonomous/{dest}" if dest in self.plan.steps else dest
                m.add_transition(
                    "recover",
                    f"autonomous/{notbe(s)}",
                    full,
                    conditions=self._is_target(dest),
                    before=self._before_enter,
                )
            goto = self.plan.steps[s].policy.goto
            if goto is not None:
                full = f"autonomous/{goto}" if goto in self.plan.steps else goto
                src = f"autonomous/{notbe(s)}"
                m.add_transition("recover", src, full, before=self._before_enter)
        m.add_transition("lock", [s for s in live if s != "lock"], "lock")
        m.add_transition("manual", [s for s in live if s != "manual"], "manual")
        m.add_transition("abort", ["idle", *live], ABORTED)
        m.add_transition("fail", ["idle", *live], FAILED)

    def _is_target(self, step: str) -> Callable[[Any], bool]:
        return lambda _event: self._target == step

    # ----------------------------------------------------------------- callbacks
    def _before_enter(self, event: Any) -> None:
        """Build and start the destination step's skill before the state changes."""
        dest: str = event.transition.dest
        name = dest.split("/", 1)[1] if dest.startswith("autonomous/") else dest
        spec = self.plan.steps.get(name)
        if spec is None:
            return
        if not spec.enabled:  # skipped (when: false): no skill to build or start
            self._pending = (spec, None)
            return
        skill = spec.make_skill()
        self._start_skill(spec, skill)
        self._pending = (spec, skill)

    # ----------------------------------------------------------------- queries
    @property
    def state(self) -> str:
        """The full current state name (e.g. ``autonomous/tighten``)."""
        return self._model.state

    @property
    def mode(self) -> Mode:
        """The high-level mode (Fig. 4.23)."""
        s = self.state
        if s == self._mode_state:
            return self._mode
        self._mode_state, self._mode = s, self._mode_of_state(s)
        return self._mode

    @staticmethod
    def _mode_of_state(s: str) -> Mode:
        if s == "idle":
            return Mode.IDLE
        if s in ("lock", "manual"):
            return Mode.LOCK if s == "lock" else Mode.MANUAL
        if s.startswith("autonomous/"):
            return Mode.LOCK if s.endswith(NOTBE_SUFFIX) else Mode.AUTONOMOUS
        return Mode.TERMINAL

    def mode_of(self, robot: str) -> Mode:
        """Mode of one robot; in autonomous steps robots the step does not drive are locked."""
        mode = self.mode
        step = self.active_step
        if mode is _AUTONOMOUS and step is not None and step.robots:
            return _AUTONOMOUS if robot in step.robots else _LOCK
        return mode

    @property
    def step_name(self) -> str | None:
        """The procedure step the machine is in (or its NOT-BE state's step), else None."""
        s = self.state
        if not s.startswith("autonomous/"):
            return None
        name = s.split("/", 1)[1]
        return name[: -len(NOTBE_SUFFIX)] if name.endswith(NOTBE_SUFFIX) else name

    @property
    def finished(self) -> bool:
        """True once a terminal state is reached."""
        return self.mode is _TERMINAL

    # ----------------------------------------------------------------- events
    def _fire(self, event: str, kind: str, reason: str = "", target: str = "") -> TransitionRecord:
        source = self.state
        self._target = target
        self._pending = None
        try:
            ok = self._model.trigger(event)  # type: ignore[attr-defined]
        except Exception as exc:
            if type(exc).__name__ == "MachineError":
                raise AutomatonError(
                    f"event {event!r} is not allowed in state {source!r}", source, event
                ) from exc
            raise
        if not ok:
            raise AutomatonError(
                f"event {event!r} to {target!r} is not allowed in state {source!r}", source, event
            )
        if self._pending is not None:
            self.active_step, self.active_skill = self._pending
        elif not self.state.startswith("autonomous/") or self.state.endswith(NOTBE_SUFFIX):
            self.active_skill = None
            if not self.state.startswith("autonomous/"):
                self.active_step = None
        record = TransitionRecord(source, self.state, event, kind, reason)
        self.history.append(record)
        if self.state in self.plan.terminals:
            self.outcome = self.plan.terminals[self.state]
        elif self.state == ABORTED:
            self.outcome = Outcome.ABORTED
        elif self.state == FAILED:
            self.outcome = Outcome.FAILED
        return record

    def _enter_step(
        self, event: str, kind: str, step: str, reason: str = "", previous: str | None = None
    ) -> list[TransitionRecord]:
        """Fire an event that enters ``step``; a skill start failure becomes a fault.

        A step whose ``when:`` is false completes at once: its planned event follows
        in the same call, with the reason ``skipped:<step>``.
        """
        if step not in self.plan.steps:
            raise AutomatonError(f"no step named {step!r}", self.state, event)
        try:
            out = [self._fire(event, kind, reason, target=step)]
        except AutomatonError:
            raise
        except Exception as exc:  # the skill's start raised; the state did not change
            return self._start_failed(step, exc)
        if previous is not None and self.step_name == step:
            self._previous[step] = previous
        if self.mode is Mode.AUTONOMOUS and not self.plan.steps[step].enabled:
            out += self._advance(step, f"{SKIPPED}:{step} (when: false)")
        return out

    def _start_failed(self, step: str, exc: Exception) -> list[TransitionRecord]:
        reason = f"skill-start-failed:{step}:{type(exc).__name__}: {exc}"
        if self.mode is Mode.AUTONOMOUS:
            return self.unpredictable(reason)
        if self.state.endswith(NOTBE_SUFFIX):
            return self._apply_policy(reason)
        if self.mode is Mode.IDLE:  # the first step cannot start: nothing to fall back on
            return [self._fire("fail", "unpredictable", reason)]
        # lock or manual: an operator's resume that could not start; stay and wait
        return [TransitionRecord(self.state, self.state, "start-failed", "unpredictable", reason)]

    def start(self) -> list[TransitionRecord]:
        """Enter the initial step (from ``idle``)."""
        return self._enter_step("start", "planned", self.plan.initial)

    def planned(self) -> list[TransitionRecord]:
        """The planned event e_i: the active step finished; go to its ``done`` state."""
        step = self.step_name
        if self.mode is not Mode.AUTONOMOUS or step is None:
            raise AutomatonError("no running step to finish", self.state, "advance")
        return self._advance(step, f"done:{step}")

    def _advance(self, step: str, reason: str) -> list[TransitionRecord]:
        """Fire ``step``'s planned event to its ``done`` state (a step or a terminal)."""
        dest = self.plan.steps[step].on_done
        if dest in self.plan.steps:
            return self._enter_step("advance", "planned", dest, reason=reason, previous=step)
        return [self._fire("advance", "planned", reason)]

    def unpredictable(
        self, reason: str, operator_lock: bool = False, event: str = ""
    ) -> list[TransitionRecord]:
        """An unpredictable event e~_i: into the step's NOT-BE state, then apply its policy.

        Args:
            reason: what happened ("invariant:tension", "timeout", "skill-failure", ...).
            operator_lock: an operator interrupt: lock after NOT-BE instead of the policy.
            event: the skill's named failure event, if any (``taut-early``): a step that
                routes it (:attr:`StepSpec.on_event`) goes there instead of its policy.
        """
        step = self.step_name
        if self.mode is not Mode.AUTONOMOUS or step is None:
            raise AutomatonError("unpredictable events arise only in a running step", self.state)
        self.interrupted_step = step
        self.interrupted_skill = self.active_skill
        out = [self._fire("fault", "unpredictable", reason)]
        if operator_lock:
            out.append(self._fire("lock", "operator", reason))
            self.waiting_for_operator = True
            return out
        return out + self._apply_policy(reason, event)

    def emergency_lock(self, reason: str) -> list[TransitionRecord]:
        """The monitor's emergency (tension near its limit, a non-finite measurement, a
        stale sensor): lock every robot and wait for the operator, whatever the step's
        policy. A running step goes through its NOT-BE state first (Fig. 4.25).

        Returns:
            The transitions (none when the robots already hold their pose or the run
            is over).
        """
        if self.mode in (Mode.IDLE, Mode.LOCK, Mode.TERMINAL):
            return []
        out: list[TransitionRecord] = []
        if self.mode is Mode.AUTONOMOUS:
            self.interrupted_step = self.step_name
            self.interrupted_skill = self.active_skill
            out.append(self._fire("fault", "unpredictable", reason))
        out.append(self._fire("lock", "unpredictable", reason))
        self.waiting_for_operator = True
        return out

    def _apply_policy(self, reason: str, event: str = "") -> list[TransitionRecord]:
        step = self.step_name
        assert step is not None
        routed = self.plan.steps[step].on_event.get(event) if event else None
        if routed is not None:
            why = f"{event}:{step}"
            if routed in self.plan.steps:
                return self._enter_step("recover", "policy", routed, why)
            return [self._fire("recover", "policy", why, target=routed)]
        policy = self.plan.steps[step].policy
        if self.retries[step] < policy.retry:
            self.retries[step] += 1
            self.retries_total += 1
            target = policy.retry_from or self._previous.get(step) or step
            return self._enter_step("retry", "policy", target, reason=f"retry:{step}")
        if policy.goto is not None:
            if policy.goto in self.plan.steps:
                return self._enter_step("recover", "policy", policy.goto, f"failed:{step}")
            return [self._fire("recover", "policy", f"failed:{step}")]
        if policy.then is Then.LOCK:
            self.waiting_for_operator = True
            return [self._fire("lock", "policy", f"exhausted:{step}")]
        if policy.then is Then.ABORT:
            return [self._fire("abort", "policy", f"exhausted:{step}")]
        return [self._fire("fail", "policy", f"exhausted:{step}")]

    # ----------------------------------------------------------------- operator
    def operator(self, action: str, step: str | None = None) -> list[TransitionRecord]:
        """An operator event: ``lock``, ``manual``, ``resume`` [step] or ``abort``.

        Raises:
            AutomatonError: the action is unknown or not allowed now (e.g. after the end).
        """
        if self.finished:
            raise AutomatonError(f"the run is over ({self.state})", self.state, action)
        if action in ("lock", "manual"):
            if self.mode is Mode.AUTONOMOUS:
                out = self.unpredictable("operator-interrupt", operator_lock=True)
                if action == "manual":
                    out.append(self._fire("manual", "operator"))
                return out
            if self.state == action:
                return []
            return [self._fire(action, "operator")]
        if action == "resume":
            if step is not None and step not in self.plan.steps:
                raise AutomatonError(
                    f"cannot resume at {step!r}: not a step ({', '.join(self.plan.steps)})",
                    self.state,
                    action,
                )
            target = step or self.interrupted_step or self.step_name or self.plan.initial
            interrupt: list[TransitionRecord] = []
            if self.mode is Mode.AUTONOMOUS:
                if step is None or step == self.step_name:
                    return []
                interrupt = self.unpredictable("operator-interrupt", operator_lock=True)
            self.waiting_for_operator = False
            return interrupt + self._enter_step("resume", "operator", target)
        if action == "abort":
            return [self._fire("abort", "operator")]
        raise AutomatonError(
            f"unknown operator action {action!r} (lock, manual, resume, abort)", self.state, action
        )

    def previous_of(self, step: str) -> str | None:
        """The step that ran before ``step`` last time (None for the first)."""
        return self._previous.get(step)
