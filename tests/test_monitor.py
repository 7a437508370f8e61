"""The safety monitor: the base-sensor tension estimate (7.6-7.9) and the emergency lock.

Oracles: PyBullet's own physics (a known force pushed on the tool tip with
``applyExternalForce``; a robot moving with no thread), the suture module's
``tip_wrench`` (itself checked against PyBullet in ``test_tension.py``), and a
thread modelled here as a spring on the ideal backend.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from suture_engine.runtime.automaton import FailurePolicy, Outcome, Plan, StepSpec, Then
from suture_engine.runtime.interpreter import Interpreter
from suture_engine.runtime.monitor import BaseSensorTension, SafetyLimits
from suture_engine.runtime.observation import (
    Command,
    Measurement,
    Observation,
    RobotCommand,
    RobotMeasurement,
    RobotObservation,
    StepResult,
)
from suture_engine.runtime.testing import IdealBackend, ScriptedSkill

HERE = Path(__file__).resolve().parent
PROCS = HERE / "procedures"


# ----------------------------------------------------------------- the estimate
def _obs(readings: dict[str, tuple[np.ndarray, np.ndarray]], tick: int = 0) -> Observation:
    robots = {
        n: RobotObservation(q, np.zeros(4), w, IdealBackend().reset().robots["endobot_1"].tool)
        for n, (q, w) in readings.items()
    }
    return Observation(tick, tick * 1e-3, robots, IdealBackend().geometry())


def test_estimate_is_the_suture_modules_tip_wrench_with_a_tare() -> None:
    from suture_engine.robot.params import E1
    from suture_engine.suture.tension import gravity_wrench, tip_wrench

    rng = np.random.default_rng(5)
    g = (1.2, -0.7, 9.7)
    prm = dataclasses.replace(E1, gravity=g)
    est = BaseSensorTension({"r": prm}, cutoff_hz=math.inf)
    q0 = np.array([0.1, -0.2, 0.3, 0.08])
    bias = rng.normal(size=6)
    s0 = gravity_wrench(q0, prm) + bias
    est.tare(Measurement(0, 0.0, {"r": RobotMeasurement(q0, s0)}))
    for k in range(10):
        q = np.array([*rng.uniform(-0.8, 0.8, 2), rng.uniform(-2, 2), rng.uniform(0.02, 0.18)])
        w = gravity_wrench(q, prm) + bias + rng.normal(scale=3.0, size=6)
        obs = _obs({"r": (q, w)}, k)
        out = est.estimate(obs)
        oracle = tip_wrench(w, q, prm, offset=bias)
        assert out["r"] == pytest.approx(float(np.linalg.norm(oracle[:3])), rel=1e-9)
        np.testing.assert_allclose(est.tip_wrench("r", obs.robots["r"]), oracle, atol=1e-9)


def test_estimate_low_pass_follows_a_step_with_the_cut_off_time_constant() -> None:
    est = BaseSensorTension(cutoff_hz=30.0)
    q = np.array([0.0, 0.2, 0.0, 0.1])
    rest = np.array([0.0, 0.0, -20.0, 0.0, 0.0, 0.0])
    est.tare(Measurement(0, 0.0, {"r": RobotMeasurement(q, rest)}))
    assert est.estimate(_obs({"r": (q, rest)}))["r"] == pytest.approx(0.0, abs=1e-12)
    pulled = rest + np.array([0.0, 2.0, 0.0, 0.0, 0.0, 0.0])
    tau = 1.0 / (2.0 * math.pi * 30.0)
    values = [est.estimate(_obs({"r": (q, pulled)}, k))["r"] for k in range(1, 60)]
    # continuous first order: 2 N (1 - e^(-t/tau)); the discrete (backward Euler) filter's
    # time constant lies between tau and tau + dt
    for k in (5, 10, 20):
        t = k * 1e-3
        low = 2.0 * (1.0 - math.exp(-t / (tau + 1e-3)))
        high = 2.0 * (1.0 - math.exp(-t / tau))
        assert low <= values[k - 1] <= high
    assert values[-1] == pytest.approx(2.0, rel=1e-4)


# ----------------------------------------------------------------- on PyBullet
pybullet = pytest.importorskip("pybullet")


def _pybullet_run(procedure: Path, sets: list[str], on_tick: Any, max_time_s: float) -> Any:
    from backends import registry
    from suture_engine.runtime.run import load_plan

    proc, plan = load_plan(procedure, sets)
    be = registry.create("pybullet")
    try:
        first = be.reset(proc.scene, 1)
        interp = Interpreter(
            plan,
            be,
            first,
            roles=proc.roles,
            params=proc.params,
            scene=proc.scene,
            max_time_s=max_time_s,
            tension_limit_N=float(proc.scene.tension_limit),
            on_tick=on_tick,
        )
        summary = interp.run(proc.name, "pybullet")
    finally:
        be.close()
    return interp, summary


def test_on_pybullet_a_robot_moving_through_its_workspace_reads_no_tension() -> None:
    """Both robots tour their workspace at 50 mm/s, no thread: the estimate stays < 0.3 N
    (what it still sees is the arms' motion wrench, neglected at low speed, 7.2.2)."""
    reach: list[float] = []

    def on_tick(it: Any) -> None:
        tips = [
            np.linalg.norm(np.asarray(it.backend.robots[n].true_tool_pose()[0])) for n in it.robots
        ]
        reach.append(float(max(tips)))

    _, summary = _pybullet_run(PROCS / "tour.yaml", [], on_tick, 12.0)
    assert summary.outcome == "succeeded"
    assert max(reach) - min(reach) > 0.02  # the tour really went somewhere
    assert summary.max_tension_N < 0.3
    assert summary.violations == []


def test_on_pybullet_a_known_tip_force_is_read_within_5_percent() -> None:
    """A hold; 0.5 s in, PyBullet pushes the stitcher's tool tip with a known force."""
    force = np.array([0.9, -0.6, 1.1])  # world frame [N], |F| = 1.54 N (the invariant: 2 N)
    seen: dict[float, float] = {}
    moments: list[float] = []

    def on_tick(it: Any) -> None:
        t = round(it._obs.t, 3)
        if t == 0.5:
            it.backend.apply_external_force("endobot_1", tuple(force), 1.0)
        seen[t] = it._tension["endobot_1"]
        if t == 1.2:
            moments.append(
                np.linalg.norm(it.tension.tip_wrench("endobot_1", it._obs.robots["endobot_1"])[3:])
            )

    interp, _ = _pybullet_run(PROCS / "steps.yaml", ["hold_time=1.8 s"], on_tick, 1.6)
    assert seen[0.45] < 0.02  # at rest, before the push
    expected = float(np.linalg.norm(force))
    for t in (1.0, 1.2, 1.4):
        assert seen[t] == pytest.approx(expected, rel=0.05)
    assert interp.monitor.violations == []
    # the load is a pure force at the tip: no moment left about it (7.9); the same force
    # 0.1 m off the tip would leave ~0.15 N*m
    assert moments[0] < 5e-3


# ----------------------------------------------------------------- emergency lock
class ThreadBackend(IdealBackend):
    """The ideal backend with a thread: a spring of ``stiffness`` [N/m] from the
    stitcher's start tool tip, slack up to ``slack`` [m]; its true tension is kept."""

    def __init__(self, stiffness: float = 200.0, slack: float = 0.0, **kw: Any) -> None:
        super().__init__(**kw)
        self.stiffness = stiffness
        self.slack = slack
        self.anchor: np.ndarray | None = None
        self.true_tension: list[float] = []

    def _tip(self) -> np.ndarray:
        from suture_engine.robot.kinematics import forward_kinematics

        return np.asarray(forward_kinematics(self.q["endobot_1"]).position)

    def reset(self, scene: Any = None, seed: int = 0) -> Measurement:
        m = super().reset(scene, seed)
        self.anchor = self._tip()
        self.true_tension = []
        return m

    def _force(self, robot: str) -> np.ndarray:
        f = super()._force(robot)
        if robot != "endobot_1" or self.anchor is None:
            return f
        d = self.anchor - self._tip()
        n = float(np.linalg.norm(d))
        tension = self.stiffness * max(0.0, n - self.slack)
        return f + (tension * d / n if n > 0.0 else 0.0)

    def step(self) -> None:
        super().step()
        self.true_tension.append(float(np.linalg.norm(self._force("endobot_1"))))


class Pull:
    """Retracts the stitcher's tool at ``speed`` [m/s] (insertion q4 decreasing)."""

    def __init__(self, speed: float = 0.01) -> None:
        self.speed = speed

    def start(self, ctx: Any) -> None:
        self._q = np.array(ctx.start.robots["endobot_1"].q)
        self._t0 = ctx.t0

    def step(self, ctx: Any, obs: Observation) -> StepResult:
        q = self._q.copy()
        q[3] -= self.speed * (obs.t - self._t0)
        return StepResult(Command({"endobot_1": RobotCommand.position(q)}))


def _pull_plan(invariant: Any = None) -> Plan:
    return Plan(
        "pull",
        "pull",
        {
            "pull": StepSpec(
                "pull",
                Pull,
                "end",
                FailurePolicy(2, Then.ABORT),
                robots=("endobot_1",),
                invariant=invariant,
            )
        },
        {"end": Outcome.SUCCEEDED},
    )


def test_emergency_lock_stops_a_pull_before_the_tension_limit() -> None:
    be = ThreadBackend()
    it = Interpreter(_pull_plan(), be, be.reset(), max_time_s=5.0, tension_limit_N=4.0)
    s = it.run("pull", "ideal")
    history = [(r.source, r.dest, r.event, r.kind) for r in it.automaton.history]
    assert history[1:] == [
        ("autonomous/pull", "autonomous/pull~notbe", "fault", "unpredictable"),
        ("autonomous/pull~notbe", "lock", "lock", "unpredictable"),
    ]  # the monitor locks, whatever the step's policy (retry 2 then abort)
    assert it.automaton.history[1].reason.startswith("emergency:tension-limit:endobot_1:")
    assert [v["invariant"] for v in s.violations] == ["tension-limit"]
    assert s.violations[0]["value"] >= 0.9 * 4.0
    # locked for good (no operator): the thread's true tension and the estimate stay below 4 N
    assert s.outcome == "failed" and "locked" in s.metrics["stopped"]
    assert 0.9 * 4.0 <= max(be.true_tension) < 4.0
    assert s.max_tension_N < 4.0


def test_without_the_tension_limit_the_same_pull_goes_past_it() -> None:
    """The control case: nothing else stops the pull (the test above can fail)."""
    be = ThreadBackend()
    it = Interpreter(_pull_plan(), be, be.reset(), max_time_s=5.0, tension_limit_N=None)
    it.run("pull", "ideal")
    assert max(be.true_tension) > 4.0


def test_the_emergency_acts_before_a_steps_looser_invariant() -> None:
    from suture_engine.runtime.monitor import Invariant

    be = ThreadBackend()
    plan = _pull_plan(Invariant(max_tension_N=3.9))
    it = Interpreter(plan, be, be.reset(), max_time_s=5.0, tension_limit_N=4.0)
    s = it.run("pull", "ideal")
    assert [v["invariant"] for v in s.violations] == ["tension-limit"]


class Faulty(IdealBackend):
    """The ideal backend whose stitcher's sensors misbehave on given ticks."""

    def __init__(self, nan: set[int] | None = None, stale: set[int] | None = None) -> None:
        super().__init__()
        self.nan = nan or set()
        self.stale = stale or set()

    def observe(self) -> Measurement:
        m = super().observe()
        r = m.robots["endobot_1"]
        if self.tick in self.nan:
            w = np.array(r.base_wrench)
            w[2] = math.nan
            r = RobotMeasurement(r.q, w, r.tool)
        if self.tick in self.stale:
            r = RobotMeasurement(r.q, r.base_wrench, r.tool, fault=True)
        return Measurement(m.tick, m.t, {**m.robots, "endobot_1": r})


def _hold_plan() -> Plan:
    return Plan(
        "p",
        "a",
        {
            "a": StepSpec(
                "a",
                lambda: ScriptedSkill("a", "success", after_s=0.1),
                "end",
                FailurePolicy(1, Then.ABORT),
                robots=("endobot_1",),
            )
        },
        {"end": Outcome.SUCCEEDED},
    )


def test_a_short_sensor_dropout_is_absorbed() -> None:
    be = Faulty(stale=set(range(30, 40)))  # 10 ms: the bound
    it = Interpreter(_hold_plan(), be, be.reset(), max_stale_s=0.01)
    s = it.run("p", "ideal")
    assert s.outcome == "succeeded" and s.violations == []


def test_a_long_sensor_dropout_locks() -> None:
    be = Faulty(stale=set(range(30, 45)))  # 15 ms
    it = Interpreter(_hold_plan(), be, be.reset(), max_stale_s=0.01)
    s = it.run("p", "ideal")
    assert [(v["invariant"], v["tick"]) for v in s.violations] == [("sensor-stale", 40)]
    assert it.automaton.history[-1].dest == "lock"
    assert s.outcome == "failed"


def test_a_non_finite_measurement_locks_without_a_crash(tmp_path: Path) -> None:
    from suture_engine.runtime.recorder import TraceRecorder
    from suture_engine.trace.reader import TraceReader

    be = Faulty(nan=set(range(20, 10_000)))  # blown up for good
    first = be.reset()
    rec = TraceRecorder(
        tmp_path / "t.mcap",
        procedure="p",
        seed=0,
        control_rate_hz=1000.0,
        robots=tuple(first.robots),
        backend="ideal",
        params={},
    )
    it = Interpreter(_hold_plan(), be, first, recorder=rec)
    s = it.run("p", "ideal")
    assert [(v["invariant"], v["tick"], v["robot"]) for v in s.violations] == [
        ("non-finite", 20, "endobot_1")
    ]
    assert it.automaton.history[-1].dest == "lock" and s.outcome == "failed"
    assert math.isfinite(s.max_tension_N)
    events = [m.data for m in TraceReader(tmp_path / "t.mcap").messages(["/events"])]
    emergencies = [e["detail"] for e in events if e["name"] == "emergency"]
    assert emergencies == ["emergency:non-finite:endobot_1:1>=0"]


def test_in_manual_the_tension_lock_leaves_the_surgeon_alone_but_a_blow_up_locks() -> None:
    """The base sensor cannot tell the surgeon's hand from the thread: a manual push past
    the limit's margin does not lock; a non-finite measurement in Manual does."""
    from suture_engine.runtime.operator import OperatorEvent

    class Ops:
        exhausted = False

        def __init__(self) -> None:
            self.sent: set[str] = set()

        def poll(self, t: float, state: str, step: str | None, mode: str) -> list[Any]:
            out = []
            if t >= 0.01 and "manual" not in self.sent:
                self.sent.add("manual")
                out.append(OperatorEvent("manual"))
            if t >= 0.05 and "force" not in self.sent:
                self.sent.add("force")
                out.append(
                    OperatorEvent("force", robot="endobot_1", force=(0.0, 0.0, 5.0), duration=0.1)
                )
            self.exhausted = len(self.sent) == 2
            return out

    be = Faulty(nan={300})
    it = Interpreter(
        _hold_plan(), be, be.reset(), operator=Ops(), tension_limit_N=4.0, max_time_s=1.0
    )
    s = it.run("p", "ideal")
    assert s.max_tension_N > 4.0  # the surgeon's push, read at the tip
    assert [(v["invariant"], v["tick"]) for v in s.violations] == [("non-finite", 300)]
    assert [(r.source, r.dest, r.kind) for r in it.automaton.history[-1:]] == [
        ("manual", "lock", "unpredictable")
    ]


def test_safety_limits_refuse_nonsense() -> None:
    with pytest.raises(ValueError):
        SafetyLimits(4.0, margin=1.0)
    with pytest.raises(ValueError):
        SafetyLimits(4.0, max_stale_s=-1.0)
    assert SafetyLimits(4.0, margin=0.25).lock_tension_N == pytest.approx(3.0)
    assert SafetyLimits(None).lock_tension_N is None


def test_the_tension_invariant_reads_every_robot_not_only_the_steps() -> None:
    """A step that drives the stitcher must not overload the strand the grasper holds: the
    suture's tension is one quantity, whichever robot's base sensor reads it."""
    from suture_engine.runtime.monitor import Invariant, Monitor

    q = np.array([0.1, 0.2, 0.0, 0.1])
    obs = _obs({n: (q, np.zeros(6)) for n in ("endobot_1", "endobot_2")})
    monitor = Monitor()
    inv = Invariant(max_tension_N=3.0)
    ok = {"endobot_1": 0.4, "endobot_2": 2.9}
    assert monitor.check(inv, obs, "slide-off", ok, {}, robots=("endobot_1",)) is None
    over = {"endobot_1": 0.4, "endobot_2": 5.0}
    found = monitor.check(inv, obs, "slide-off", over, {}, robots=("endobot_1",))
    assert found is not None
    assert (found.robot, found.invariant, found.value, found.bound) == (
        "endobot_2",
        "tension",
        5.0,
        3.0,
    )
    # other invariants still concern the step's own robots only: a force bound on the
    # stitcher is not broken by the grasper's reading
    force = Invariant(max_force_N=3.0)
    assert monitor.check(force, obs, "slide-off", over, {}, robots=("endobot_1",)) is None
