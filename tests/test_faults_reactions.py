"""Each fault kind on a short procedure: absorbed, or an unpredictable event the automaton
reacts to; the fault is in the trace; the same seed gives the same trace, byte for byte.

The procedure is ``tests/procedures/reach.yaml`` on the ``ideal`` backend: ``approach``
(move-to, tension bound 2 N, retry 2 then lock), ``settle`` (hold), ``retreat``
(move-to, retry 1 then abort). Grasp slip and snag run on a thread-less stand-in
backend that has the surgical backend's hooks (it records the calls).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, ClassVar

import pytest
from typer.testing import CliRunner

from backends import registry
from suture_engine.faults.record import read_faults
from suture_engine.runtime.run import RunResult, run_procedure
from suture_engine.runtime.testing import IdealBackend
from suture_engine.trace.reader import TraceReader

ROOT = Path(__file__).resolve().parent.parent
REACH = ROOT / "tests" / "procedures" / "reach.yaml"


def _run(tmp_path: Path, *faults: str, seed: int = 0, name: str = "run", **kw: Any) -> RunResult:
    return run_procedure(
        REACH,
        backend=kw.pop("backend", "ideal"),
        seed=seed,
        out=tmp_path / name,
        faults=faults,
        max_time_s=30.0,
        **kw,
    )


def _events(result: RunResult) -> list[tuple[float, str, str]]:
    return [
        (m.log_time_ns * 1e-9, m.data["name"], m.data.get("detail") or "")
        for m in TraceReader(result.trace).messages(["/events"])
        if not str(m.data["name"]).startswith("fault:")
    ]


def _reasons(result: RunResult) -> list[str]:
    return [detail for _, name, detail in _events(result) if name in ("fault", "emergency")]


@pytest.mark.parametrize(
    "spec",
    ["ft.noise=0.05 N", "enc.noise=0.0002 rad", "ft.delay=2 ms", "ft.dropout@0.5 s for 3 ms"],
)
def test_small_sensor_faults_are_absorbed(tmp_path: Path, spec: str) -> None:
    result = _run(tmp_path, spec)
    assert result.summary.outcome == "succeeded"
    assert result.summary.retries == 0 and _reasons(result) == []
    records = read_faults(result.trace)
    assert records and records[0].phase == "start"
    assert records[0].kind == spec.split(".")[1].split("=")[0].split("@")[0]


def test_a_bias_beyond_the_bound_is_a_tension_event_then_retries_then_lock(
    tmp_path: Path,
) -> None:
    result = _run(tmp_path, "ft.bias=3 N@0.5 s")
    s = result.summary
    assert (s.outcome, s.final_state, s.retries) == ("failed", "lock", 2)
    reasons = _reasons(result)
    assert reasons and all(r.startswith("invariant:tension:endobot_1") for r in reasons)
    (start,) = [r for r in read_faults(result.trace) if r.phase == "start"]
    assert (start.t, start.target, start.params["value"]) == (pytest.approx(0.5), "ft", 3.0)
    first = min(t for t, name, _ in _events(result) if name == "fault")
    assert 0.5 <= first < 0.6  # the event follows the onset


def test_a_long_dropout_is_a_stale_sensor_and_locks(tmp_path: Path) -> None:
    result = _run(tmp_path, "endobot_1:ft.dropout@0.5 s for 50 ms")
    assert result.summary.final_state == "lock"
    assert any("sensor" in r for r in _reasons(result))
    phases = [(r.phase, round(r.t, 3)) for r in read_faults(result.trace)]
    assert phases[0] == ("start", 0.5)


def test_a_locked_joint_fails_the_move_then_the_policy_locks(tmp_path: Path) -> None:
    result = _run(tmp_path, "endobot_1:pitch.joint-lock@0.1 s")
    s = result.summary
    assert (s.outcome, s.final_state, s.retries) == ("failed", "lock", 2)
    assert all(r.startswith("skill-failure") or r == "timeout" for r in _reasons(result))
    (rec,) = read_faults(result.trace)
    assert rec.target == "pitch" and "q_lock_endobot_1" in rec.params


def test_a_joint_locked_in_retreat_aborts_by_the_retreats_policy(tmp_path: Path) -> None:
    result = _run(tmp_path, "endobot_1:pitch.joint-lock@state retreat")
    assert (result.summary.outcome, result.summary.retries) == ("aborted", 1)
    (rec,) = read_faults(result.trace)
    assert rec.trigger == "when retreat" and rec.t > 1.0


def test_a_weak_joint_sags_and_the_move_fails(tmp_path: Path) -> None:
    result = _run(tmp_path, "endobot_1:insertion.joint-weak=0.0@0.1 s")
    assert result.summary.final_state == "lock" and result.summary.retries == 2


@pytest.mark.parametrize(
    ("spec", "reason"),
    [("blow-up@0.5 s", "non-finite"), ("blow-up@0.5 s;mode=energy", "invariant:tension")],
)
def test_a_blow_up_locks_at_once(tmp_path: Path, spec: str, reason: str) -> None:
    result = _run(tmp_path, spec)
    s = result.summary
    assert s.outcome == "failed" and s.final_state == "lock"
    assert s.sim_time_s < 0.7  # locked within 0.2 s of the onset, run stopped
    reasons = _reasons(result)
    assert reasons and reason in reasons[0]
    summary = json.loads(result.summary_path.read_text())
    assert summary["max_tension_N"] == summary["max_tension_N"]  # no NaN in the summary
    estimates = [
        m.data["tension_N"] for m in TraceReader(result.trace).messages(["/tension/estimated"])
    ]
    finite = [v for v in estimates if v is not None and v == v]
    assert max(finite) < s.tension_limit_N  # locked before the scene's limit


class Threaded(IdealBackend):
    """An ideal backend standing in for one with a thread: it records the hook calls."""

    name = "threaded"
    calls: ClassVar[list[tuple[str, int, Any]]] = []

    def inject_grasp_slip(self, robot: str) -> None:
        Threaded.calls.append(("slip", self.tick, robot))

    def inject_snag(self, extra_friction_N: float, duration_s: float) -> None:
        Threaded.calls.append(("snag", self.tick, (extra_friction_N, duration_s)))


def test_grasp_slip_and_snag_reach_the_backend_hooks_at_their_trigger(tmp_path: Path) -> None:
    registry.register("threaded", Threaded)
    Threaded.calls = []
    result = _run(
        tmp_path,
        "endobot_2:grasp-slip@state settle",
        "snag=2 N@0.3 s for 100 ms",
        backend="threaded",
    )
    assert result.summary.outcome == "succeeded"  # the stand-in has no thread to lose
    settle = next(t for t, name, d in _events(result) if d == "done:approach")
    kinds = {(c[0]): c for c in Threaded.calls}
    assert kinds["snag"] == ("snag", 300, (2.0, 0.1))
    assert kinds["slip"][2] == "endobot_2"
    assert kinds["slip"][1] * 1e-3 == pytest.approx(settle, abs=2e-3)
    assert sorted((r.kind, r.phase) for r in read_faults(result.trace)) == [
        ("grasp-slip", "start"),
        ("snag", "end"),
        ("snag", "start"),
    ]


def test_a_fault_the_backend_cannot_simulate_is_refused_before_the_run(tmp_path: Path) -> None:
    from suture_engine.faults.support import FaultNotSupported

    with pytest.raises(FaultNotSupported, match="ideal backend cannot simulate a snag"):
        _run(tmp_path, "snag=2 N@0.3 s")
    assert not (tmp_path / "run").exists()


def test_same_seed_same_faults_byte_identical_trace(tmp_path: Path) -> None:
    faults = ("ft.noise=0.05 N", "enc.dropout@rate 3/s for 2 ms", "ft.bias=0.2 N@p 0.8 in 1 s")
    a = _run(tmp_path, *faults, seed=11, name="a")
    b = _run(tmp_path, *faults, seed=11, name="b")
    c = _run(tmp_path, *faults, seed=12, name="c")
    assert a.trace.read_bytes() == b.trace.read_bytes()
    assert a.trace.read_bytes() != c.trace.read_bytes()
    ra, rc = read_faults(a.trace), read_faults(c.trace)
    assert len([r for r in ra if r.kind == "dropout"]) >= 2  # the random stream did fire
    assert [(r.kind, r.t) for r in ra] != [(r.kind, r.t) for r in rc]
    meta = TraceReader(a.trace).meta
    extra = meta.get("extra") if isinstance(meta.get("extra"), dict) else meta
    assert extra["faults"][0] == "ft.noise=0.05 N"


@pytest.mark.parametrize(
    ("fault", "code", "needle"),
    [
        ("ft.bais=1 N", 2, "at column 4"),
        ("ft.bias=1 s", 1, "expected length*mass/time^2 (N), found time"),
        ("snag=1 N", 2, "the ideal backend cannot simulate a snag"),
        ("endobot_9:ft.noise=1 N", 1, "no robot 'endobot_9'"),
        ("ft.noise=1 N@state nowhere", 1, "no step 'nowhere'"),
    ],
)
def test_cli_refuses_a_bad_fault_before_running(
    tmp_path: Path, fault: str, code: int, needle: str
) -> None:
    from suture_engine.cli import app

    out = tmp_path / "out"
    res = CliRunner().invoke(
        app, ["run", str(REACH), "--backend", "ideal", "--out", str(out), "--fault", fault]
    )
    text = " ".join(res.output.split())
    assert res.exit_code == code, res.output
    assert needle in text and "Traceback" not in res.output
    assert not out.exists()


def test_cli_runs_with_faults_and_exits_by_outcome(tmp_path: Path) -> None:
    from suture_engine.cli import app

    out = tmp_path / "out"
    args = ["run", str(REACH), "--backend", "ideal", "--out", str(out)]
    ok = CliRunner().invoke(app, [*args, "--fault", "ft.noise=0.02 N", "--fault", "ft.delay=2 ms"])
    assert ok.exit_code == 0, ok.output
    assert [r.kind for r in read_faults(out / "trace.mcap")] == ["noise", "delay"]
    bad = CliRunner().invoke(app, [*args, "--fault", "blow-up@0.2 s"])
    assert bad.exit_code == 1 and "lock" in bad.output


def test_a_faulted_run_replays_and_checks(tmp_path: Path) -> None:
    """The trace holds the faulted measurements: a replay reproduces the engine's commands
    and events (the fault records themselves are not compared: nothing re-injects them)."""
    from suture_engine.runtime.run import replay_trace

    result = _run(tmp_path, "ft.noise=0.05 N", "endobot_1:pitch.joint-lock@state retreat")
    assert read_faults(result.trace)
    replay = replay_trace(result.trace, check=True)
    assert replay.ok, replay.diff
    assert replay.summary.outcome == result.summary.outcome == "aborted"


@pytest.mark.parametrize(
    ("spec", "reason"),
    [("blow-up@0.3 s", "non-finite"), ("blow-up@0.3 s;mode=energy", "invariant:tension")],
)
def test_blow_ups_on_pybullet_lock_below_the_limit(tmp_path: Path, spec: str, reason: str) -> None:
    result = _run(tmp_path, spec, backend="pybullet")
    s = result.summary
    assert (s.outcome, s.final_state) == ("failed", "lock") and s.sim_time_s < 0.5
    assert reason in _reasons(result)[0]
    assert s.max_tension_N < s.tension_limit_N


@pytest.mark.slow
def test_same_seed_same_faults_byte_identical_trace_on_pybullet(tmp_path: Path) -> None:
    faults = ("ft.noise=0.05 N", "enc.dropout@rate 3/s for 2 ms", "endobot_1:yaw.joint-weak=0.5")
    a = _run(tmp_path, *faults, seed=4, name="a", backend="pybullet")
    b = _run(tmp_path, *faults, seed=4, name="b", backend="pybullet")
    assert a.trace.read_bytes() == b.trace.read_bytes()


@pytest.mark.slow
def test_grasp_slip_and_snag_on_the_surgical_backend(tmp_path: Path) -> None:
    """The surgical backend's hooks take the faults at their trigger (the record says whether
    the jaw held anything); the run goes on and its true tension stays under the limit."""
    from suture_engine.faults.campaign import trace_violations

    result = run_procedure(
        ROOT / "tests" / "procedures" / "skills-grasp-rotate.yaml",
        backend="pybullet-surgical",
        out=tmp_path / "run",
        faults=["endobot_2:grasp-slip@state rotate+0.2 s", "snag=3 N@state rotate for 300 ms"],
        max_time_s=20.0,
    )
    records = {(r.kind, r.phase): r for r in read_faults(result.trace)}
    assert set(records) == {("grasp-slip", "start"), ("snag", "start"), ("snag", "end")}
    assert "lost_endobot_2" in records["grasp-slip", "start"].params
    snag = records["snag", "end"].t - records["snag", "start"].t
    assert snag == pytest.approx(0.3, abs=1.5e-3)
    limit = float(result.summary.tension_limit_N or 0.0)
    true_max, true_over, *_ = trace_violations(result.trace, limit)
    assert true_max == true_max and true_over == 0  # the backend has a thread; no violation
