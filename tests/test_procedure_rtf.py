"""The reading of PyBullet's timing log in ``benchmarks/procedure_rtf.py``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from benchmark_modules import load_benchmark

rtf = load_benchmark("procedure_rtf")


def _scope(name: str, counter: int, t0: float, t1: float) -> list[dict[str, object]]:
    """One scope as PyBullet writes it: a B event and its E event, the name counted."""
    common = {"cat": "timing", "pid": 1, "tid": 0, "args": {}}
    return [
        {**common, "ts": t0, "ph": "B", "name": f"{name}{counter}"},
        {**common, "ts": t1, "ph": "E", "name": f"{name}{counter}"},
    ]


def _two_steps() -> list[dict[str, object]]:
    # Written as PyBullet does, an inner scope before the scope that holds it. Step 1:
    # 1000 us, its solver 600 us, its AABB update 150 us, 3 contacts; step 2: 800 us,
    # solver 500 us, AABB 130 us, 1 contact and 2 friction constraints.
    events: list[dict[str, object]] = []
    n = 0
    for t, whole, solver, aabb, contacts, friction in (
        (0.0, 1000.0, 600.0, 150.0, 3, 0),
        (5000.0, 800.0, 500.0, 130.0, 1, 2),
    ):
        for _ in range(contacts):
            events += _scope("setupMultiBodyContactConstraint", n, t + 1, t + 2)
            n += 1
        for _ in range(friction):
            events += _scope("addMultiBodyFrictionConstraint", n, t + 2, t + 3)
            n += 1
        events += _scope("processIslands", n, t + 10, t + 10 + solver)
        events += _scope("updateAabbs", n + 1, t + 700, t + 700 + aabb)
        events += _scope("internalSingleStepSimulation", n + 2, t, t + whole)
        n += 3
    return events


def test_phases_are_summed_per_step(tmp_path: Path) -> None:
    path = tmp_path / "timings_0.json"
    path.write_text(json.dumps({"traceEvents": _two_steps(), "displayTimeUnit": "ns"}))
    phases = rtf.simulator_phases(path)
    assert phases.steps == 2
    assert phases.us_per_step["internalSingleStepSimulation"] == pytest.approx(900.0)
    assert phases.us_per_step["processIslands"] == pytest.approx(550.0)
    assert phases.us_per_step["updateAabbs"] == pytest.approx(140.0)
    # a scope the log does not hold reads zero
    assert phases.us_per_step["dispatchAllCollisionPairs"] == 0.0
    assert phases.per_step == {"contact constraints": 2.0, "friction constraints": 1.0}
    text = rtf.phases_report(phases)
    assert "550.0 us per step ( 61.1 %)" in text
    assert "2.0 contact constraints, 1.0 friction constraints" in text


def test_a_log_without_a_step_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "timings_0.json"
    path.write_text(json.dumps({"traceEvents": _scope("b3ProcessServerStatus", 0, 0, 1)}))
    with pytest.raises(ValueError, match="no physics step"):
        rtf.simulator_phases(path)
