"""The tick loop: scripted operator scenarios checked in the trace, modes, monitor, timeouts."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from suture_engine.runtime.automaton import FailurePolicy, Outcome, Plan, StepSpec, Then
from suture_engine.runtime.interpreter import Interpreter
from suture_engine.runtime.monitor import Invariant
from suture_engine.runtime.observation import Observation, RobotObservation
from suture_engine.runtime.run import run_procedure
from suture_engine.runtime.testing import IdealBackend, ScriptedSkill
from suture_engine.trace.reader import TraceReader

HERE = Path(__file__).resolve().parent
PROCS = HERE / "procedures"


def _messages(trace: Path, topic: str) -> list[Any]:
    return list(TraceReader(trace).messages([topic]))


def _transitions(trace: Path) -> list[tuple[float, str, str, str]]:
    return [
        (m.log_time_ns / 1e9, m.data["source"], m.data["dest"], m.data["trigger"])
        for m in _messages(trace, "/transitions")
    ]


def _run(tmp_path: Path, ops: str | None, **kw: Any) -> Any:
    return run_procedure(
        PROCS / "steps.yaml",
        backend="ideal",
        out=tmp_path / "run",
        operator_file=PROCS / ops if ops else None,
        **kw,
    )


def test_scenario_lock_manual_resume_completes(tmp_path: Path) -> None:
    result = _run(tmp_path, "ops-manual.yaml")
    assert result.summary.outcome == "succeeded"
    assert result.summary.operator_events == 4
    steps = [(src, dst, trig) for _, src, dst, trig in _transitions(result.trace)]
    assert steps == [
        ("idle", "autonomous/prepare", "start"),
        ("autonomous/prepare", "autonomous/prepare~notbe", "fault"),
        ("autonomous/prepare~notbe", "lock", "lock"),
        ("lock", "manual", "manual"),
        ("manual", "autonomous/prepare", "resume"),
        ("autonomous/prepare", "autonomous/tighten", "advance"),
        ("autonomous/tighten", "autonomous/release", "advance"),
        ("autonomous/release", "finished", "advance"),
    ]
    ops = [m.data["action"] for m in _messages(result.trace, "/operator")]
    assert ops == ["lock", "manual", "force", "resume"]
    # In Manual only gravity is compensated: the surgeon's push moved the arm. In Lock
    # (before) and after the resume (hold) it stayed put.
    q = {
        round(m.log_time_ns / 1e6): np.array(m.data["position"])
        for m in _messages(result.trace, "/joint_state/endobot_1")
    }
    moved_in_manual = np.abs(q[500] - q[250]).max()
    assert moved_in_manual > 1e-2
    assert np.abs(q[200] - q[100]).max() < 1e-6
    assert np.abs(q[1000] - q[700]).max() < 1e-4
    modes = {
        round(m.log_time_ns / 1e6): m.data["mode"]
        for m in _messages(result.trace, "/command/endobot_1")
    }
    assert (modes[50], modes[150], modes[300], modes[600]) == (
        "autonomous",
        "lock",
        "manual",
        "autonomous",
    )


def test_scenario_injected_violation_notbe_retry_success(tmp_path: Path) -> None:
    result = _run(tmp_path, "ops-snag.yaml")
    s = result.summary
    assert s.outcome == "succeeded" and s.retries == 1
    assert [v["invariant"] for v in s.violations] == ["tension"]
    assert s.violations[0]["value"] > s.violations[0]["bound"] == 2.0
    steps = [(src, dst, trig) for _, src, dst, trig in _transitions(result.trace)]
    assert steps[1:6] == [
        ("autonomous/prepare", "autonomous/tighten", "advance"),
        ("autonomous/tighten", "autonomous/tighten~notbe", "fault"),
        ("autonomous/tighten~notbe", "autonomous/prepare", "retry"),
        ("autonomous/prepare", "autonomous/tighten", "advance"),
        ("autonomous/tighten", "autonomous/release", "advance"),
    ]
    events = _messages(result.trace, "/events")
    unpredictable = [e.data for e in events if e.data["kind"] == "unpredictable"]
    assert len(unpredictable) == 1 and "invariant:tension" in unpredictable[0]["detail"]
    # the 30 ms push of 3 N through the estimate's 30 Hz low-pass (tau 5.3 ms):
    # 3 N (1 - e^(-30/5.3)) = 2.99 N, a little less for the discrete filter
    assert 0.98 * 3.0 < s.max_tension_N < 3.0


def test_scenario_unrecoverable_violation_lock_then_operator_abort(tmp_path: Path) -> None:
    result = _run(tmp_path, "ops-abort.yaml")
    s = result.summary
    assert (s.outcome, s.final_state, s.retries) == ("aborted", "ABORTED", 2)
    steps = [(src, dst) for _, src, dst, _ in _transitions(result.trace)]
    assert ("autonomous/tighten~notbe", "lock") in steps
    assert steps[-1] == ("lock", "ABORTED")
    assert [m.data["action"] for m in _messages(result.trace, "/operator")][-1] == "abort"
    assert Path(result.summary_path).is_file()


def test_no_operator_and_exhausted_policy_stops_locked_as_failed(tmp_path: Path) -> None:
    plan = Plan(
        "p",
        "a",
        {"a": StepSpec("a", lambda: ScriptedSkill("a", "failure"), "end", FailurePolicy(0))},
        {"end": Outcome.SUCCEEDED},
    )
    be = IdealBackend()
    it = Interpreter(plan, be, be.reset())
    s = it.run("p", "ideal")
    assert (s.outcome, s.final_state) == ("failed", "lock")
    assert "waiting for an operator" in s.metrics["stopped"]


def test_the_summary_names_the_step_and_reason_of_the_last_fault() -> None:
    """A run that locks says where and why (the last unpredictable event); a run whose
    failures were all retried away keeps the last one; a clean run has none."""
    retry = FailurePolicy(1)
    plan = Plan(
        "p",
        "a",
        {
            "a": StepSpec("a", lambda: ScriptedSkill("a", after_s=0.02), "b", retry),
            "b": StepSpec("b", lambda: ScriptedSkill("b", "failure", after_s=0.05), "end", retry),
        },
        {"end": Outcome.SUCCEEDED},
    )
    be = IdealBackend()
    s = Interpreter(plan, be, be.reset()).run("p", "ideal")
    assert (s.outcome, s.final_state) == ("failed", "lock")
    assert s.last_fault is not None and s.last_fault["step"] == "b"
    assert s.last_fault["reason"].startswith("skill-failure")
    # b failed twice (once retried through a): the second time is the last
    assert s.last_fault["t_s"] == pytest.approx(0.02 + 0.05 + 0.02 + 0.05, abs=0.01)
    assert s.to_dict()["last_fault"]["step"] == "b"
    ScriptedSkill.starts.clear()
    plan = Plan(
        "p",
        "a",
        {"a": StepSpec("a", lambda: ScriptedSkill("a", fail_first=1), "end", FailurePolicy(1))},
        {"end": Outcome.SUCCEEDED},
    )
    s = Interpreter(plan, be, be.reset()).run("p", "ideal")
    assert s.outcome == "succeeded" and s.last_fault is not None and s.last_fault["step"] == "a"
    ok = Plan("p", "a", {"a": StepSpec("a", lambda: ScriptedSkill("a"), "end", retry)},
              {"end": Outcome.SUCCEEDED})  # fmt: skip
    assert Interpreter(ok, be, be.reset()).run("p", "ideal").last_fault is None


def test_skill_exception_is_an_unpredictable_event_not_a_crash() -> None:
    plan = Plan(
        "p",
        "a",
        {
            "a": StepSpec(
                "a", lambda: ScriptedSkill("a", "raise"), "end", FailurePolicy(0, Then.FAIL)
            )
        },
        {"end": Outcome.SUCCEEDED},
    )
    be = IdealBackend()
    it = Interpreter(plan, be, be.reset())
    s = it.run("p", "ideal")
    assert s.outcome == "failed" and s.final_state == "FAILED"
    reasons = [r.reason for r in it.automaton.history if r.kind == "unpredictable"]
    assert reasons and "RuntimeError" in reasons[0]


def test_timeout_is_an_unpredictable_event() -> None:
    plan = Plan(
        "p",
        "a",
        {
            "a": StepSpec(
                "a",
                lambda: ScriptedSkill("a", "never"),
                "end",
                FailurePolicy(0, Then.ABORT),
                timeout_s=0.05,
            )
        },
        {"end": Outcome.SUCCEEDED},
    )
    be = IdealBackend()
    it = Interpreter(plan, be, be.reset())
    s = it.run("p", "ideal")
    assert s.outcome == "aborted"
    fault = next(r for r in it.automaton.history if r.event == "fault")
    assert fault.reason == "timeout"
    assert s.sim_time_s == pytest.approx(0.05, abs=1.5e-3)


def test_workspace_and_singularity_invariants() -> None:
    from suture_engine.runtime.monitor import Monitor

    obs = Observation(
        3,
        0.003,
        {
            "r": RobotObservation(
                np.array([0.0, 1.55, 0.0, 0.1]),
                np.zeros(4),
                np.zeros(6),
                dataclasses.replace(IdealBackend().reset().robots["endobot_1"].tool),
            )
        },
        IdealBackend().geometry(),
    )
    m = Monitor()
    inv = Invariant(singularity_margin_rad=0.05)
    v = m.check(inv, obs, "s", {"r": 0.0}, {})
    assert v is not None and v.invariant == "singularity"
    assert v.value == pytest.approx(np.pi / 2 - 1.55)
    inv = Invariant(q_max=(1.0, 1.0, 1.0, 1.0))
    v = m.check(inv, obs, "s", {"r": 0.0}, {})
    assert v is not None and (v.invariant, v.bound) == ("workspace", 1.0)
    inv = Invariant(workspace_min=(-1.0, -1.0, -1.0), workspace_max=(1.0, 1.0, 0.0))
    v = m.check(inv, obs, "s", {"r": 0.0}, {})
    # tip z = q4 cos(q1) cos(q2) > 0 in the base frame (identity base): outside the box
    assert v is not None and v.invariant == "workspace"
    assert m.check(Invariant(max_tension_N=5.0), obs, "s", {"r": 4.9}, {}) is None
    assert m.check(Invariant(max_tension_N=5.0), obs, "s", {"r": 5.1}, {}) is not None
    assert m.check(None, obs, "s", {"r": 9.0}, {}) is None  # no invariant, nothing to check


def test_skills_observe_estimated_velocity_and_no_ground_truth() -> None:
    seen: list[Observation] = []

    class Spy(ScriptedSkill):
        def step(self, ctx: Any, obs: Any) -> Any:
            seen.append(obs)
            return super().step(ctx, obs)

    plan = Plan(
        "p",
        "a",
        {"a": StepSpec("a", lambda: Spy("a", "success", after_s=0.2), "end")},
        {"end": Outcome.SUCCEEDED},
    )
    be = IdealBackend(q0={"endobot_1": (0.0, 0.2, 0.0, 0.12)})
    it = Interpreter(plan, be, be.reset())
    be.apply_external_force("endobot_1", (0.0, 0.0, 2.0), 0.1)  # it moves: nonzero velocity
    it.run("p", "ideal")
    fields = {f.name for f in dataclasses.fields(Observation)}
    assert fields == {"tick", "t", "robots", "scene"}
    robot_fields = {f.name for f in dataclasses.fields(RobotObservation)}
    assert robot_fields == {"q", "qd", "base_wrench", "tool"}
    # the velocity is the washout filter's estimate from the encoders, not the simulator's
    from suture_engine.control.filters import WashoutFilter

    wf = WashoutFilter(150.0, 1e-3)
    for obs in seen[:120]:
        est = wf.update(obs.robots["endobot_1"].q)
        np.testing.assert_allclose(obs.robots["endobot_1"].qd, est, atol=1e-12)
    assert max(abs(o.robots["endobot_1"].qd).max() for o in seen) > 1e-4


def test_manual_mode_uses_the_interrupted_steps_fixture_when_it_has_one() -> None:
    from suture_engine.runtime.observation import Command, RobotCommand
    from suture_engine.runtime.operator import OperatorEvent

    class Fixture(ScriptedSkill):
        """Holds the pose; in Manual a stiff joint spring (a stand-in fixture) plus gravity."""

        def manual_step(self, ctx: Any, obs: Any) -> Command:
            from suture_engine.robot import endobot

            q = obs.robots["endobot_1"].q
            qd = obs.robots["endobot_1"].qd
            tau = endobot.gravity_vector(q) - 50.0 * (q - self._hold["endobot_1"]) - 2.0 * qd
            return Command({"endobot_1": RobotCommand.torque(tau)})

    class Ops:
        def __init__(self) -> None:
            self.sent = False

        def poll(self, t: float, state: str, step: str | None, mode: str) -> list[Any]:
            if t >= 0.01 and not self.sent:
                self.sent = True
                return [OperatorEvent("manual")]
            return []

    moved = {}
    for name, cls in (("plain", ScriptedSkill), ("fixture", Fixture)):
        plan = Plan(
            "p",
            "a",
            {"a": StepSpec("a", lambda cls=cls: cls("a", "never"), "end")},
            {"end": Outcome.SUCCEEDED},
        )
        be = IdealBackend()
        it = Interpreter(plan, be, be.reset(), operator=Ops(), max_time_s=0.3)
        q0 = be.q["endobot_1"].copy()
        be.apply_external_force("endobot_1", (0.0, 0.5, 0.0), 0.3)
        s = it.run("p", "ideal")
        assert s.final_state == "manual"
        moved[name] = float(np.abs(be.q["endobot_1"] - q0).max())
    assert moved["plain"] > 10 * moved["fixture"] > 0.0


def test_simulated_hand_drags_the_tool_in_manual_and_replays(tmp_path: Path) -> None:
    from suture_engine.runtime.run import replay_trace

    result = _run(tmp_path, "ops-push.yaml")
    assert result.summary.outcome == "succeeded"
    [push] = [m.data for m in _messages(result.trace, "/operator") if m.data["action"] == "push"]
    assert "velocity=[0.0, 0.02, 0.0]" in push["detail"] and "stiffness=100.0" in push["detail"]
    q = {
        round(m.log_time_ns / 1e6): np.array(m.data["position"])
        for m in _messages(result.trace, "/joint_state/endobot_1")
    }
    assert np.abs(q[450] - q[200]).max() > 1e-3  # dragged while in Manual
    check = replay_trace(result.trace, check=True)
    assert check.ok, check.diff


def test_summary_has_no_nan() -> None:
    from suture_engine.runtime.summary import RunSummary

    s = RunSummary(
        "p",
        "succeeded",
        "end",
        1.0,
        1.0,
        1.0,
        1e3,
        0.0,
        None,
        [],
        0,
        0,
        {"k": float("nan"), "x": [1.0, float("inf")]},
    )
    d = s.to_dict()
    assert d["metrics"] == {"k": None, "x": [1.0, None]}


@pytest.mark.parametrize(("mode", "low", "high"), [("lock", 0.0, 5e-3), ("manual", 5e-2, 1.0)])
def test_on_pybullet_lock_holds_the_pose_and_manual_gives_way(
    tmp_path: Path, mode: str, low: float, high: float
) -> None:
    """Lock regulates the captured pose (4.44); Manual only compensates gravity (5.1)."""
    ops = tmp_path / "ops.yaml"
    ops.write_text(
        "events:\n"
        "  - {at: 0.05 s, do: lock}\n"
        f"  - {{at: 0.07 s, do: {mode}}}\n"
        "  - {at: 0.1 s, do: force, robot: endobot_1, force: [0.0, 5.0, 0.0], duration: 100 ms}\n"
        "  - {at: 0.6 s, do: abort}\n",
        encoding="utf-8",
    )
    result = run_procedure(
        PROCS / "steps.yaml", backend="pybullet", operator_file=ops, out=tmp_path / "run"
    )
    assert result.summary.outcome == "aborted"
    q = {
        round(m.log_time_ns / 1e6): np.array(m.data["position"])
        for m in _messages(result.trace, "/joint_state/endobot_1")
    }
    drift = max(float(np.abs(q[k] - q[50]).max()) for k in range(100, 600))
    assert low < drift < high


def test_operator_takes_one_robot_while_the_other_works(tmp_path: Path) -> None:
    result = _run(tmp_path, "ops-one-robot.yaml")
    assert result.summary.outcome == "succeeded"
    steps = [(src, dst, trig) for _, src, dst, trig in _transitions(result.trace)]
    assert steps[:3] == [
        ("idle", "autonomous/prepare", "start"),
        ("autonomous/prepare", "autonomous/tighten", "advance"),
        ("autonomous/tighten", "autonomous/release", "advance"),
    ]
    assert ("autonomous/release", "autonomous/release~notbe", "fault") in steps
    assert steps[-2:] == [
        ("lock", "autonomous/release", "resume"),
        ("autonomous/release", "finished", "advance"),
    ]
    faults = [
        m.data["detail"] for m in _messages(result.trace, "/events") if m.data["name"] == "fault"
    ]
    assert faults == ["operator-holds:endobot_2"]
    mode2 = {
        round(m.log_time_ns / 1e6): m.data["mode"]
        for m in _messages(result.trace, "/command/endobot_2")
    }
    mode1 = {
        round(m.log_time_ns / 1e6): m.data["mode"]
        for m in _messages(result.trace, "/command/endobot_1")
    }
    assert (mode1[300], mode2[300]) == ("autonomous", "manual")
    q2 = {
        round(m.log_time_ns / 1e6): np.array(m.data["position"])
        for m in _messages(result.trace, "/joint_state/endobot_2")
    }
    assert np.abs(q2[400] - q2[100]).max() > 1e-3  # the surgeon moved the grasper


def test_summary_is_written_atomically(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import json

    from suture_engine.runtime import summary as summary_module
    from suture_engine.runtime.summary import RunSummary, write_summary

    s = RunSummary("p", "succeeded", "end", 1.0, 2.0, 0.5, 1e3, 0.1, 4.7, [], 0, 0)
    target = tmp_path / "summary.json"
    write_summary(target, s)
    assert json.loads(target.read_text())["outcome"] == "succeeded"

    def boom(*args: Any, **kwargs: Any) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(summary_module.json, "dump", boom)
    with pytest.raises(OSError):
        write_summary(target, dataclasses.replace(s, outcome="failed"))
    assert json.loads(target.read_text())["outcome"] == "succeeded"  # old file intact
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]  # no temp left behind


def test_use_states_are_inlined_and_run_in_order(tmp_path: Path) -> None:
    from suture_engine.language.loader import load
    from suture_engine.runtime.plan import compile_procedure

    loaded = load(PROCS / "nested.yaml")
    assert loaded.problems == []
    plan = compile_procedure(loaded.procedure)
    assert plan.initial == "stitcher-part.first"
    assert plan.steps["stitcher-part.second"].on_done == "grasper-part.first"
    assert plan.steps["grasper-part.second"].on_done == "finished"
    assert plan.steps["grasper-part.first"].robots == ("endobot_2",)
    assert set(plan.terminals) == {"finished"}  # the sub-procedure's success is inlined
    result = run_procedure(PROCS / "nested.yaml", backend="ideal", out=tmp_path / "run")
    assert result.summary.outcome == "succeeded"
    dests = [dst for _, _, dst, _ in _transitions(result.trace)]
    assert dests == [
        "autonomous/stitcher-part.first",
        "autonomous/stitcher-part.second",
        "autonomous/grasper-part.first",
        "autonomous/grasper-part.second",
        "finished",
    ]


def test_a_use_states_failed_target_catches_the_sub_procedures_failed_end(
    tmp_path: Path,
) -> None:
    """``on: {failed: recover}`` on a ``use:`` state: the sub-procedure's ``failed``
    terminal leads to ``recover`` instead of ending the run (which a sub-procedure's
    ``failed`` terminal does by default, as ``give-up.yaml`` alone shows)."""
    from suture_engine.language.loader import load
    from suture_engine.runtime.plan import compile_procedure

    loaded = load(PROCS / "caught.yaml")
    assert loaded.problems == []
    plan = compile_procedure(loaded.procedure)
    assert plan.steps["try.first"].on_done == "recover"
    assert set(plan.terminals) == {"recovered", "finished"}
    result = run_procedure(PROCS / "caught.yaml", backend="ideal", out=tmp_path / "run")
    assert result.summary.outcome == "aborted"  # the catching branch's own terminal
    dests = [dst for _, _, dst, _ in _transitions(result.trace)]
    assert dests == ["autonomous/try.first", "autonomous/recover", "recovered"]
    alone = run_procedure(PROCS / "give-up.yaml", backend="ideal", out=tmp_path / "alone")
    assert alone.summary.outcome == "failed"


@pytest.mark.parametrize("then", ["lock", "abort"])
def test_a_use_states_failure_policy_retries_its_sub_procedure_then_locks_or_aborts(
    tmp_path: Path, then: str
) -> None:
    """``on: {failed: {retry: 1, then: ...}}`` on a ``use:`` state: the sub-procedure's
    ``failed`` terminal is a step that fails at once (an unpredictable event); its NOT-BE
    state runs the sub-procedure again from its first step, once, then locks the robots
    for the operator (none here: the run stops ``failed``) or aborts."""
    from suture_engine.trace.reader import TraceReader

    out = tmp_path / then
    result = run_procedure(PROCS / "retried.yaml", backend="ideal", out=out, sets=[f"then={then}"])
    moves = [(src, dst, trig) for _, src, dst, trig in _transitions(result.trace)]
    once = [
        ("autonomous/try.first", "autonomous/try.gave-up", "advance"),
        ("autonomous/try.gave-up", "autonomous/try.gave-up~notbe", "fault"),
    ]
    assert moves[1:3] == once and moves[4:6] == once
    assert moves[3] == ("autonomous/try.gave-up~notbe", "autonomous/try.first", "retry")
    assert result.summary.retries == 1
    events = [m.data for m in TraceReader(out / "trace.mcap").messages(["/events"])]
    assert any("ended in 'gave-up'" in (e["detail"] or "") for e in events)
    if then == "lock":
        assert moves[-1] == ("autonomous/try.gave-up~notbe", "lock", "lock")
        assert result.summary.outcome == "failed"
        assert result.summary.metrics["stopped"].startswith("locked")
    else:
        assert moves[-1][2] == "abort" and result.summary.outcome == "aborted"


@pytest.mark.parametrize("extra", [False, True])
def test_when_false_skips_skill_and_use_states_and_says_so(tmp_path: Path, extra: bool) -> None:
    from suture_engine.language.loader import load
    from suture_engine.runtime.plan import compile_procedure

    sets = [f"extra={str(extra).lower()}"]
    result = run_procedure(PROCS / "when.yaml", backend="ideal", out=tmp_path / "run", sets=sets)
    assert result.summary.outcome == "succeeded"
    moves = [(src, dst) for _, src, dst, _ in _transitions(result.trace)]
    details = [
        m.data["detail"] for m in _messages(result.trace, "/events") if m.data["name"] == "advance"
    ]
    skipped = [d for d in details if d and d.startswith("skipped:")]
    if extra:
        assert skipped == []
        assert ("autonomous/maybe-use.second", "autonomous/last") in moves
        assert result.summary.sim_time_s == pytest.approx(
            0.04 + 0.03 + 0.05 + 0.05 + 0.02, abs=0.01
        )
        return
    assert skipped == [
        "skipped:maybe-first (when: false)",
        "skipped:maybe-skill (when: false)",
        "skipped:maybe-use (when: false)",
    ]
    assert moves == [
        ("idle", "autonomous/maybe-first"),
        ("autonomous/maybe-first", "autonomous/always"),
        ("autonomous/always", "autonomous/maybe-skill"),
        ("autonomous/maybe-skill", "autonomous/maybe-use"),
        ("autonomous/maybe-use", "autonomous/last"),
        ("autonomous/last", "finished"),
    ]
    # only the enabled holds took time (30 ms + 20 ms); the sub-procedure was not inlined
    assert result.summary.sim_time_s == pytest.approx(0.05, abs=0.005)
    plan = compile_procedure(load(PROCS / "when.yaml").procedure)
    assert not any(name.startswith("maybe-use.") for name in plan.steps)


def test_every_step_gets_the_runs_first_observation_as_its_rest() -> None:
    """``SkillContext.rest`` is the run's first tick (where the run's tension estimate is
    tared), for the first step and a later one alike; ``start`` is each step's own."""
    contexts: list[Any] = []

    class Spy(ScriptedSkill):
        def start(self, ctx: Any) -> None:
            contexts.append(ctx)
            super().start(ctx)

    plan = Plan(
        "p",
        "a",
        {
            "a": StepSpec("a", lambda: Spy("a", "success", after_s=0.05), "b"),
            "b": StepSpec("b", lambda: Spy("b", "success", after_s=0.05), "end"),
        },
        {"end": Outcome.SUCCEEDED},
    )
    be = IdealBackend(q0={"endobot_1": (0.0, 0.2, 0.0, 0.12)})
    it = Interpreter(plan, be, be.reset())
    it.run("p", "ideal")
    assert [c.step for c in contexts] == ["a", "b"]
    first, second = contexts
    assert first.rest is not None and first.rest.tick == 0 and first.start.tick == 0
    assert second.rest is first.rest and second.start.tick > 40
