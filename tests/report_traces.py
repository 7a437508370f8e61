"""Hand-built traces for the report tests (a known run, written with the trace writer)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from suture_engine.trace import channels
from suture_engine.trace.writer import TraceMeta, TraceWriter

ROBOTS = ("endobot_1", "endobot_2")
RATE_HZ = 100.0


def write_known_trace(
    path: Path,
    *,
    seconds: float = 2.0,
    tension_limit: float | None = 2.0,
    extra_meta: dict[str, Any] | None = None,
    knot: bool = True,
    operator: bool = True,
) -> Path:
    """A 2-robot EndoBot trace with every channel, and ``summary.json`` beside it.

    The stitcher's insertion grows linearly (a straight path along the tool axis),
    the tension ramps up to 1.5 x the limit, the automaton goes
    prepare -> tighten -> tighten~notbe -> (retry) prepare -> finished.
    """
    meta = TraceMeta(
        procedure="known",
        seed=3,
        control_rate_hz=RATE_HZ,
        params={"depth": 0.01},
        robots=ROBOTS,
        backend="test",
        extra=extra_meta or {},
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    ticks = round(seconds * RATE_HZ)
    limit = tension_limit if tension_limit is not None else 2.0
    with TraceWriter(path, meta, include_wall_clock=True, fsync=False) as w:
        w.write(channels.TRANSITIONS, 0, {"source": "idle", "dest": "autonomous/prepare"})
        schedule = {
            round(0.4 * ticks): ("autonomous/prepare", "autonomous/tighten", "advance"),
            round(0.6 * ticks): ("autonomous/tighten", "autonomous/tighten~notbe", "fault"),
            round(0.65 * ticks): ("autonomous/tighten~notbe", "autonomous/prepare", "retry"),
            ticks - 1: ("autonomous/prepare", "finished", "advance"),
        }
        for k in range(ticks):
            t_ns = round(k * 1e9 / RATE_HZ)
            s = k / ticks
            for r, robot in enumerate(ROBOTS):
                q = [0.0, 0.0, 0.0, 0.08 + (0.03 * s if r == 0 else 0.0)]
                w.write(
                    channels.joint_state_topic(robot), t_ns, {"position": q, "velocity": [0.0] * 4}
                )
                w.write(
                    channels.command_topic(robot),
                    t_ns,
                    {"kind": "position", "values": [0.0, 0.0, 0.0, 0.08 + 0.03 * s]},
                )
                f = [0.1 * math.sin(s * 6), 0.0, 0.5 * s]
                w.write(channels.base_wrench_topic(robot), t_ns, {"force": f, "torque": [0.0] * 3})
            w.write(
                channels.qp_topic(ROBOTS[0]),
                t_ns,
                {
                    "status": "solved",
                    "iterations": 5,
                    "active_constraints": ["line[0]", "line[1]"],
                    "solve_time_us": 40.0,
                },
            )
            w.write(channels.TENSION_ESTIMATED, t_ns, {"tension_N": 1.5 * limit * s})
            w.write(channels.GROUND_TRUTH_TENSION, t_ns, {"tension_N": 1.5 * limit * s})
            if k in schedule:
                src, dest, trig = schedule[k]
                kind = "unpredictable" if trig == "fault" else "planned"
                w.write(channels.EVENTS, t_ns, {"name": trig, "kind": kind, "state": src})
                w.write(channels.TRANSITIONS, t_ns, {"source": src, "dest": dest, "trigger": trig})
            if operator and k == round(0.8 * ticks):
                w.write(channels.OPERATOR, t_ns, {"action": "lock", "source": "scripted"})
        if knot:
            w.write(channels.GROUND_TRUTH_KNOT, round((ticks - 1) * 1e9 / RATE_HZ),
                    {"type": "square", "crossings": 6, "seated": True})  # fmt: skip
    summary = {
        "procedure": "known",
        "outcome": "succeeded",
        "final_state": "finished",
        "sim_time_s": seconds,
        "tension_limit_N": tension_limit,
        "max_tension_N": 1.5 * limit,
        "violations": [],
        "retries": 1,
        "operator_events": 1,
        "metrics": {},
        "knot": None,
    }
    path.with_name("summary.json").write_text(json.dumps(summary), encoding="utf-8")
    return path
