"""Writes a run's messages to the trace channels of :mod:`suture_engine.trace.channels`.

Every tick: ``/joint_state/<robot>`` (encoder positions and *estimated*
velocities), ``/base_wrench/<robot>``, ``/command/<robot>`` (the torques
applied and the robot's mode), ``/tension/estimated`` and, when the backend has
them, ``/ground_truth/tension`` (every tick) and ``/ground_truth/suture``
(every ``centerline_every`` ticks), ``/tool_state/<robot>`` (the measured bend of a
bent-tip grasper's universal joint, on the ticks it changes: never while it stays
straight, so the traces of runs without a bend are unchanged), ``/hook_load/<robot>``
(the flexible hook's actuator load, likewise on the ticks it changes). On events:
``/transitions``, ``/events``, ``/operator``, ``/ground_truth/suture_cut`` (a cut
thread's last centerline, :mod:`skills.reload`). Time is simulation time: tick * period [ns].
"""

from __future__ import annotations

import json
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
_STRAIGHT = (0.0, 0.0)


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

    def event(
        self,
        time_ns: int,
        name: str,
        kind: str,
        state: str,
        detail: str,
        robot: str | None = None,
    ) -> None:
        """Record an event that changes no state (e.g. a refused operator action, a
        backend's event); ``robot``: the robot concerned, if any."""

    def qp(self, time_ns: int, robot: str, result: Any) -> None:
        """Record one QP solve's status (a ``constrained_qp.QPResult``)."""

    def suture_cut(self, time_ns: int, centerline: Any) -> None:
        """Record a cut thread's last centerline [m] (N x 3; ground truth)."""

    def close(self) -> None:
        """Finish the trace."""


class TraceRecorder(Recorder):
    """Records into an MCAP trace through :class:`suture_engine.trace.writer.TraceWriter`.

    The per-tick channels are encoded here, from templates, and handed to the writer as
    one batch per tick (:meth:`~suture_engine.trace.writer.TraceWriter.write_encoded`):
    the same bytes as the generic path (``fast=False``: a dict per message through
    :func:`suture_engine.trace.codec.encode`), which takes over for any message the
    templates do not cover (a non-finite value, an array that is not float64).
    ``tests/test_trace_recorder.py`` compares both paths byte for byte. A ``/qp``
    message waits for the tick's batch (or the next transition, event or operator
    message), so messages keep the order of the calls.

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
        fast: encode the per-tick channels from templates (False: one dict per message
            through the generic encoder; same bytes, several times slower).
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
        fast: bool = True,
    ) -> None:
        from suture_engine.trace import channels, codec
        from suture_engine.trace.writer import TraceMeta, TraceWriter

        self._ch = channels
        self._encode = codec.encode
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
        self._qp_topics: dict[str, str] = {}
        self._every = max(1, int(centerline_every))
        self._n = 0
        self._fast = bool(fast)
        self._json_str: dict[Any, str] = {}
        self._json_bytes: dict[Any, bytes] = {}
        self._encode_vectors = codec.encode_vectors
        self._qp_prefix: dict[tuple[str, ...], str] = {}
        self._queued: list[tuple[str, bytes]] = []
        self._queued_ns = 0
        self._wall_clock = self.writer.include_wall_clock
        self._bends: dict[str, tuple[float, float]] = {}
        self._hook_loads: dict[str, float] = {}

    # -- the per-tick fast path -------------------------------------------------------------

    def _str(self, value: Any) -> str:
        """A string (or None) as JSON text, cached (robot names, modes, QP statuses)."""
        text = self._json_str.get(value)
        if text is None:
            text = self._json_str[value] = json.dumps(value, ensure_ascii=False)
        return text

    def _bytes(self, value: Any) -> bytes:
        """:meth:`_str` as UTF-8 bytes, cached."""
        data = self._json_bytes.get(value)
        if data is None:
            data = self._json_bytes[value] = self._str(value).encode()
        return data

    def _drain(self) -> None:
        """Write the queued ``/qp`` messages (before anything else of a later call)."""
        if self._queued:
            queued, self._queued = self._queued, []
            self.writer.write_encoded(self._queued_ns, queued)

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
        if self._queued and self._queued_ns != time_ns:
            self._drain()
        batch = self._queued
        self._queued = []
        robot_name = max(tension, key=lambda k: tension[k]) if tension else None
        true_tension = ground_truth.get("tension_N")
        # where along the thread the true tension acts (a backend may not say)
        joint = ground_truth.get("tension_joint") if true_tension is not None else None
        true = None if true_tension is None else (true_tension, joint)
        fast = self._fast and self._tick_fast(batch, obs, torques, modes, tension, robot_name, true)
        if not fast:
            self._tick_generic(batch, obs, torques, modes, tension, robot_name, true)
        self.writer.write_encoded(time_ns, batch)
        for name, robot in obs.robots.items():
            bend = robot.tool.bend
            if bend != self._bends.get(name, _STRAIGHT):
                self._bends[name] = bend
                topic = self._ch.tool_state_topic(name)
                self.writer.write(topic, time_ns, {"bend": [float(bend[0]), float(bend[1])]})
            load = robot.tool.hook_load
            if load != self._hook_loads.get(name, 0.0):
                self._hook_loads[name] = load
                self.writer.write(self._ch.hook_load_topic(name), time_ns, {"load": float(load)})
        # The centerline is looked up on its ticks only: a backend may compute it lazily.
        centerline = ground_truth.get("centerline") if self._n % self._every == 0 else None
        if centerline is not None:
            pts = [_floats(p) for p in centerline]
            self.writer.write(self._ch.GROUND_TRUTH_SUTURE, time_ns, {"centerline": pts})
        self._n += 1

    def _tick_fast(
        self,
        batch: list[tuple[str, bytes]],
        obs: Observation,
        torques: Mapping[str, Any],
        modes: Mapping[str, str],
        tension: Mapping[str, float],
        robot_name: str | None,
        true: tuple[Any, Any] | None,
    ) -> bool:
        """The tick's messages from templates, every vector encoded in one call; False
        (nothing appended) when a vector is not a float64 NumPy vector, or the base
        wrench does not have six values."""
        vectors: list[Any] = []
        for name, robot in obs.robots.items():
            wr = robot.base_wrench
            if len(wr) != 6:
                return False
            vectors += (robot.q, robot.qd, wr)
            tau = torques.get(name)
            if tau is not None:
                vectors.append(tau)
        if robot_name is not None:
            vectors.append([float(v) for v in tension.values()])
        if true is not None:
            vectors.append([float(true[0])])
        texts = self._encode_vectors(vectors)
        if texts is None:
            return False
        k = 0
        for name in obs.robots:
            js, bw, cmd = self._topics[name]
            batch.append((js, b'{"position":[%b],"velocity":[%b]}' % (texts[k], texts[k + 1])))
            w = texts[k + 2]  # six numbers: the third comma splits force from torque
            i = w.index(b",", w.index(b",", w.index(b",") + 1) + 1)
            batch.append((bw, b'{"force":[%b],"torque":[%b]}' % (w[:i], w[i + 1 :])))
            k += 3
            if torques.get(name) is not None:
                mode = self._bytes(modes.get(name))
                batch.append((cmd, b'{"kind":"torque","mode":%b,"values":[%b]}' % (mode, texts[k])))
                k += 1
        if robot_name is not None:
            values = texts[k].split(b",")  # a number's text holds no comma
            each = b",".join(
                b'{"robot":%b,"tension_N":%b}' % (self._bytes(name), value)
                for name, value in zip(tension, values, strict=True)
            )
            top = values[list(tension).index(robot_name)]
            text = b'{"estimates":[%b],"robot":%b,"tension_N":%b}' % (
                each,
                self._bytes(robot_name),
                top,
            )
            batch.append((self._ch.TENSION_ESTIMATED, text))
            k += 1
        if true is not None:
            if true[1] is None:
                text = b'{"tension_N":%b}' % texts[k]
            else:
                text = b'{"joint":%d,"tension_N":%b}' % (int(true[1]), texts[k])
            batch.append((self._ch.GROUND_TRUTH_TENSION, text))
        return True

    def _tick_generic(
        self,
        batch: list[tuple[str, bytes]],
        obs: Observation,
        torques: Mapping[str, Any],
        modes: Mapping[str, str],
        tension: Mapping[str, float],
        robot_name: str | None,
        true: tuple[Any, Any] | None,
    ) -> None:
        """The tick's messages as dicts through the generic encoder."""
        encode = self._encode
        for name, robot in obs.robots.items():
            js, bw, cmd = self._topics[name]
            batch.append(
                (js, encode({"position": _floats(robot.q), "velocity": _floats(robot.qd)}))
            )
            wr = robot.base_wrench
            batch.append((bw, encode({"force": _floats(wr[:3]), "torque": _floats(wr[3:])})))
            tau = torques.get(name)
            if tau is not None:
                msg = {"kind": "torque", "values": _floats(tau), "mode": modes.get(name)}
                batch.append((cmd, encode(msg)))
        if robot_name is not None:
            msg2 = {
                "tension_N": float(tension[robot_name]),
                "robot": robot_name,
                "estimates": [{"robot": n, "tension_N": float(v)} for n, v in tension.items()],
            }
            batch.append((self._ch.TENSION_ESTIMATED, encode(msg2)))
        if true is not None:
            msg3: dict[str, Any] = {"tension_N": float(true[0])}
            if true[1] is not None:
                msg3["joint"] = int(true[1])
            batch.append((self._ch.GROUND_TRUTH_TENSION, encode(msg3)))

    def transition(self, time_ns: int, record: TransitionRecord) -> None:
        """Record one transition on ``/transitions`` and its event on ``/events``."""
        self._drain()
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
        self._drain()
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

    def event(
        self,
        time_ns: int,
        name: str,
        kind: str,
        state: str,
        detail: str,
        robot: str | None = None,
    ) -> None:
        """Record an event on ``/events`` (with ``robot`` when one is given)."""
        self._drain()
        msg: dict[str, Any] = {
            "name": name,
            "kind": _EVENT_KIND.get(kind, "info"),
            "state": state,
            "detail": detail,
        }
        if robot is not None:
            msg["robot"] = robot
        self.writer.write(self._ch.EVENTS, time_ns, msg)

    def suture_cut(self, time_ns: int, centerline: Any) -> None:
        """Record a cut thread's last centerline on ``/ground_truth/suture_cut``."""
        self._drain()
        pts = [_floats(p) for p in centerline]
        self.writer.write(self._ch.GROUND_TRUTH_SUTURE_CUT, time_ns, {"centerline": pts})

    def qp(self, time_ns: int, robot: str, result: Any) -> None:
        """Record one QP solve on ``/qp/<robot>`` (the wall-clock solve time is dropped).

        The message is queued and written with the tick's batch (or before the next
        message of another kind): the file is the same as with an immediate write.
        """
        if self._queued and self._queued_ns != time_ns:
            self._drain()
        topic = self._qp_topics.get(robot)
        if topic is None:
            topic = self._qp_topics[robot] = self._ch.qp_topic(robot)
        status = str(result.status)
        active = tuple(result.active)
        iterations = int(result.iterations)
        prefix = self._qp_prefix.get(active) if self._fast else None
        if prefix is None and self._fast and all(type(a) is str for a in active):
            prefix = '{"active_constraints":' + json.dumps(
                list(active), ensure_ascii=False, separators=(",", ":")
            )
            self._qp_prefix[active] = prefix
        if prefix is not None and not self._wall_clock:
            text = prefix + ',"iterations":' + str(iterations) + ',"status":' + self._str(status)
            data = (text + "}").encode()
        else:
            msg: dict[str, Any] = {
                "status": status,
                "iterations": iterations,
                "active_constraints": list(active),
            }
            if self._wall_clock:
                msg["solve_time_us"] = float(result.solve_time_s) * 1e6
            data = self._encode(msg)
        self._queued_ns = time_ns
        self._queued.append((topic, data))

    def close(self) -> None:
        """Write the queued messages, the footer, and close the file."""
        try:
            self._drain()
        finally:
            self.writer.close()
