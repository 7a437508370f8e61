"""The replay backend: serves a recorded trace's measurements tick by tick.

No physics: at tick k, :meth:`ReplayBackend.observe` returns the encoder
positions (``/joint_state/<robot>``) and base wrenches (``/base_wrench/<robot>``)
recorded at tick k, and the tool joints a trace records (``/tool_state/<robot>``: a
bent-tip grasper's measured bend, as last recorded at or before tick k; straight when a
trace, e.g. an older one, records none; ``/hook_load/<robot>``: the hook actuator's load
likewise, 0 when none is recorded), so the engine recomputes its commands and events from the
very measurements of the recorded run. :func:`recorded_operator_events` gives the
recorded operator events so they can be fed back at the same ticks. A truncated
trace (a killed run) is served up to its last complete tick.

The comparison of the engine's new commands and events with the recorded ones
is :func:`suture_engine.runtime.replay.replay_trace`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from backends.base import BackendError
from suture_engine.runtime.observation import (
    Command,
    Measurement,
    RobotMeasurement,
    SceneGeometry,
    ToolState,
    scene_geometry,
)
from suture_engine.runtime.operator import OperatorEvent

__all__ = ["EndOfRecording", "ReplayBackend", "recorded_operator_events"]

_DURATION = re.compile(r"duration=([-+0-9.eE]+)")
_VELOCITY = re.compile(r"velocity=\[([^\]]*)\]")
_STIFFNESS = re.compile(r"stiffness=([-+0-9.eE]+)")


class EndOfRecording(BackendError):
    """The recording has no measurement for the tick asked for.

    Attributes:
        tick: the tick asked for.
    """

    code = "end-of-recording"

    def __init__(self, tick: int) -> None:
        super().__init__("replay", f"the recording ends before tick {tick}")
        self.tick = tick


def _last_recorded(series: tuple[list[int], list[Any]], tick: int, default: Any) -> Any:
    """The value of ``series`` (the ticks it changed at, sorted, and its values) recorded
    last at or before ``tick``; ``default`` before its first change."""
    import bisect

    ticks, values = series
    i = bisect.bisect_right(ticks, tick) - 1
    return values[i] if i >= 0 else default


class ReplayBackend:
    """Serves the measurements of a recorded trace.

    Args:
        trace: the trace file (or a path-like).
        reader: an already open :class:`suture_engine.trace.reader.TraceReader`.
    """

    name = "replay"

    def __init__(self, trace: str | Path | None = None, reader: Any = None) -> None:
        from suture_engine.trace.reader import TraceReader

        if reader is None:
            if trace is None:
                raise BackendError(self.name, "needs a trace to replay")
            reader = TraceReader(trace)
        self.reader = reader
        self.meta: dict[str, Any] = dict(reader.meta)
        self.rate = float(self.meta.get("control_rate_hz", 1000.0))
        self.period_ns = round(1e9 / self.rate)
        self.dt = 1.0 / self.rate
        """The tick's period [s], as the live backends hold it (1e-3 at 1 kHz)."""
        self.robots: tuple[str, ...] = tuple(self.meta.get("robots") or ())
        self._q: dict[str, dict[int, list[float]]] = {r: {} for r in self.robots}
        self._w: dict[str, dict[int, list[float]]] = {r: {} for r in self.robots}
        self.commands: dict[str, dict[int, list[float]]] = {r: {} for r in self.robots}
        bends: dict[str, dict[int, tuple[float, float]]] = {}
        loads: dict[str, dict[int, float]] = {}
        for msg in reader.messages():
            topic = msg.topic
            tick = round(msg.log_time_ns / self.period_ns)
            if topic.startswith("/joint_state/"):
                self._q.setdefault(topic[13:], {})[tick] = msg.data["position"]
            elif topic.startswith("/base_wrench/"):
                data = msg.data
                self._w.setdefault(topic[13:], {})[tick] = list(data["force"]) + list(
                    data["torque"]
                )
            elif topic.startswith("/command/"):
                self.commands.setdefault(topic[9:], {})[tick] = msg.data["values"]
            elif topic.startswith("/tool_state/"):
                bend = msg.data["bend"]
                bends.setdefault(topic[12:], {})[tick] = (float(bend[0]), float(bend[1]))
            elif topic.startswith("/hook_load/"):
                loads.setdefault(topic[11:], {})[tick] = float(msg.data["load"])
        if not self.robots:
            self.robots = tuple(sorted(self._q))
        self.last_tick = self._last_complete_tick()
        self.tick = 0
        # Read-only (q, wrench) arrays per (robot, tick), built once here, off the tick's
        # hot path, and shared by every observation of that tick. A malformed entry is left
        # out and raises when observed, as before.
        self._frozen: dict[tuple[str, int], tuple[Any, Any]] = {}
        for r in self.robots:
            ws = self._w.get(r, {})
            for k, q in self._q.get(r, {}).items():
                w = ws.get(k)
                if w is None or len(q) != 4 or len(w) != 6:
                    continue
                qa = np.array(q, dtype=np.float64)
                wa = np.array(w, dtype=np.float64)
                qa.flags.writeable = False
                wa.flags.writeable = False
                self._frozen[(r, k)] = (qa, wa)
        self.last_applied: Command | None = None
        # per robot: the ticks at which the recorded bend changed, and the bends
        self._bends = {r: (sorted(b), [b[k] for k in sorted(b)]) for r, b in bends.items() if b}
        # likewise the ticks at which the recorded hook load changed, and the loads
        self._loads = {r: (sorted(v), [v[k] for k in sorted(v)]) for r, v in loads.items() if v}
        self._tools: dict[str, ToolState] = {r: ToolState() for r in self.robots}
        self._geometry = SceneGeometry()

    def _last_complete_tick(self) -> int:
        """The last tick with positions and wrenches of every robot, consecutive from 0."""
        k = -1
        while all(k + 1 in self._q.get(r, {}) and k + 1 in self._w.get(r, {}) for r in self.robots):
            k += 1
        return k

    @property
    def exhausted(self) -> bool:
        """True when the next tick to observe is not in the recording."""
        return self.tick > self.last_tick

    def reset(self, scene: Any = None, seed: int = 0) -> Measurement:
        """Rewind to tick 0; ``scene`` and ``seed`` are those of the recorded run.

        Raises:
            EndOfRecording: the recording holds no complete tick.
        """
        del seed
        self.tick = 0
        self.last_applied = None
        self._geometry = scene_geometry(scene)
        robots = getattr(scene, "robots", None) or {}
        self._tools = {
            r: ToolState(kind=str(robots[r].tool)) if r in robots else ToolState()
            for r in self.robots
        }
        return self.observe()

    def observe(self) -> Measurement:
        """The recorded measurement of the current tick.

        Raises:
            EndOfRecording: past the last complete tick.
        """
        if self.tick > self.last_tick:
            raise EndOfRecording(self.tick)
        k = self.tick
        robots = {}
        for r in self.robots:
            frozen = self._frozen.get((r, k))
            if frozen is None:  # malformed: the checked constructor says why
                probe = RobotMeasurement(np.array(self._q[r][k]), np.array(self._w[r][k]))
                frozen = self._frozen[(r, k)] = (probe.q, probe.base_wrench)
            tool = self._tools.get(r) or ToolState()
            if r in self._bends:
                bend = _last_recorded(self._bends[r], k, (0.0, 0.0))
                if bend != tool.bend:
                    tool = replace(tool, bend=bend)
            if r in self._loads:
                load = _last_recorded(self._loads[r], k, 0.0)
                if load != tool.hook_load:
                    tool = replace(tool, hook_load=load)
            robots[r] = RobotMeasurement.trusted(frozen[0], frozen[1], tool)
        # tick * dt, to the bit as the live backends compute a tick's time (k * period_ns
        # * 1e-9 is a different float on some ticks, and a skill's trajectory sampled at
        # it then differs in the last bit from the recorded run's)
        return Measurement.trusted(k, k * self.dt, robots)

    def apply(self, command: Command) -> None:
        """Keep the last command (the comparison reads the trace the engine writes) and
        update the reported tool states from its tool commands, as the live backend does."""
        self.last_applied = command
        for name, rc in command.robots.items():
            tc = rc.tool
            if tc is None:
                continue
            t = self._tools.get(name, ToolState())
            self._tools[name] = ToolState(
                t.kind,
                t.jaw_closed if tc.jaw_closed is None else tc.jaw_closed,
                t.jaw2_closed if tc.jaw2_closed is None else tc.jaw2_closed,
                t.hook_extension if tc.hook_extension is None else tc.hook_extension,
            )

    def apply_external_force(
        self, robot: str, force: tuple[float, float, float], duration: float
    ) -> None:
        """Nothing to do: the recorded measurements already felt the force."""
        del robot, force, duration

    def apply_operator_hand(
        self, robot: str, velocity: tuple[float, float, float], stiffness: float, duration: float
    ) -> None:
        """Nothing to do: the recorded measurements already felt the hand."""
        del robot, velocity, stiffness, duration

    def cut_suture(self, withdraw: bool = False) -> None:
        """The recorded run's suture was cut here (``cut-suture``): the measurements that
        follow are of the world after the cut; there is nothing to change, and no ground
        truth to give.

        Args:
            withdraw: the suture was withdrawn, not kept (unused).
        """
        del withdraw

    def remove_posts(self) -> None:
        """The recorded run's calibration posts were taken away here (``remove-posts``):
        nothing to change."""

    def load_suture(self, entry: str, exit: str) -> None:
        """The recorded run loaded the next stitch's suture here (``load-suture``): as
        :meth:`cut_suture`, nothing to change.

        Args:
            entry: the stitch's entry point's name (unused).
            exit: its exit point's name (unused).
        """

    def step(self) -> None:
        """Move to the next recorded tick."""
        self.tick += 1

    def geometry(self) -> SceneGeometry:
        """The geometry the scene given to :meth:`reset` declares (as the live backend)."""
        return self._geometry

    def ground_truth(self) -> Mapping[str, Any]:
        """None: a recording replays no physics."""
        return {}

    def close(self) -> None:
        """Nothing to release."""


class _ReplayOperator:
    def __init__(self, events: dict[int, list[OperatorEvent]], rate: float) -> None:
        self._events = events
        self._rate = rate

    @property
    def exhausted(self) -> bool:
        return False

    def poll(self, t: float, state: str, step: str | None, mode: str) -> list[OperatorEvent]:
        return self._events.pop(round(t * self._rate), [])


def recorded_operator_events(reader: Any, rate: float) -> _ReplayOperator:
    """An operator source that re-issues the trace's ``/operator`` events at their ticks."""
    period_ns = round(1e9 / rate)
    events: dict[int, list[OperatorEvent]] = {}
    for msg in reader.messages(["/operator"]):
        d = msg.data
        detail = d.get("detail") or ""
        m = _DURATION.search(detail)
        force = d.get("force")
        vel = _VELOCITY.search(detail)
        stiff = _STIFFNESS.search(detail)
        velocity = tuple(float(v) for v in vel.group(1).split(",")) if vel else None
        ev = OperatorEvent(
            action=d["action"],
            step=d.get("target_state"),
            robot=d.get("robot"),
            force=tuple(force) if force is not None else None,
            duration=float(m.group(1)) if m else 0.0,
            source=d.get("source") or "replay",
            velocity=velocity,  # type: ignore[arg-type]
            stiffness=float(stiff.group(1)) if stiff else 0.0,
        )
        events.setdefault(round(msg.log_time_ns / period_ns), []).append(ev)
    return _ReplayOperator(events, rate)
