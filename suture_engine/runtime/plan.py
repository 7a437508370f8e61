"""Compile a loaded procedure into the automaton's :class:`Plan`.

Skill states become steps (a factory building a fresh skill on each entry,
their ``done`` target, failure policy, timeout, invariant and the robot they
drive); terminal states become terminals with their outcome. A state whose
``when:`` is false becomes a skipped step (``StepSpec.enabled`` False): the
automaton completes it at once when it is entered; a skipped ``use:`` state is
one skipped step, its sub-procedure is not inlined. A ``use:`` state
is inlined: its sub-procedure's states are named ``<state>.<sub-state>``, the
sub-procedure's ``succeeded`` terminals lead to the ``use:`` state's ``done``
target, and its other terminals end the run with their outcome, except its ``failed``
terminals when the ``use:`` state has a ``failed:`` entry. Naming a state
(``on: {done: tied, failed: again}``) leads them there. A failure policy
(``failed: {retry: 1, then: lock}``) makes each one a step that fails at once: its
retries run the sub-procedure again from its first step, then the robots lock (or the
run aborts), as a failing skill's would.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial
from typing import Any

from suture_engine.language.model import BASE_EVENTS
from suture_engine.runtime.automaton import (
    AutomatonError,
    FailurePolicy,
    Outcome,
    Plan,
    StepSpec,
    Then,
)
from suture_engine.runtime.monitor import Invariant

__all__ = ["compile_procedure", "convert_invariant"]


def convert_invariant(inv: Any) -> Invariant | None:
    """The monitor's :class:`Invariant` from a procedure state's ``invariant`` (SI)."""
    if inv is None:
        return None
    ws = getattr(inv, "workspace", None)
    return Invariant(
        max_tension_N=getattr(inv, "max_tension", None),
        max_force_N=getattr(inv, "max_force", None),
        singularity_margin_rad=getattr(inv, "singularity_margin", None),
        workspace_min=tuple(ws.min) if ws is not None else None,
        workspace_max=tuple(ws.max) if ws is not None else None,
    )


def _policy(value: Any) -> FailurePolicy:
    if value is None:
        return FailurePolicy()
    if isinstance(value, str):
        return FailurePolicy(goto=value)
    retry = getattr(value, "retry", 0)
    then = getattr(value, "then", "lock")
    return FailurePolicy(retry=int(retry), then=Then(then))


def _robots(params: Any, roles: Mapping[str, str]) -> tuple[str, ...]:
    out: list[str] = []
    for field in ("robot", "robots"):
        value = getattr(params, field, None)
        values = [value] if isinstance(value, str) else list(value or [])
        for role in values:
            name = roles.get(role, role)
            if name not in out:
                out.append(name)
    return tuple(out)


def _factory(skill_name: str, params: Any) -> Any:
    from skills.registry import get_skill

    cls = get_skill(skill_name)
    return lambda: cls(params)


class _Ended:
    """The skill of a sub-procedure's ``failed`` terminal under its ``use:`` state's
    failure policy: fails on its first tick with ``message``; every robot holds its
    pose."""

    def __init__(self, message: str) -> None:
        self.message = message

    def start(self, ctx: Any) -> None:
        """Nothing to prepare."""

    def step(self, ctx: Any, obs: Any) -> Any:
        """A failure (an unpredictable event) with no command of its own."""
        from suture_engine.runtime.observation import Command, SkillStatus, StepResult

        return StepResult(Command({}), SkillStatus.FAILURE, self.message)


def _skipped() -> Any:
    """The skill factory of a skipped ``use:`` state: never called (no skill runs)."""
    raise AutomatonError("a skipped state (when: false) runs no skill")


def _inline(
    proc: Any,
    prefix: str,
    on_success: str | None,
    roles: Mapping[str, str],
    steps: dict[str, StepSpec],
    terminals: dict[str, Outcome],
    exits: Mapping[str, str | None] | None = None,
) -> str:
    """Add ``proc``'s states; return the full name of its entry step.

    ``exits`` maps outcomes of ``proc``'s terminals (a sub-procedure's) to the caller's
    state they lead to instead of ending the run; ``None`` keeps the terminal's name
    for a step the caller adds."""
    exits = exits or {}
    roles = {**roles, **dict(getattr(proc, "roles", None) or {})}
    states: Mapping[str, Any] = proc.states
    entry: dict[str, str] = {}
    busy: set[str] = set()

    def resolve(name: str) -> str:
        if name not in states:
            raise AutomatonError(f"{prefix or 'procedure'}: unknown state {name!r}", prefix + name)
        st = states[name]
        if st.outcome is not None:
            if on_success is not None and st.outcome == "succeeded":
                return on_success
            return exits.get(st.outcome) or prefix + name
        if st.use is not None:
            return use_entry(name)
        return prefix + name

    def use_entry(name: str) -> str:
        if name in entry:
            return entry[name]
        if name in busy:
            raise AutomatonError(f"{prefix}{name}: 'use:' states lead to each other", name)
        busy.add(name)
        st = states[name]
        done = st.on.get("done")
        if not isinstance(done, str):
            raise AutomatonError(f"state {prefix + name!r} has no 'done' target", prefix + name)
        if not getattr(st, "enabled", True):
            # ``when:`` false: one skipped step stands for the whole sub-procedure.
            entry[name] = prefix + name
            steps[prefix + name] = StepSpec(
                name=prefix + name,
                make_skill=_skipped,
                on_done=resolve(done),
                roles=roles,
                enabled=False,
            )
            return entry[name]
        if not hasattr(st.use, "states"):
            raise AutomatonError(f"state {prefix + name!r}: sub-procedure not loaded", name)
        succ = resolve(done)
        failed = st.on.get("failed")
        sub_exits: dict[str, str | None] = {}
        if isinstance(failed, str):
            sub_exits["failed"] = resolve(failed)
        elif failed is not None:
            sub_exits["failed"] = None
        sub_prefix = f"{prefix}{name}."
        entry[name] = _inline(st.use, sub_prefix, succ, roles, steps, terminals, sub_exits)
        if failed is not None and not isinstance(failed, str):
            policy = _policy(failed)
            for end, sub in st.use.states.items():
                if sub.outcome != "failed":
                    continue
                steps[sub_prefix + end] = StepSpec(
                    name=sub_prefix + end,
                    make_skill=partial(_Ended, f"{prefix}{name} ended in {end!r} (outcome failed)"),
                    on_done=entry[name],
                    policy=FailurePolicy(policy.retry, policy.then, retry_from=entry[name]),
                    roles=roles,
                )
        return entry[name]

    for name, st in states.items():
        if st.outcome is not None and not (on_success is not None and st.outcome == "succeeded"):
            if st.outcome not in exits:
                terminals[prefix + name] = Outcome(st.outcome)
    for name, st in states.items():
        if st.use is not None:
            use_entry(name)
    for name, st in states.items():
        if st.skill is None:
            continue
        done = st.on.get("done")
        if not isinstance(done, str):
            raise AutomatonError(f"state {prefix + name!r} has no 'done' target", prefix + name)
        policy = _policy(st.on.get("failed"))
        if policy.goto is not None:
            policy = FailurePolicy(policy.retry, policy.then, resolve(policy.goto))
        on_event = {
            event: resolve(target)
            for event, target in st.on.items()
            if event not in BASE_EVENTS and isinstance(target, str)
        }
        if st.params is None:
            raise AutomatonError(f"state {prefix + name!r}: its parameters are invalid", name)
        steps[prefix + name] = StepSpec(
            name=prefix + name,
            make_skill=_factory(st.skill, st.params),
            on_done=resolve(done),
            policy=policy,
            timeout_s=st.timeout,
            invariant=convert_invariant(st.invariant),
            robots=_robots(st.params, roles),
            roles=roles,
            enabled=bool(getattr(st, "enabled", True)),
            on_event=on_event,
        )
    return resolve(proc.initial)


def compile_procedure(proc: Any) -> Plan:
    """The :class:`Plan` of a loaded :class:`suture_engine.language.procedure.Procedure`.

    Raises:
        AutomatonError: a state without a ``done`` target, an unknown target, a
            sub-procedure that did not load.
    """
    roles: Mapping[str, str] = dict(proc.roles)
    steps: dict[str, StepSpec] = {}
    terminals: dict[str, Outcome] = {}
    initial = _inline(proc, "", None, roles, steps, terminals)
    robots: tuple[str, ...] = ("endobot_1", "endobot_2")
    scene = getattr(proc, "scene", None)
    if scene is not None and getattr(scene, "robots", None):
        robots = tuple(scene.robots)
    if initial not in steps:
        raise AutomatonError(f"the initial state {proc.initial!r} is not a skill state", initial)
    return Plan(proc.name, initial, steps, terminals, robots)
