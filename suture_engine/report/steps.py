"""What the robots measured in each state of a recorded run.

Every check a procedure makes is a threshold on something the robots measure: how far
a tool moved before the strand went taut, how high a base estimate rose. The
thresholds are set from runs whose outcome is known. This module reads a trace and
gives, for every visited state, what a real robot would have measured there:

* each robot's tool-tip travel, from its encoders through the forward kinematics
  (3.12): the straight distance from where the state began to where it ended, and the
  length of the path between. Both are distances, so they do not depend on where the
  robot's base stands or how it is turned; the displacement is given in the robot's
  own base frame for the same reason.
* each robot's tension estimate from its base force/torque sensor (7.5-7.10, the
  ``/tension/estimated`` channel): at the state's start, its end, and its peak.

The largest true tension in the state (``/ground_truth/tension``) is given beside them,
marked as ground truth: it is for evaluation, never for a check.

Rows from many runs, each labelled with the run's outcome and knot from its
``summary.json``, are what a new check is calibrated on (``suture steps --csv``).
"""

from __future__ import annotations

import fnmatch
import json
import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from suture_engine.robot.kinematics import forward_kinematics
from suture_engine.trace.channels import (
    GROUND_TRUTH_TENSION,
    TENSION_ESTIMATED,
    TRANSITIONS,
    joint_state_topic,
)

__all__ = ["RobotMeasures", "StateMeasures", "run_label", "state_measures"]

ENDOBOT_JOINTS = 4
"""Joints of an EndoBot (yaw, pitch, roll, insertion); other robots get no travel."""


@dataclass
class RobotMeasures:
    """One robot's measurements over one state.

    Attributes:
        travel_mm: straight distance of the tool tip from the state's start to its end
            [mm], from the encoders (``None``: no joint state, or not an EndoBot).
        path_mm: length of the tool tip's path over the state [mm], every joint-state
            message taken.
        displacement_mm: the tip's displacement in the robot's base frame [mm].
        estimate_start_N, estimate_end_N, estimate_peak_N: the robot's tension estimate
            from its base sensor at the state's first and last tick, and its largest
            value [N] (``None`` when the run recorded no estimate).
    """

    travel_mm: float | None = None
    path_mm: float | None = None
    displacement_mm: tuple[float, float, float] | None = None
    estimate_start_N: float | None = None
    estimate_end_N: float | None = None
    estimate_peak_N: float | None = None


@dataclass
class StateMeasures:
    """One visited state and what was measured during it.

    Attributes:
        state: the state's name (dotted inside a sub-procedure).
        start_s, end_s: simulation times the state was entered and left [s].
        robots: per robot, its :class:`RobotMeasures`.
        true_peak_N: the largest true tension during the state [N]; ground truth, for
            evaluation only (``None`` when the run had no simulated thread).
        true_peak_joint: the thread's joint that peak acted at (an index among the
            ``/ground_truth/suture`` centerline's points; ``None`` when the trace does not
            say, as traces written before 2026-12-06 do not).
    """

    state: str
    start_s: float
    end_s: float
    robots: dict[str, RobotMeasures] = field(default_factory=dict)
    true_peak_N: float | None = None
    true_peak_joint: int | None = None

    @property
    def duration_s(self) -> float:
        """How long the state lasted [s]."""
        return self.end_s - self.start_s


class _Robot:
    """Running sums of one robot over the current state."""

    __slots__ = ("first", "last", "path", "peak", "tip0", "tip1")

    def __init__(self) -> None:
        self.tip0: tuple[float, float, float] | None = None
        self.tip1: tuple[float, float, float] | None = None
        self.path = 0.0
        self.first: float | None = None
        self.last: float | None = None
        self.peak: float | None = None

    def tip(self, position: Sequence[float]) -> None:
        if len(position) != ENDOBOT_JOINTS:
            return
        p = forward_kinematics(position).position
        tip = (float(p[0]), float(p[1]), float(p[2]))
        if self.tip1 is not None:
            self.path += math.dist(tip, self.tip1)
        else:
            self.tip0 = tip
        self.tip1 = tip

    def estimate(self, value: float) -> None:
        if self.first is None:
            self.first = value
        self.last = value
        self.peak = value if self.peak is None else max(self.peak, value)

    def measures(self) -> RobotMeasures:
        out = RobotMeasures(
            estimate_start_N=self.first, estimate_end_N=self.last, estimate_peak_N=self.peak
        )
        if self.tip0 is not None and self.tip1 is not None:
            d = tuple(1e3 * (b - a) for a, b in zip(self.tip0, self.tip1, strict=True))
            out.displacement_mm = (d[0], d[1], d[2])
            out.travel_mm = math.hypot(*d)
            out.path_mm = 1e3 * self.path
        return out

    def carry(self) -> _Robot:
        """A fresh state's sums, starting where this one's tip ended."""
        nxt = _Robot()
        nxt.tip0 = nxt.tip1 = self.tip1
        return nxt


def state_measures(path: str | Path, *, states: Sequence[str] = ()) -> Iterator[StateMeasures]:
    """What the robots measured in every visited state of a trace.

    Args:
        path: a trace (``trace.mcap``); a truncated one is read up to where it stops.
        states: glob patterns of the states to give (``mirrored-knot.*``, matched with
            or without the mode: ``autonomous/mirrored-knot.*``); all when empty. Only
            the names are filtered: every state is still read.

    Yields:
        One :class:`StateMeasures` per visited state, in order (a state visited twice
        gives two rows).

    Raises:
        TraceError: the trace cannot be read.
    """
    from suture_engine.trace.reader import TraceReader

    reader = TraceReader(path)
    robots = [str(r) for r in reader.meta.get("robots", [])]
    joint_topics = {joint_state_topic(r): r for r in robots}
    topics = [TRANSITIONS, TENSION_ESTIMATED, GROUND_TRUTH_TENSION, *joint_topics]
    sums = {r: _Robot() for r in robots}
    state: str | None = None
    start = 0.0
    t = 0.0
    true_peak: float | None = None
    true_joint: int | None = None

    def row(end: float) -> StateMeasures:
        return StateMeasures(
            state or "(start)",
            start,
            end,
            {r: s.measures() for r, s in sums.items()},
            true_peak,
            true_joint,
        )

    def wanted(name: str) -> bool:
        # a state is named with its mode (``autonomous/tighten``); a pattern may leave
        # the mode out
        bare = name.rsplit("/", 1)[-1]
        return not states or any(
            fnmatch.fnmatchcase(name, p) or fnmatch.fnmatchcase(bare, p) for p in states
        )

    for msg in reader.messages(topics):
        t = msg.log_time_ns * 1e-9
        topic = msg.topic
        if topic in joint_topics:
            sums[joint_topics[topic]].tip(msg.data["position"])
        elif topic == TENSION_ESTIMATED:
            # one entry per robot; traces written before the per-robot list carry the
            # running step's robot alone
            entries = msg.data.get("estimates") or [msg.data]
            for entry in entries:
                robot = str(entry.get("robot"))
                if robot in sums and entry.get("tension_N") is not None:
                    sums[robot].estimate(float(entry["tension_N"]))
        elif topic == GROUND_TRUTH_TENSION:
            value = msg.data.get("tension_N")  # null: a non-finite reading, skipped
            if value is not None and math.isfinite(value):
                if true_peak is None or value > true_peak:
                    true_peak, joint = float(value), msg.data.get("joint")
                    true_joint = None if joint is None else int(joint)
        else:
            if state is None:
                state = str(msg.data["source"])
            if wanted(state):
                yield row(t)
            state, start, true_peak, true_joint = str(msg.data["dest"]), t, None, None
            sums = {r: s.carry() for r, s in sums.items()}
    if wanted(state or "(start)"):
        yield row(t)


def run_label(trace: str | Path) -> dict[str, Any]:
    """The outcome and knot of the run a trace belongs to, from the ``summary.json``
    beside it: ``{"outcome": ..., "knot": "square"}`` (several knots joined by ``+``);
    empty when there is no readable summary."""
    summary = Path(trace).with_name("summary.json")
    try:
        data = json.loads(summary.read_text())
    except (OSError, ValueError):
        return {}
    knots: Iterable[Any] = data.get("knot") or []
    if isinstance(knots, dict):
        knots = [knots]
    kinds = [str(k.get("type")) for k in knots if isinstance(k, dict)]
    return {"outcome": data.get("outcome"), "knot": "+".join(kinds) or None}
