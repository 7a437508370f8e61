"""The trace recorder's per-tick fast path writes the same file as the generic path.

The generic path builds one dict per message and encodes it with the standard
library's JSON encoder (``codec.encode``); the fast path encodes every vector of a
tick in one orjson call, lays the numbers out as ``repr`` does, and fills message
templates. Both are run on the same calls and the files compared byte for byte.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from suture_engine.control.constrained_qp import QPResult
from suture_engine.runtime import recorder as recorder_mod
from suture_engine.runtime.automaton import TransitionRecord
from suture_engine.runtime.observation import (
    Observation,
    RobotObservation,
    SceneGeometry,
    ToolState,
)
from suture_engine.runtime.operator import OperatorEvent
from suture_engine.runtime.recorder import TraceRecorder
from suture_engine.runtime.run import run_procedure
from suture_engine.trace.reader import TraceReader

PROCS = Path(__file__).parent / "procedures"
ROBOTS = ("endobot_1", "endobot_2")


def _recorder(path: Path, **options: Any) -> TraceRecorder:
    """A recorder for two robots, procedure "p", seed 0, at 1 kHz."""
    return TraceRecorder(
        path,
        procedure="p",
        seed=0,
        control_rate_hz=1000.0,
        robots=ROBOTS,
        backend="test",
        params={},
        **options,
    )


def _observation(k: int, rng: np.random.Generator) -> Observation:
    """Values across the decades where repr and orjson lay numbers out differently."""
    scale = 10.0 ** rng.integers(-12, 3, size=6)
    robots = {
        r: RobotObservation(
            rng.normal(size=4) * scale[:4],
            rng.normal(size=4) * scale[2:6],
            rng.normal(size=6) * scale,
            ToolState(),
        )
        for r in ROBOTS
    }
    return Observation(k, k * 1e-3, robots, SceneGeometry())


def _record(path: Path, fast: bool, wall_clock: bool = False) -> bytes:
    """One call sequence, with the odd cases the fast path must hand over or keep in order."""
    rng = np.random.default_rng(7)
    rec = _recorder(path, centerline_every=4, fast=fast)
    if wall_clock:
        rec.writer._include_wall_clock = True
        rec._wall_clock = True
    for k in range(60):
        t = k * 1_000_000
        obs = _observation(k, rng)
        torques: dict[str, Any] = {r: rng.normal(size=4) for r in ROBOTS}
        truth: dict[str, Any] = {"tension_N": float(rng.uniform(0, 3))}
        if k % 8 != 7:  # a backend that says where the tension acts, on most ticks
            truth["tension_joint"] = int(rng.integers(1, 40))
        if k % 5 == 1:
            torques["endobot_2"] = np.array([1, 2, 3, 4])  # ints: written as floats
        if k % 7 == 2:
            torques["endobot_1"] = np.array([0.5, np.nan, np.inf, -1e-5])  # null
        if k % 9 == 3:
            torques["endobot_1"] = np.arange(8.0)[::2]  # not contiguous
        if k % 11 == 4:
            del torques["endobot_2"]  # no command this tick
        if k % 4 == 0:
            truth["centerline"] = rng.normal(size=(5, 3))
        if k % 13 == 5:
            truth["tension_N"] = float("nan")
        if k % 3 == 0:
            active = ("line[0]", "line[1]") if k % 2 else ("joint_bound[3]",)
            res = QPResult(np.zeros(4), "solved", True, k, 1e-5, active, 0.0)
            rec.qp(t, "endobot_1", res)
        if k % 10 == 6:  # a transition between the QP message and the tick's messages
            rec.transition(t, TransitionRecord("a", "b", "advance", "planned", "done"))
        if k == 20:
            rec.operator(t, OperatorEvent(action="lock", source="test"), True, "")
            rec.event(t, "note", "info", "a", "detail")
        tension = {"endobot_1": float(rng.uniform(0, 1)), "endobot_2": 1e-7 * k}
        modes = {"endobot_1": "autonomous", "endobot_2": None if k % 6 == 0 else "lock"}
        rec.tick(t, obs, torques, modes, tension, truth)  # type: ignore[arg-type]
    rec.qp(60_000_000, "endobot_2", QPResult(np.zeros(4), "max iter", False, 9, 1.0, (), 0.0))
    rec.close()  # writes the queued QP message
    return path.read_bytes()


def test_fast_path_writes_the_generic_paths_bytes(tmp_path: Path) -> None:
    fast = _record(tmp_path / "fast.mcap", fast=True)
    generic = _record(tmp_path / "generic.mcap", fast=False)
    assert fast == generic
    messages = list(TraceReader(tmp_path / "fast.mcap").messages())
    true = [m.data for m in messages if m.topic == "/ground_truth/tension"]
    # the joint where the true tension acts, when the backend gave it (ticks k % 8 != 7)
    assert [("joint" in d) for d in true] == [k % 8 != 7 for k in range(60)]
    assert all(1 <= d["joint"] < 40 for d in true if "joint" in d)
    topics = {m.topic for m in messages}
    assert {"/qp/endobot_2", "/operator", "/ground_truth/suture", "/transitions"} <= topics
    assert messages[-1].topic == "/qp/endobot_2"


def test_fast_path_keeps_wall_clock_fields_when_asked(tmp_path: Path) -> None:
    fast = _record(tmp_path / "fast.mcap", fast=True, wall_clock=True)
    generic = _record(tmp_path / "generic.mcap", fast=False, wall_clock=True)
    assert fast == generic
    qp = next(m for m in TraceReader(tmp_path / "fast.mcap").messages() if m.topic[:3] == "/qp")
    assert qp.data["solve_time_us"] == pytest.approx(10.0)


def test_fast_path_is_taken_and_matches_json_on_a_tick(tmp_path: Path) -> None:
    rec = _recorder(tmp_path / "t.mcap")
    obs = _observation(0, np.random.default_rng(3))
    torques = {r: np.array([0.25, -1e-9, 3e16, 5e-5]) for r in ROBOTS}
    batch: list[tuple[str, bytes]] = []
    modes = {r: "lock" for r in ROBOTS}
    assert rec._tick_fast(batch, obs, torques, modes, {"a": 1.0}, "a", (2.0, 7))
    rec.close()
    by_topic = dict(batch)
    assert json.loads(by_topic["/ground_truth/tension"]) == {"tension_N": 2.0, "joint": 7}
    cmd = json.loads(by_topic["/command/endobot_1"])
    assert cmd == {"kind": "torque", "mode": "lock", "values": [0.25, -1e-9, 3e16, 5e-5]}
    assert by_topic["/command/endobot_1"].endswith(b'"values":[0.25,-1e-09,3e+16,5e-05]}')
    wrench = json.loads(by_topic["/base_wrench/endobot_2"])
    assert wrench["force"] + wrench["torque"] == obs.robots["endobot_2"].base_wrench.tolist()
    assert json.loads(by_topic["/ground_truth/tension"]) == {"tension_N": 2.0, "joint": 7}


@pytest.mark.parametrize("fast", [True, False])
def test_the_estimated_tension_carries_every_robots_estimate(tmp_path: Path, fast: bool) -> None:
    rec = _recorder(tmp_path / "t.mcap", fast=fast)
    obs = _observation(0, np.random.default_rng(3))
    tension = {"endobot_1": 0.25, "endobot_2": 1.5e-7}
    rec.tick(0, obs, {}, {}, tension, {})
    tension = {"endobot_1": 0.25, "endobot_2": 3.5}
    rec.tick(1_000_000, obs, {}, {}, tension, {})
    rec.close()
    msgs = [m.data for m in TraceReader(tmp_path / "t.mcap").messages(["/tension/estimated"])]
    assert msgs == [
        {"robot": "endobot_1", "tension_N": 0.25,
         "estimates": [{"robot": "endobot_1", "tension_N": 0.25},
                       {"robot": "endobot_2", "tension_N": 1.5e-7}]},
        {"robot": "endobot_2", "tension_N": 3.5,
         "estimates": [{"robot": "endobot_1", "tension_N": 0.25},
                       {"robot": "endobot_2", "tension_N": 3.5}]},
    ]  # fmt: skip


def test_a_run_records_the_same_trace_on_both_paths(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    taken: list[bool] = []
    original = recorder_mod.TraceRecorder._tick_fast

    def spy(self: TraceRecorder, *args: Any) -> bool:
        taken.append(original(self, *args))
        return taken[-1]

    monkeypatch.setattr(recorder_mod.TraceRecorder, "_tick_fast", spy)
    fast = run_procedure(PROCS / "steps.yaml", backend="ideal", out=tmp_path / "fast")
    assert len(taken) > 100 and all(taken)
    taken.clear()
    defaults = dict(recorder_mod.TraceRecorder.__init__.__kwdefaults__ or {})
    monkeypatch.setattr(
        recorder_mod.TraceRecorder.__init__, "__kwdefaults__", {**defaults, "fast": False}
    )
    generic = run_procedure(PROCS / "steps.yaml", backend="ideal", out=tmp_path / "generic")
    assert taken == []
    assert fast.trace.read_bytes() == generic.trace.read_bytes()


def test_centerline_is_looked_up_on_its_ticks_only(tmp_path: Path) -> None:
    from collections.abc import Iterator, Mapping

    class CountingTruth(Mapping[str, Any]):
        """A backend's lazy ground truth: counts how often the centerline is computed."""

        def __init__(self) -> None:
            self.computed = 0

        def __getitem__(self, key: str) -> Any:
            if key == "centerline":
                self.computed += 1
                return np.zeros((3, 3))
            if key == "tension_N":
                return 0.5
            raise KeyError(key)

        def __iter__(self) -> Iterator[str]:
            return iter(("centerline", "tension_N"))

        def __len__(self) -> int:
            return 2

    rec = _recorder(tmp_path / "t.mcap", centerline_every=100)
    truth = CountingTruth()
    rng = np.random.default_rng(1)
    for k in range(250):
        obs = _observation(k, rng)
        rec.tick(k * 1_000_000, obs, {}, {}, {"endobot_1": 0.1}, truth)
    rec.close()
    assert truth.computed == 3  # ticks 0, 100 and 200
    topics = [m.topic for m in TraceReader(tmp_path / "t.mcap").messages()]
    assert topics.count("/ground_truth/suture") == 3
    assert topics.count("/ground_truth/tension") == 250


def test_without_orjson_the_generic_path_writes_the_same_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from suture_engine.trace import codec

    with_orjson = _record(tmp_path / "a.mcap", fast=True)
    monkeypatch.setattr(codec, "_FAST", [None])  # as when orjson is not installed
    assert codec.encode_vectors([np.zeros(2)]) is None
    without = _record(tmp_path / "b.mcap", fast=True)
    assert with_orjson == without


def test_hook_load_is_recorded_when_it_changes_and_replayed(tmp_path: Path) -> None:
    """``/hook_load/<robot>`` holds one message per change of the measured load (none
    while it stays 0 from the start), and the replay backend serves, at every tick, the
    load last recorded at or before it."""
    from dataclasses import replace

    from backends.replay import ReplayBackend

    loads = [0.0, 0.0, 0.0, 0.5, 0.5, 1.25, 1.25, 1.25, 0.0, 0.0]
    rec = _recorder(tmp_path / "t.mcap")
    rng = np.random.default_rng(3)
    for k, load in enumerate(loads):
        obs = _observation(k, rng)
        hooked = replace(obs.robots["endobot_2"], tool=ToolState("hook-grasper", hook_load=load))
        obs = Observation(k, obs.t, {**obs.robots, "endobot_2": hooked}, obs.scene)
        rec.tick(k * 1_000_000, obs, {}, {}, {"endobot_1": 0.1}, {})
    rec.close()
    trace = TraceReader(tmp_path / "t.mcap")
    written = [
        (round(m.log_time_ns / 1_000_000), m.data["load"])
        for m in trace.messages(["/hook_load/endobot_2"])
    ]
    assert written == [(3, 0.5), (5, 1.25), (8, 0.0)]
    assert not list(trace.messages(["/hook_load/endobot_1"]))
    replay = ReplayBackend(tmp_path / "t.mcap")
    served = [replay.reset().robots["endobot_2"].tool.hook_load]
    for _ in loads[1:]:
        replay.step()
        served.append(replay.observe().robots["endobot_2"].tool.hook_load)
    assert served == loads
