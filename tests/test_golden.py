"""Tests of the golden-trace comparison: first divergence, tolerances, readable diff."""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from suture_engine.trace.golden import (
    DEFAULT_TOLERANCES,
    Tolerance,
    ToleranceSpec,
    compare,
)
from suture_engine.trace.reader import TraceMessage, TraceReader
from suture_engine.trace.writer import TraceMeta, TraceWriter

Msgs = list[tuple[str, int, dict[str, Any]]]
MS = 1_000_000  # one tick at 1 kHz [ns]


def _run(ticks: int = 200) -> Msgs:
    """A small hand-made run: two robots, events every 50 ticks."""
    msgs: Msgs = []
    for k in range(ticks):
        t = k * MS
        for r, robot in enumerate(("left", "right")):
            values = [0.5 + 0.001 * k + 0.1 * j + r for j in range(6)]
            msgs.append((f"/command/{robot}", t, {"kind": "torque", "values": values}))
            msgs.append(
                (
                    f"/qp/{robot}",
                    t,
                    {
                        "status": "solved",
                        "iterations": 3,
                        "active_constraints": ["line"],
                        "solve_time_us": 10.0 + k,
                    },
                )
            )
        msgs.append(("/tension/estimated", t, {"tension_N": 2.0 + 0.01 * k}))
        if k and k % 50 == 0:
            msgs.append(("/events", t, {"name": f"step{k}", "kind": "planned", "state": "s"}))
            msgs.append(("/transitions", t, {"source": "a", "dest": "b", "trigger": f"step{k}"}))
    return msgs


def _write(path: Path, msgs: Msgs, version: str = "0.1.0") -> Path:
    meta = TraceMeta("golden-test", seed=7, control_rate_hz=1000.0, engine_version=version)
    with TraceWriter(path, meta, include_wall_clock=True, validate=True) as w:
        for topic, t, msg in msgs:
            w.write(topic, t, msg)
    return path


def _edit(msgs: Msgs, topic: str, tick: int, change: Callable[[dict[str, Any]], None]) -> Msgs:
    out = copy.deepcopy(msgs)
    for topic_i, t, msg in out:
        if topic_i == topic and t == tick * MS:
            change(msg)
            return out
    raise AssertionError(f"no {topic} message at tick {tick}")


@pytest.fixture
def golden(tmp_path: Path) -> Path:
    return _write(tmp_path / "golden.mcap", _run())


def test_identical_traces_match(tmp_path: Path, golden: Path) -> None:
    again = _write(tmp_path / "again.mcap", _run())
    result = compare(golden, again)
    assert result.ok and bool(result) and result.divergence is None
    assert result.messages_compared == len(_run()) + 1  # + /meta
    assert "traces match" in result.text


def test_first_diverging_tick_and_signal_are_named(tmp_path: Path, golden: Path) -> None:
    msgs = _edit(_run(), "/command/left", 123, lambda m: m["values"].__setitem__(3, 9.0))
    # a later divergence on another channel must not hide the first one
    msgs = _edit(msgs, "/tension/estimated", 150, lambda m: m.__setitem__("tension_N", 0.0))
    result = compare(golden, _write(tmp_path / "a.mcap", msgs))
    assert not result.ok
    d = result.divergence
    assert d is not None
    assert (d.tick, d.time_ns, d.channel, d.field, d.index) == (
        123,
        123 * MS,
        "/command/left",
        "values[3]",
        123,
    )
    assert d.expected == pytest.approx(0.5 + 0.123 + 0.3)
    assert d.actual == 9.0
    assert [c.channel for c in result.channel_divergences] == [
        "/command/left",
        "/tension/estimated",
    ]
    text = result.text
    assert "tick 123" in text and "/command/left" in text and "values[3]" in text
    assert "/tension/estimated" in text  # listed among the other diverging channels


@pytest.mark.parametrize(
    ("delta", "ok"),
    [(0.999e-3, True), (-0.999e-3, True), (1.001e-3, False), (-1.001e-3, False)],
)
def test_absolute_tolerance_edges(tmp_path: Path, golden: Path, delta: float, ok: bool) -> None:
    """abs 1e-3 on commands: just inside passes, just outside fails."""
    spec = DEFAULT_TOLERANCES.with_rules(("/command/*", "values", Tolerance(abs=1e-3)))
    expected = 0.5 + 0.001 * 60 + 0.1 * 2  # /command/left values[2] at tick 60
    msgs = _edit(
        _run(), "/command/left", 60, lambda m: m["values"].__setitem__(2, expected + delta)
    )
    result = compare(golden, _write(tmp_path / "a.mcap", msgs), spec)
    assert result.ok is ok
    if not ok:
        d = result.divergence
        assert d is not None and d.tolerance == Tolerance(abs=1e-3)
        assert (d.tick, d.field) == (60, "values[2]")
        assert "> 0.001 (abs 0.001 + rel 0)" in result.text


@pytest.mark.parametrize(("factor", "ok"), [(1.0 + 0.99e-2, True), (1.0 + 1.01e-2, False)])
def test_relative_tolerance_edges(tmp_path: Path, golden: Path, factor: float, ok: bool) -> None:
    """rel 1 % on the estimated tension: 2.4 N may move by 0.024 N."""
    spec = ToleranceSpec(rules=(("/tension/estimated", "tension_N", Tolerance(rel=1e-2)),))
    spec = ToleranceSpec(spec.rules + DEFAULT_TOLERANCES.rules, DEFAULT_TOLERANCES.ignore)
    msgs = _edit(
        _run(), "/tension/estimated", 40, lambda m: m.__setitem__("tension_N", 2.4 * factor)
    )
    result = compare(golden, _write(tmp_path / "a.mcap", msgs), spec)
    assert result.ok is ok


def test_default_tolerance_absorbs_only_rounding_noise(tmp_path: Path, golden: Path) -> None:
    x = 0.5 + 0.001 * 10
    noisy = _edit(_run(), "/command/right", 10, lambda m: m["values"].__setitem__(0, x + 1 + 1e-12))
    assert compare(golden, _write(tmp_path / "a.mcap", noisy)).ok
    off = _edit(_run(), "/command/right", 10, lambda m: m["values"].__setitem__(0, x + 1 + 1e-6))
    assert not compare(golden, _write(tmp_path / "b.mcap", off)).ok


def test_events_and_transitions_are_exact(tmp_path: Path, golden: Path) -> None:
    msgs = _edit(_run(), "/events", 100, lambda m: m.__setitem__("name", "step100b"))
    d = compare(golden, _write(tmp_path / "a.mcap", msgs)).divergence
    assert d is not None and (d.channel, d.tick, d.field) == ("/events", 100, "name")
    assert (d.expected, d.actual) == ("step100", "step100b")
    msgs = _edit(_run(), "/transitions", 50, lambda m: m.__setitem__("dest", "c"))
    d = compare(golden, _write(tmp_path / "b.mcap", msgs)).divergence
    assert d is not None and (d.channel, d.tick, d.field) == ("/transitions", 50, "dest")


def test_qp_iterations_exact_but_solve_time_and_version_ignored(
    tmp_path: Path, golden: Path
) -> None:
    # the solve time differs at every tick in _run() vs this copy, and the version too
    msgs = [
        (t, k, {**m, "solve_time_us": 99.0} if t.startswith("/qp/") else m) for t, k, m in _run()
    ]
    assert compare(golden, _write(tmp_path / "a.mcap", msgs, version="9.9.9")).ok
    msgs = _edit(_run(), "/qp/right", 7, lambda m: m.__setitem__("iterations", 4))
    d = compare(golden, _write(tmp_path / "b.mcap", msgs)).divergence
    assert d is not None and (d.channel, d.tick, d.field) == ("/qp/right", 7, "iterations")


def test_shorter_actual_trace_names_the_first_missing_message(tmp_path: Path, golden: Path) -> None:
    msgs = [m for m in _run() if m[1] < 80 * MS]
    result = compare(golden, _write(tmp_path / "a.mcap", msgs))
    d = result.divergence
    assert d is not None and d.tick == 80 and d.actual == "<missing>"
    assert d.channel == "/command/left"  # first topic in name order at that tick


def test_extra_message_and_time_shift(tmp_path: Path, golden: Path) -> None:
    msgs = [*_run(), ("/events", 199 * MS, {"name": "extra", "kind": "info"})]
    d = compare(golden, _write(tmp_path / "a.mcap", msgs)).divergence
    assert d is not None and d.channel == "/events" and d.expected == "<missing>"
    shifted = [(t, k + (MS if t == "/events" and k == 150 * MS else 0), m) for t, k, m in _run()]
    shifted.sort(key=lambda x: x[1])
    d = compare(golden, _write(tmp_path / "b.mcap", shifted)).divergence
    assert d is not None and (d.channel, d.field, d.tick) == ("/events", "<time>", 150)


def test_structure_differences(tmp_path: Path, golden: Path) -> None:
    msgs = _edit(_run(), "/command/left", 5, lambda m: m["values"].append(1.0))
    d = compare(golden, _write(tmp_path / "a.mcap", msgs)).divergence
    assert d is not None and d.field == "values" and (d.expected, d.actual) == (6, 7)
    msgs = _edit(_run(), "/command/left", 6, lambda m: m.__setitem__("tool", 0.3))
    d = compare(golden, _write(tmp_path / "b.mcap", msgs)).divergence
    assert d is not None and d.field == "tool" and d.expected == "<missing>"
    msgs = _edit(_run(), "/command/left", 8, lambda m: m["values"].__setitem__(0, None))
    d = compare(golden, _write(tmp_path / "c.mcap", msgs)).divergence
    assert d is not None and d.tick == 8 and d.actual is None


def test_compare_with_live_messages_and_topic_filter(golden: Path) -> None:
    live = [TraceMessage(t, k, copy.deepcopy(m)) for t, k, m in _run()]
    k = next(i for i in range(500, len(live)) if live[i].topic == "/command/right")
    live[k].data["values"][0] += 1.0
    reader = TraceReader(golden)
    result = compare(reader, [TraceMessage("/meta", 0, reader.meta), *live])
    assert not result.ok and result.divergence is not None
    assert result.divergence.channel == "/command/right"
    assert result.divergence.time_ns == live[k].log_time_ns
    assert compare(golden, live, topics=["/events", "/transitions", "/qp/*"]).ok


def test_tolerance_validation() -> None:
    with pytest.raises(ValueError):
        Tolerance(abs=-1.0)
    assert Tolerance(abs=1e-3, rel=0.1).bound(-2.0) == pytest.approx(0.201)
    assert str(Tolerance()) == "exact"


@given(
    expected=st.floats(-1e6, 1e6, allow_nan=False),
    scale=st.one_of(st.floats(0.0, 2.0), st.floats(0.99, 1.01)),
    sign=st.sampled_from([-1.0, 1.0]),
    atol=st.sampled_from([1e-9, 1e-3, 0.5]),
    rtol=st.sampled_from([0.0, 1e-6, 1e-2]),
)
def test_tolerance_decision_agrees_with_numpy_isclose(
    expected: float, scale: float, sign: float, atol: float, rtol: float
) -> None:
    """The comparison's verdict on one field is numpy.isclose(actual, expected)'s.

    The actual value is placed at ``scale`` times the allowed deviation, so both
    verdicts and the edge (scale near 1) are exercised.
    """
    actual = expected + sign * scale * (atol + rtol * abs(expected))
    spec = ToleranceSpec(rules=(("*", "*", Tolerance(abs=atol, rel=rtol)),))

    def msgs(value: float) -> list[TraceMessage]:
        return [TraceMessage("/tension/estimated", 1000, {"tension_N": value})]

    result = compare(msgs(expected), msgs(actual), spec)
    assert result.ok == bool(np.isclose(actual, expected, rtol=rtol, atol=atol))
