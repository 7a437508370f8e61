"""The supervisory hybrid automaton (thesis 4.6, Figs. 4.23 and 4.25)."""

from __future__ import annotations

from typing import Any

import pytest

from suture_engine.runtime.automaton import (
    ABORTED,
    FAILED,
    Automaton,
    AutomatonError,
    FailurePolicy,
    Mode,
    Outcome,
    Plan,
    StepSpec,
    Then,
)


class _Skill:
    def __init__(self, name: str, boom: bool = False) -> None:
        self.name = name
        self.boom = boom


def _plan(policy_b: FailurePolicy | None = None, boom: set[str] | None = None) -> Plan:
    boom = boom or set()

    def make(name: str) -> Any:
        return lambda: _Skill(name, name in boom)

    return Plan(
        "p",
        "a",
        {
            "a": StepSpec("a", make("a"), "b"),
            "b": StepSpec("b", make("b"), "c", policy_b or FailurePolicy(1, Then.LOCK)),
            "c": StepSpec("c", make("c"), "end"),
        },
        {"end": Outcome.SUCCEEDED},
    )


def _automaton(plan: Plan, started: list[str] | None = None) -> Automaton:
    log = started if started is not None else []

    def start(spec: StepSpec, skill: _Skill) -> None:
        if skill.boom:
            raise RuntimeError(f"{spec.name} cannot start")
        log.append(spec.name)

    return Automaton(plan, start)


def test_planned_events_advance_to_the_terminal() -> None:
    started: list[str] = []
    a = _automaton(_plan(), started)
    assert a.mode is Mode.IDLE
    a.start()
    assert (a.state, a.mode) == ("autonomous/a", Mode.AUTONOMOUS)
    a.planned()
    a.planned()
    a.planned()
    assert a.state == "end" and a.finished and a.outcome is Outcome.SUCCEEDED
    assert started == ["a", "b", "c"]
    assert [r.event for r in a.history] == ["start", "advance", "advance", "advance"]
    assert all(r.kind == "planned" for r in a.history)


def test_unpredictable_event_goes_to_notbe_then_retries_the_previous_step() -> None:
    started: list[str] = []
    a = _automaton(_plan(FailurePolicy(2, Then.ABORT)), started)
    a.start()
    a.planned()
    records = a.unpredictable("invariant:tension")
    assert [(r.source, r.dest, r.event) for r in records] == [
        ("autonomous/b", "autonomous/b~notbe", "fault"),
        ("autonomous/b~notbe", "autonomous/a", "retry"),
    ]
    assert records[0].kind == "unpredictable" and records[0].reason == "invariant:tension"
    assert a.retries == {"a": 0, "b": 1, "c": 0} and a.retries_total == 1
    assert started == ["a", "b", "a"]
    assert a.active_skill.name == "a"


def test_exhausted_retries_apply_then_lock_abort_or_fail() -> None:
    for then, state, outcome in (
        (Then.LOCK, "lock", None),
        (Then.ABORT, ABORTED, Outcome.ABORTED),
        (Then.FAIL, FAILED, Outcome.FAILED),
    ):
        a = _automaton(_plan(FailurePolicy(0, then)))
        a.start()
        a.planned()
        a.unpredictable("timeout")
        assert a.state == state
        assert a.outcome is outcome
        assert a.waiting_for_operator is (then is Then.LOCK)


def test_failed_goto_recovers_into_a_named_state() -> None:
    a = _automaton(_plan(FailurePolicy(0, goto="c")))
    a.start()
    a.planned()
    records = a.unpredictable("skill-failure")
    assert records[-1].event == "recover" and a.state == "autonomous/c"


def _routed_plan(policy: FailurePolicy, on_event: dict[str, str]) -> Plan:
    """a -> b -> c -> end, b routing named failure events; ``free`` leads back to c."""

    def make(name: str) -> Any:
        return lambda: _Skill(name)

    return Plan(
        "p",
        "a",
        {
            "a": StepSpec("a", make("a"), "b"),
            "b": StepSpec("b", make("b"), "c", policy, on_event=on_event),
            "free": StepSpec("free", make("free"), "c"),
            "c": StepSpec("c", make("c"), "end"),
        },
        {"end": Outcome.SUCCEEDED, "given-up": Outcome.FAILED},
    )


@pytest.mark.parametrize(
    ("policy", "event", "state", "mode"),
    [
        # the routed event goes to its state, ahead of the step's retry
        (FailurePolicy(2, Then.LOCK), "taut-early", "autonomous/free", Mode.AUTONOMOUS),
        # ... and ahead of a `failed:` state
        (FailurePolicy(0, goto="c"), "taut-early", "autonomous/free", Mode.AUTONOMOUS),
        # another named event, or none, follows the policy
        (FailurePolicy(0, Then.LOCK), "not-taut", "lock", Mode.LOCK),
        (FailurePolicy(0, Then.LOCK), "", "lock", Mode.LOCK),
        (FailurePolicy(1, Then.LOCK), "not-taut", "autonomous/a", Mode.AUTONOMOUS),
        (FailurePolicy(0, goto="c"), "timeout", "autonomous/c", Mode.AUTONOMOUS),
        # a terminal as the route
        (FailurePolicy(0, Then.LOCK), "stall", "given-up", Mode.TERMINAL),
    ],
)
def test_a_named_failure_event_follows_its_route_before_the_policy(
    policy: FailurePolicy, event: str, state: str, mode: Mode
) -> None:
    started: list[str] = []
    a = _automaton(_routed_plan(policy, {"taut-early": "free", "stall": "given-up"}), started)
    a.start()
    a.planned()
    records = a.unpredictable("skill-failure:x", event=event)
    assert records[0].dest == "autonomous/b~notbe"  # through NOT-BE as any fault
    assert (a.state, a.mode) == (state, mode)
    if state == "autonomous/free":
        assert records[-1].event == "recover" and records[-1].reason == f"{event}:b"
        assert started == ["a", "b", "free"] and a.retries["b"] == 0
        a.planned()
        assert a.state == "autonomous/c"
    if mode is Mode.TERMINAL:
        assert a.outcome is Outcome.FAILED


def test_a_route_to_an_unknown_state_is_refused_at_compile() -> None:
    with pytest.raises(AutomatonError, match="taut-early"):
        _automaton(_routed_plan(FailurePolicy(), {"taut-early": "nowhere"}))


def test_retry_budget_is_bounded_then_lock() -> None:
    a = _automaton(_plan(FailurePolicy(2, Then.LOCK)))
    a.start()
    for _ in range(2):
        a.planned()  # a -> b
        a.unpredictable("x")  # b -> NOT-BE -> a
        assert a.state == "autonomous/a"
    a.planned()
    a.unpredictable("x")
    assert a.state == "lock" and a.retries["b"] == 2


def test_operator_lock_manual_resume_and_named_resume() -> None:
    a = _automaton(_plan())
    a.start()
    a.planned()  # in b
    records = a.operator("lock")
    assert [r.dest for r in records] == ["autonomous/b~notbe", "lock"]
    assert records[0].reason == "operator-interrupt" and a.mode is Mode.LOCK
    a.operator("manual")
    assert a.mode is Mode.MANUAL
    a.operator("resume")
    assert a.state == "autonomous/b"  # the interrupted step
    a.operator("manual")  # straight from autonomous: through NOT-BE and lock
    assert a.state == "manual"
    a.operator("resume", "c")
    assert a.state == "autonomous/c"
    a.operator("abort")
    assert a.state == ABORTED and a.outcome is Outcome.ABORTED


def test_operator_actions_after_the_end_or_unknown_are_typed_errors() -> None:
    a = _automaton(_plan())
    a.start()
    with pytest.raises(AutomatonError):
        a.operator("jump")
    with pytest.raises(AutomatonError):
        a.operator("resume", "nowhere")
    a.operator("abort")
    with pytest.raises(AutomatonError) as err:
        a.operator("lock")
    assert err.value.state == ABORTED and err.value.event == "lock"


def test_a_skill_that_fails_to_start_leaves_the_machine_where_it_was() -> None:
    # b cannot start: advancing from a must not leave the machine in b without a skill.
    a = _automaton(_plan(FailurePolicy(0, Then.LOCK), boom={"b"}))
    a.start()
    records = a.planned()
    assert records[0].source == "autonomous/a" and records[0].dest == "autonomous/a~notbe"
    assert "skill-start-failed:b" in records[0].reason
    assert a.state == "lock"
    assert a.active_step is None


def test_planned_event_is_refused_outside_a_running_step() -> None:
    a = _automaton(_plan())
    with pytest.raises(AutomatonError):
        a.planned()
    a.start()
    a.operator("lock")
    with pytest.raises(AutomatonError):
        a.planned()
    with pytest.raises(AutomatonError):
        a.unpredictable("x")


@pytest.mark.parametrize("bad", ["lock", "a/b", "x~notbe", ABORTED])
def test_reserved_state_names_are_rejected(bad: str) -> None:
    plan = Plan("p", bad, {bad: StepSpec(bad, lambda: None, "end")}, {"end": Outcome.SUCCEEDED})
    with pytest.raises(AutomatonError):
        _automaton(plan)


def test_unknown_targets_are_rejected() -> None:
    plan = Plan("p", "a", {"a": StepSpec("a", lambda: None, "nowhere")}, {})
    with pytest.raises(AutomatonError, match="nowhere"):
        _automaton(plan)


def test_mode_of_locks_the_robots_a_step_does_not_drive() -> None:
    plan = Plan(
        "p",
        "a",
        {"a": StepSpec("a", lambda: _Skill("a"), "end", robots=("endobot_1",))},
        {"end": Outcome.SUCCEEDED},
    )
    a = _automaton(plan)
    a.start()
    assert a.mode_of("endobot_1") is Mode.AUTONOMOUS
    assert a.mode_of("endobot_2") is Mode.LOCK


def test_a_first_step_that_cannot_start_fails_the_run() -> None:
    a = _automaton(_plan(boom={"a"}))
    [record] = a.start()
    assert (record.source, record.dest, record.event) == ("idle", FAILED, "fail")
    assert "skill-start-failed:a" in record.reason and a.outcome is Outcome.FAILED


def test_a_resume_that_cannot_start_stays_locked() -> None:
    a = _automaton(_plan(boom={"c"}))
    a.start()
    a.operator("lock")
    [record] = a.operator("resume", "c")
    assert a.state == "lock" and record.event == "start-failed"


def _skipping_plan(first_enabled: bool = False) -> Plan:
    def make(name: str) -> Any:
        return lambda: _Skill(name)

    return Plan(
        "p",
        "a",
        {
            "a": StepSpec("a", make("a"), "b", enabled=first_enabled),
            "b": StepSpec("b", make("b"), "c", FailurePolicy(1, Then.LOCK)),
            "c": StepSpec("c", make("c"), "d", enabled=False),
            "d": StepSpec("d", make("d"), "end", enabled=False),
        },
        {"end": Outcome.SUCCEEDED},
    )


def test_a_step_whose_when_is_false_completes_at_once_without_a_skill() -> None:
    started: list[str] = []
    a = _automaton(_skipping_plan(), started)
    records = a.start()
    # the first step is skipped: the start and its planned event in the same call
    assert [(r.source, r.dest, r.event, r.reason) for r in records] == [
        ("idle", "autonomous/a", "start", ""),
        ("autonomous/a", "autonomous/b", "advance", "skipped:a (when: false)"),
    ]
    assert started == ["b"] and a.active_step is not None and a.active_step.name == "b"
    records = a.planned()  # b done: c and d are skipped in a row, up to the terminal
    assert [(r.dest, r.reason) for r in records] == [
        ("autonomous/c", "done:b"),
        ("autonomous/d", "skipped:c (when: false)"),
        ("end", "skipped:d (when: false)"),
    ]
    assert a.outcome is Outcome.SUCCEEDED and started == ["b"]


def test_a_retry_through_a_skipped_previous_step_reruns_the_current_one() -> None:
    started: list[str] = []
    a = _automaton(_skipping_plan(), started)
    a.start()
    records = a.unpredictable("invariant:tension")
    # b's previous step is the skipped a: the retry passes through a and runs b again
    assert [(r.dest, r.event) for r in records] == [
        ("autonomous/b~notbe", "fault"),
        ("autonomous/a", "retry"),
        ("autonomous/b", "advance"),
    ]
    assert started == ["b", "b"]


def test_skipped_steps_that_lead_to_each_other_are_refused() -> None:
    def make() -> Any:
        return _Skill("x")

    plan = Plan(
        "p",
        "a",
        {
            "a": StepSpec("a", make, "b"),
            "b": StepSpec("b", make, "c", enabled=False),
            "c": StepSpec("c", make, "b", enabled=False),
        },
        {"end": Outcome.SUCCEEDED},
    )
    with pytest.raises(AutomatonError, match="skipped"):
        _automaton(plan)
