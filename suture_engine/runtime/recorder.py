"""Writes a run's messages to the trace channels of :mod:`suture_engine.trace.channels`.

Every tick: ``/joint_state/<robot>`` (encoder positions and *estimated*
velocities), ``/base_wrench/<robot>``, ``/command/<robot>`` (the torques
applied and the robot's mode), ``/tension/estimated`` and, when the backend has
them, ``/ground_truth/tension`` (every tick) and ``/ground_truth/suture``
(every ``centerline_every`` ticks). On events: ``/transitions``, ``/events``,
``/operator``. Time is simulation time: tick * period [ns].
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from suture_engine.runtime.automaton import TransitionRecord
from suture_engine.runtime.observation import Observation
from suture_engine.runtime.operator import OperatorEvent

__all__ = ["Recorder", "TraceRecorder"]

_EVENT_KIND = {"planned": "planned", "unpredictable": "unpredictable", "operator": "operator"}


def _floats(values: Any) -> list[float]:
    if type(values) is np.ndarray:
        if values.dtype is not _F64:
            values = values.astype(np.float64)
        out: list[float] = values.tolist()
        return out
    if isinstance(values, np.ndarray):
        return values.astype(np.float64).tolist()  # type: ignore[no-any-return]
    return [float(v) for v in values]


_F64 = np.dtype(np.float64)


class Recorder:
    """A recorder that keeps nothing (for runs without a trace); the base of the others."""

    def tick(
        self,
        time_ns: int,
        obs: Observation,
        torques: Mapping[str, Any],
        modes: Mapping[str, str],
        tension: Mapping[str, float],
        ground_truth: Mapping[str, Any],
    ) -> None:
        """Record one tick's measurements, commands and estimates."""

    def transition(self, time_ns: int, record: TransitionRecord) -> None:
        """Record one transition of the automaton (and its event)."""

    def operator(self, time_ns: int, event: OperatorEvent, accepted: bool, detail: str) -> None:
        """Record one operator event."""

    def event(self, time_ns: int, name: str, kind: str, state: str, detail: str) -> None:
        """Record an event that changes no state (e.g. a refused operator action)."""

    def qp(self, time_ns: int, robot: str, result: Any) -> None:
        """Record one QP solve's status (a ``constrained_qp.QPResult``)."""

    def close(self) -> None:
        """Finish the trace."""


class TraceRecorder(Recorder):
    """Records into an MCAP trace through :class:`suture_engine.trace.writer.TraceWriter`.

    Args:
        path: the trace file.
        procedure: procedure name.
        seed: random seed.
        control_rate_hz: control rate [Hz].
        robots: robot names.
        backend: backend name.
        params: the procedure's parameters as run.
        extra: more metadata (the procedure file, the ``--set`` overrides).
        centerline_every: ticks between two ground-truth centerline messages.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        procedure: str,
        seed: int,
        control_rate_hz: float,
        robots: tuple[str, ...],
        backend: str,
        params: Mapping[str, Any],
        extra: Mapping[str, Any] | None = None,
        centerline_every: int = 100,
    ) -> None:
        from suture_engine.trace import channels
        from suture_engine.trace.writer import TraceMeta, TraceWriter

        self._ch = channels
        meta = TraceMeta(
            procedure=procedure,
            seed=seed,
            control_rate_hz=control_rate_hz,
            params=dict(params),
            robots=robots,
            backend=backend,
            extra=dict(extra or {}),
        )
        self.writer = TraceWriter(path, meta)
        self._topics = {
            r: (
                channels.joint_state_topic(r),
                channels.base_wrench_topic(r),
                channels.command_topic(r),
            )
            for r in robots
        }
        self._every = max(1, int(centerline_every))
        self._n = 0

    def tick(
        self,
        time_ns: int,
        obs: Observation,
        torques: Mapping[str, Any],
        modes: Mapping[str, str],
        tension: Mapping[str, float],
        ground_truth: Mapping[str, Any],
    ) -> None:
        """Record one tick's measurements, commands and estimates."""
        w = self.writer
        for name, robot in obs.robots.items():
            js, bw, cmd = self._topics[name]
            w.write(js, time_ns, {"position": _floats(robot.q), "velocity": _floats(robot.qd)})
            wr = robot.base_wrench
            w.write(bw, time_ns, {"force": _floats(wr[:3]), "torque": _floats(wr[3:])})
            tau = torques.get(name)
            if tau is not None:
                w.write(
                    cmd,
                    time_ns,
                    {"kind": "torque", "values": _floats(tau), "mode": modes.get(name)},
                )
        if tension:
            robot_name = max(tension, key=lambda k: tension[k])
            w.write(
                self._ch.TENSION_ESTIMATED,
                time_ns,
                {"tension_N": float(tension[robot_name]), "robot": robot_name},
            )
        true_tension = ground_truth.get("tension_N")
        if true_tension is not None:
            w.write(self._ch.GROUND_TRUTH_TENSION, time_ns, {"tension_N": float(true_tension)})
        centerline = ground_truth.get("centerline")
        if centerline is not None and self._n % self._every == 0:
            pts = [_floats(p) for p in centerline]
            w.write(self._ch.GROUND_TRUTH_SUTURE, time_ns, {"centerline": pts})
        self._n += 1

    def transition(self, time_ns: int, record: TransitionRecord) -> None:
        """Record one transition on ``/transitions`` and its event on ``/events``."""
        self.writer.write(
            self._ch.TRANSITIONS,
            time_ns,
            {"source": record.source, "dest": record.dest, "trigger": record.event},
        )
        self.writer.write(
            self._ch.EVENTS,
            time_ns,
            {
                "name": record.event,
                "kind": _EVENT_KIND.get(record.kind, "info"),
                "state": record.source,
                "detail": record.reason or None,
            },
        )

    def operator(self, time_ns: int, event: OperatorEvent, accepted: bool, detail: str) -> None:
        """Record one operator event on ``/operator``."""
        msg: dict[str, Any] = {
            "action": event.action,
            "robot": event.robot,
            "target_state": event.step,
            "source": event.source,
            "detail": ("accepted" if accepted else "refused") + (f": {detail}" if detail else ""),
        }
        if event.force is not None:
            msg["force"] = _floats(event.force)
        if event.duration:
            msg["detail"] += f"; duration={event.duration!r}"
        if event.velocity is not None:
            msg["detail"] += f"; velocity={list(event.velocity)!r}; stiffness={event.stiffness!r}"
        self.writer.write(self._ch.OPERATOR, time_ns, msg)

    def event(self, time_ns: int, name: str, kind: str, state: str, detail: str) -> None:
        """Record an event on ``/events``."""
        self.writer.write(
            self._ch.EVENTS,
            time_ns,
            {"name": name, "kind": _EVENT_KIND.get(kind, "info"), "state": state, "detail": detail},
        )

    def qp(self, time_ns: int, robot: str, result: Any) -> None:
        """Record one QP solve on ``/qp/<robot>`` (the wall-clock solve time is dropped)."""
        self.writer.write(
            self._ch.qp_topic(robot),
            time_ns,
            {
                "status": str(result.status),
                "iterations": int(result.iterations),
                "active_constraints": list(result.active),
                "solve_time_us": float(result.solve_time_s) * 1e6,
            },
        )

    def close(self) -> None:
        """Write the footer and close the file."""
        self.writer.close()
