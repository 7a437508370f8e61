"""What the robots measured per state (suture_engine/report/steps.py).

The travel is checked against the EndoBot's geometry, not its forward-kinematics code:
the tool tip lies on the insertion axis through the remote centre, at the insertion
depth from it (3.12), so changing the insertion alone moves the tip by the change, and
turning the yaw alone at zero pitch moves it on a circle of radius the depth.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from suture_engine.report.steps import run_label, state_measures
from suture_engine.trace.channels import (
    GROUND_TRUTH_TENSION,
    TENSION_ESTIMATED,
    TRANSITIONS,
    joint_state_topic,
)
from suture_engine.trace.errors import TraceError
from suture_engine.trace.synthetic import synthetic_meta
from suture_engine.trace.writer import TraceWriter

S = 1_000_000_000
"""Nanoseconds per second."""

THETA = 0.4
"""The yaw turn of robot b in the state ``turn`` [rad]."""


def _estimates(a: float, b: float) -> dict[str, object]:
    return {
        "estimates": [{"robot": "a", "tension_N": a}, {"robot": "b", "tension_N": b}],
        "robot": "a",
        "tension_N": a,
    }


def write_trace(path: Path) -> None:
    """Two EndoBots, three states: ``approach`` (nothing moves), ``insert`` (robot a
    goes 30 mm deeper along its axis), ``turn`` (robot b turns its yaw by THETA at a
    depth of 100 mm, zero pitch); estimates and true tensions with known extremes."""
    n = 200
    with TraceWriter(path, synthetic_meta(robots=("a", "b")), fsync=False) as w:
        w.write(
            TRANSITIONS, 0, {"source": "idle", "dest": "autonomous/approach", "trigger": "start"}
        )
        for k in range(n):  # approach: 0-1 s, at rest
            t = int(k * S / n)
            w.write(
                joint_state_topic("a"),
                t,
                {"position": [0.1, 0.2, 0.0, 0.10], "velocity": [0.0] * 4},
            )
            w.write(
                joint_state_topic("b"),
                t,
                {"position": [0.0, 0.0, 0.0, 0.10], "velocity": [0.0] * 4},
            )
            w.write(TENSION_ESTIMATED, t, _estimates(0.05, 0.07))
        w.write(
            TRANSITIONS,
            S,
            {"source": "autonomous/approach", "dest": "autonomous/insert", "trigger": "advance"},
        )
        for k in range(n + 1):  # insert: 1-2 s, a from 100 to 130 mm deep
            t = S + int(k * S / n)
            w.write(
                joint_state_topic("a"),
                t,
                {"position": [0.1, 0.2, 0.0, 0.10 + 0.03 * k / n], "velocity": [0.0] * 4},
            )
            w.write(
                joint_state_topic("b"),
                t,
                {"position": [0.0, 0.0, 0.0, 0.10], "velocity": [0.0] * 4},
            )
            w.write(TENSION_ESTIMATED, t, _estimates(0.2 + 1.0 * math.sin(math.pi * k / n), 0.07))
            # the thread's peak at k = 37, at joint 12; a null (non-finite) reading at k = 5
            tension = None if k == 5 else 0.5 + (0.25 if k == 37 else 0.0)
            w.write(GROUND_TRUTH_TENSION, t, {"tension_N": tension, "joint": 12 if k == 37 else 3})
        w.write(
            TRANSITIONS,
            2 * S + 1,
            {"source": "autonomous/insert", "dest": "autonomous/turn", "trigger": "advance"},
        )
        for k in range(n + 1):  # turn: 2-3 s, b's yaw from 0 to THETA
            t = 2 * S + 1 + int(k * S / n)
            w.write(
                joint_state_topic("a"),
                t,
                {"position": [0.1, 0.2, 0.0, 0.13], "velocity": [0.0] * 4},
            )
            w.write(
                joint_state_topic("b"),
                t,
                {"position": [THETA * k / n, 0.0, 0.0, 0.10], "velocity": [0.0] * 4},
            )
            # a trace written before the per-robot list: the running robot's alone
            w.write(TENSION_ESTIMATED, t, {"robot": "b", "tension_N": 0.3 + 0.001 * k})
        w.write(
            TRANSITIONS,
            3 * S + 2,
            {"source": "autonomous/turn", "dest": "tied", "trigger": "advance"},
        )


def test_travel_is_the_tool_tip_moving_along_its_axis_and_round_its_remote_centre(
    tmp_path: Path,
) -> None:
    write_trace(tmp_path / "trace.mcap")
    rows = {r.state.rsplit("/", 1)[-1]: r for r in state_measures(tmp_path / "trace.mcap")}
    assert list(rows) == ["idle", "approach", "insert", "turn", "tied"]
    insert, turn = rows["insert"], rows["turn"]
    # the insertion alone: the tip moves by the change in depth, in a straight line
    assert insert.robots["a"].travel_mm == pytest.approx(30.0, abs=1e-9)
    assert insert.robots["a"].path_mm == pytest.approx(30.0, abs=1e-9)
    assert insert.robots["b"].travel_mm == pytest.approx(0.0, abs=1e-12)
    # the yaw alone at zero pitch: a chord and an arc of a 100 mm circle
    assert turn.robots["b"].travel_mm == pytest.approx(2 * 100.0 * math.sin(THETA / 2), rel=1e-9)
    assert turn.robots["b"].path_mm == pytest.approx(100.0 * THETA, rel=1e-5)
    assert turn.robots["a"].travel_mm == pytest.approx(0.0, abs=1e-9)
    assert rows["approach"].robots["a"].travel_mm == pytest.approx(0.0, abs=1e-12)
    # each state starts where the last ended: ``tied`` has no joint message of its own,
    # and its tips stand where ``turn`` left them (no travel, rather than none known)
    assert rows["tied"].robots["b"].travel_mm == 0.0
    assert rows["tied"].robots["b"].path_mm == 0.0
    assert (insert.start_s, insert.end_s) == (1.0, pytest.approx(2.0))


def test_estimates_are_per_robot_and_per_state(tmp_path: Path) -> None:
    write_trace(tmp_path / "trace.mcap")
    rows = {r.state.rsplit("/", 1)[-1]: r for r in state_measures(tmp_path / "trace.mcap")}
    a = rows["insert"].robots["a"]
    assert (a.estimate_start_N, a.estimate_end_N) == (pytest.approx(0.2), pytest.approx(0.2))
    assert a.estimate_peak_N == pytest.approx(1.2)  # sin peaks at k = n / 2
    assert rows["insert"].robots["b"].estimate_peak_N == pytest.approx(0.07)
    assert rows["approach"].robots["a"].estimate_peak_N == pytest.approx(0.05)
    # the older single-robot message: robot b's estimate, and none for a
    b = rows["turn"].robots["b"]
    assert (b.estimate_start_N, b.estimate_peak_N) == (pytest.approx(0.3), pytest.approx(0.5))
    assert rows["turn"].robots["a"].estimate_peak_N is None
    # the true peak is the state's own, not the run's
    assert rows["insert"].true_peak_N == pytest.approx(0.75)
    assert rows["insert"].true_peak_joint == 12  # where it acted, on the thread
    assert rows["turn"].true_peak_N is None and rows["turn"].true_peak_joint is None


def test_states_are_chosen_by_glob_with_or_without_the_mode(tmp_path: Path) -> None:
    write_trace(tmp_path / "trace.mcap")
    names = [
        r.state for r in state_measures(tmp_path / "trace.mcap", states=["in*", "autonomous/tu*"])
    ]
    assert names == ["autonomous/insert", "autonomous/turn"]
    assert list(state_measures(tmp_path / "trace.mcap", states=["nothing"])) == []


def test_run_label_reads_the_summary_beside_the_trace(tmp_path: Path) -> None:
    trace = tmp_path / "trace.mcap"
    assert run_label(trace) == {}
    (tmp_path / "summary.json").write_text(
        '{"outcome": "succeeded", "knot": [{"type": "square"}, {"type": "trefoil"}]}'
    )
    assert run_label(trace) == {"outcome": "succeeded", "knot": "square+trefoil"}
    (tmp_path / "summary.json").write_text('{"outcome": "failed", "knot": {"type": "unknot"}}')
    assert run_label(trace) == {"outcome": "failed", "knot": "unknot"}


def test_a_file_that_is_not_a_trace_is_a_trace_error(tmp_path: Path) -> None:
    bad = tmp_path / "trace.mcap"
    bad.write_bytes(b"not a trace")
    with pytest.raises(TraceError):
        list(state_measures(bad))
