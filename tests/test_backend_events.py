"""Events a backend reports that no sensor measures (``BackendEvent``): the PyBullet
backend's ``grip-slip`` (the thread slid through a grasper's jaws, pulled above its
``grip_limit``), recorded on ``/events`` as ``info`` events that start no transition,
counted in the summary's ``grip_slips`` / ``grip_slip_mm``, and not compared by the
replay.

The physics rig is ``tests/grip_rig.py``'s (a thread between two graspers'
jaws, the far one driven away), stepped through the backend's own physics step.
"""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from suture_engine.runtime.automaton import FailurePolicy, Outcome, Plan, StepSpec
from suture_engine.runtime.interpreter import Interpreter
from suture_engine.runtime.observation import BackendEvent
from suture_engine.runtime.recorder import TraceRecorder
from suture_engine.runtime.testing import IdealBackend, ScriptedSkill
from suture_engine.trace.reader import TraceReader

LIMIT = 3.0
"""The held grasper's grip limit [N]."""


def _rig_backend(limit: float) -> Any:
    """A PyBullet backend whose surgical scene is the two-grasper rig: ``endobot_1``'s
    jaws (limited) hold the thread mid-way, ``endobot_2``'s (unlimited) its far end."""
    p = pytest.importorskip("pybullet")
    from grip_rig import build_grip_rig

    from backends.pybullet.backend import PyBulletBackend

    rig = build_grip_rig(p, limit)
    c, suture, near, far = rig.client, rig.suture, rig.near, rig.far
    be = PyBulletBackend()
    be._p, be.client = p, c
    be.scene = SimpleNamespace(
        tools={"endobot_1": near, "endobot_2": far}, suture=suture, tissue=None, time=0.0
    )
    return be


def _drag(be: Any, distance: float, speed: float = 0.02) -> list[BackendEvent]:
    """Settle 0.2 s, then drive ``endobot_2``'s jaws ``distance`` along the thread at
    ``speed``, hold 0.2 s; the backend's events, read every step."""
    far = be.scene.tools["endobot_2"]
    x = np.asarray(far.pose()[0])
    events: list[BackendEvent] = []
    steps = round(distance / speed * 1000)
    for i in range(200 + steps + 200):
        if 200 <= i < 200 + steps:
            x = x + np.array([speed * 1e-3, 0.0, 0.0])
            far.set_pose(tuple(x))
        be._physics_step()
        events += be.backend_events()
    return events


def test_a_pull_above_the_grip_limit_reports_grip_slips_at_the_limit() -> None:
    be = _rig_backend(LIMIT)
    try:
        events = _drag(be, 0.006)
        near = be.scene.tools["endobot_1"]
        assert events and len(events) == len(near.slips)
        assert {(e.name, e.robot) for e in events} == {("grip-slip", "endobot_1")}
        details = [json.loads(e.detail) for e in events]
        for d in details:
            assert d["force_N"] == pytest.approx(LIMIT, rel=0.10)
            assert d["slid_mm"] > 0.0
        slid = sum(d["slid_mm"] for d in details)
        assert slid == pytest.approx(1e3 * near.slid, abs=1e-3)
        assert 3.0 < slid < 6.5
        m = be.run_metrics()
        assert m["thread"]["capsules"] == len(be.scene.suture.bodies)
        assert m["grip_slips"] == len(events)
        assert m["grip_slip_mm"] == pytest.approx(slid, abs=1e-3)
        assert m["grip_slips_by_robot"] == {
            "endobot_1": {"slips": len(events), "mm": m["grip_slip_mm"]}
        }
        assert be.backend_events() == []  # drained
    finally:
        be.close()


def test_a_pull_below_the_grip_limit_reports_none() -> None:
    be = _rig_backend(LIMIT)
    try:
        far = be.scene.tools["endobot_2"]
        near = be.scene.tools["endobot_1"]
        x = np.asarray(far.pose()[0])
        events: list[BackendEvent] = []
        for _ in range(200):
            be._physics_step()
        for _ in range(5000):  # pull to 0.8 x the limit, then hold 0.5 s
            if near.grip_force() >= 0.8 * LIMIT:
                break
            x = x + np.array([1e-5, 0.0, 0.0])
            far.set_pose(tuple(x))
            be._physics_step()
            events += be.backend_events()
        else:
            pytest.fail("the pull never reached 0.8 x the limit")
        for _ in range(500):
            be._physics_step()
            events += be.backend_events()
        assert events == []
        m = be.run_metrics()
        del m["thread"]
        assert m == {"grip_slips": 0, "grip_slip_mm": 0.0, "grip_slips_by_robot": {}}
    finally:
        be.close()


def test_a_needle_hand_over_that_stops_short_is_reported_and_reads_as_not_passed() -> None:
    """A stitcher's needle whose thread runs straight, slack-free, to an anchor along the
    hand-over's way: the hand-over stops short at the needle drive's force, the backend
    reports one ``needle-stall`` and the receiving jaw does not read closed, so that the
    step that asked for the hand-over cannot take it as done."""
    p = pytest.importorskip("pybullet")
    from backends.pybullet.backend import PyBulletBackend
    from backends.pybullet.suture import Suture, SutureParams, configure_physics, straight_path
    from backends.pybullet.tools import Stitcher
    from suture_engine.runtime.observation import ToolState

    c = p.connect(p.DIRECT)
    configure_physics(c)
    p.setGravity(0, 0, 0, physicsClientId=c)
    jaw0 = np.array([-4e-3, 0.0, 3e-3])
    sut = Suture.create(
        c, straight_path(tuple(jaw0 - [0.06, 0, 0]), (1, 0, 0), 0.06),
        SutureParams(length=0.06, n_segments=12),
    )  # fmt: skip
    p.changeDynamics(sut.bodies[0], -1, mass=0.0, physicsClientId=c)
    st = Stitcher.create(c, "st", (0, 0, 0), needle_body=sut.needle_body, place_needle=False)
    be = PyBulletBackend()
    be._p, be.client = p, c
    be.scene = SimpleNamespace(tools={"endobot_1": st}, suture=sut, tissue=None, time=0.0)
    be._tools = {"endobot_1": ToolState("stitcher", True, False)}
    try:
        for _ in range(100):
            be._physics_step()
        asked = ToolState("stitcher", True, True)  # the receiving jaw closed: pass it
        be._drive_tool("endobot_1", be._tools["endobot_1"], asked)
        be._tools["endobot_1"] = asked
        events: list[BackendEvent] = []
        for _ in range(400):
            be._physics_step()
            events += be.backend_events()
        assert [(e.name, e.robot) for e in events] == [("needle-stall", "endobot_1")]
        detail = json.loads(events[0].detail)
        assert detail["jaw"] == 0 and detail["shortfall_mm"] > 2.0
        reading = be._tool_reading("endobot_1")
        assert (reading.jaw_closed, reading.jaw2_closed) == (True, False)
        assert st.needle_holder == 0
        m = be.run_metrics()
        # the thread as SutureParams(length=0.06, n_segments=12) builds it: 5 mm capsules
        # of 1 g each (200 g/m), damped at 0.5 /s, keeping 0.1 g/m of weight
        assert m.pop("thread") == {
            "capsules": 12, "capsule_mm": 5.0, "damping_per_s": 0.5, "weight_g_per_m": 0.1,
            "simulated_g_per_m": 200.0, "smooth_joints": False, "bending_stiffness_Nm2": 0.0,
            "contact_stiffness_N_per_m": None,
        }  # fmt: skip
        assert m == {"needle_stalls": 1}
    finally:
        be.close()


def test_an_unknown_backend_event_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown backend event"):
        BackendEvent("slipped", "endobot_1", "{}")


class _SlippingBackend(IdealBackend):
    """The ideal backend, reporting a grip slip of ``endobot_1`` at its 50th step."""

    def __init__(self, slip: bool) -> None:
        super().__init__()
        self.slip = slip
        self.steps = 0
        self._pending: list[BackendEvent] = []

    def step(self) -> None:
        super().step()
        self.steps += 1
        if self.slip and self.steps == 50:
            self._pending.append(BackendEvent("grip-slip", "endobot_1", '{"force_N":3.0}'))

    def backend_events(self) -> list[BackendEvent]:
        out, self._pending = self._pending, []
        return out

    def run_metrics(self) -> dict[str, Any]:
        return {"grip_slips": 1 if self.slip else 0}


def _run(tmp_path: Path, slip: bool) -> tuple[Any, list[Any], list[Any]]:
    plan = Plan(
        "p",
        "a",
        {
            "a": StepSpec(
                "a", lambda: ScriptedSkill("a", "success", after_s=0.1), "end", FailurePolicy(0)
            )
        },
        {"end": Outcome.SUCCEEDED},
    )
    be = _SlippingBackend(slip)
    first = be.reset()
    trace = tmp_path / f"slip-{slip}.mcap"
    rec = TraceRecorder(
        trace,
        procedure="p",
        seed=0,
        control_rate_hz=1000.0,
        robots=tuple(first.robots),
        backend="ideal",
        params={},
    )
    summary = Interpreter(plan, be, first, recorder=rec).run("p", "ideal")
    reader = TraceReader(trace)
    events = [m for m in reader.messages(["/events"])]
    transitions = [m.data for m in TraceReader(trace).messages(["/transitions"])]
    return summary, events, transitions


def test_backend_events_are_recorded_as_info_and_start_no_transition(tmp_path: Path) -> None:
    s0, events0, transitions0 = _run(tmp_path, False)
    s1, events1, transitions1 = _run(tmp_path, True)
    assert transitions1 == transitions0
    assert (s1.outcome, s1.final_state) == (s0.outcome, s0.final_state) == ("succeeded", "end")
    slips = [m for m in events1 if m.data["name"] == "grip-slip"]
    assert len(slips) == 1
    assert slips[0].data == {
        "name": "grip-slip",
        "kind": "info",
        "state": "autonomous/a",
        "detail": '{"force_N":3.0}',
        "robot": "endobot_1",
    }
    assert slips[0].log_time_ns == 50_000_000  # recorded at the tick that measures it
    assert [m.data for m in events1 if m.data["name"] != "grip-slip"] == [m.data for m in events0]
    assert (s0.metrics["grip_slips"], s1.metrics["grip_slips"]) == (0, 1)


def test_the_replay_does_not_compare_backend_events() -> None:
    from suture_engine.runtime.run import _fault_record

    def msg(name: str) -> Any:
        return SimpleNamespace(topic="/events", data={"name": name, "kind": "info"})

    assert _fault_record(msg("grip-slip"))
    assert _fault_record(msg("fault:grasp-slip"))
    assert not _fault_record(msg("advance"))
