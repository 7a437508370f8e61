"""The trace record of injected faults: one message at each onset and each end.

Messages go on ``/faults`` when the trace catalogue has that channel; otherwise
on ``/events`` as ``info`` events named ``fault:<kind>`` whose ``detail`` is
the record as JSON. :func:`read_faults` reads either form back.

A record: ``kind``, ``phase`` (``start`` or ``end``), ``target`` (``ft``,
``encoders``, a joint, ``grasp``, ``suture``, ``physics``), ``robot`` (None:
every robot), ``trigger`` (``at``, ``when <state>``, ``rate``, ``probability``),
``index`` (the fault's position in the run's list), ``params`` (the fault's
fields, SI) and the message's log time = the tick's simulation time [ns].
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from suture_engine.faults.model import Fault
from suture_engine.faults.schedule import Onset

__all__ = [
    "FAULTS_TOPIC",
    "FaultRecord",
    "fault_message",
    "faults_topic",
    "read_faults",
    "trace_sink",
]

FAULTS_TOPIC = "/faults"
"""The channel of injected faults (when the trace catalogue has it)."""

_EVENTS = "/events"


@dataclass(frozen=True)
class FaultRecord:
    """One fault record read back from a trace.

    Attributes:
        t: simulation time [s].
        kind: the fault kind.
        phase: ``start`` or ``end``.
        target: what it acts on.
        robot: the robot, or None for every robot.
        trigger: how it was triggered.
        index: the fault's index in the run's list.
        params: the fault's parameters (SI).
    """

    t: float
    kind: str
    phase: str
    target: str
    robot: str | None
    trigger: str
    index: int
    params: Mapping[str, Any]


def faults_topic() -> str:
    """``/faults`` if the trace catalogue has it, else ``/events`` (the fallback)."""
    from suture_engine.trace import channels
    from suture_engine.trace.errors import UnknownChannelError

    try:
        channels.spec_for(FAULTS_TOPIC)
    except UnknownChannelError:
        return _EVENTS
    return FAULTS_TOPIC


def _trigger(fault: Fault) -> str:
    if fault.rate is not None:
        return "rate"
    if fault.probability is not None:
        return "probability"
    if fault.when is not None:
        return f"when {fault.when}"
    return "at"


def fault_message(
    onset: Onset, phase: str, extra: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """The ``/faults`` message of ``onset`` at its ``phase`` (``start`` or ``end``)."""
    f = onset.fault
    params = {
        k: v
        for k, v in f.model_dump(exclude_none=True, exclude_defaults=True).items()
        if k not in ("kind", "robot", "sensor")
    }
    params["occurrence"] = onset.occurrence
    if extra:
        params.update(extra)
    return {
        "kind": f.kind,
        "phase": phase,
        "target": f.target,
        "robot": f.robot,
        "trigger": _trigger(f),
        "index": onset.index,
        "params": params,
    }


def trace_sink(writer: Any) -> Callable[[int, dict[str, Any]], None]:
    """A sink writing fault messages to a :class:`~suture_engine.trace.writer.TraceWriter`."""
    topic = faults_topic()
    if topic == FAULTS_TOPIC:

        def write(time_ns: int, message: dict[str, Any]) -> None:
            writer.write(FAULTS_TOPIC, time_ns, message)

        return write

    def write_event(time_ns: int, message: dict[str, Any]) -> None:
        writer.write(
            _EVENTS,
            time_ns,
            {
                "name": f"fault:{message['kind']}",
                "kind": "info",
                "state": None,
                "robot": message.get("robot"),
                "detail": json.dumps(message, sort_keys=True, separators=(",", ":")),
            },
        )

    return write_event


def read_faults(trace: str | Path) -> list[FaultRecord]:
    """The fault records of a trace, in time order (either channel form).

    Raises:
        TraceError: the trace cannot be read.
    """
    from suture_engine.trace.reader import TraceReader

    out: list[FaultRecord] = []
    for msg in TraceReader(trace).messages([FAULTS_TOPIC, _EVENTS]):
        data = msg.data
        if msg.topic == _EVENTS:
            if not str(data.get("name", "")).startswith("fault:"):
                continue
            data = json.loads(data.get("detail") or "{}")
        out.append(
            FaultRecord(
                t=msg.log_time_ns * 1e-9,
                kind=str(data["kind"]),
                phase=str(data["phase"]),
                target=str(data["target"]),
                robot=data.get("robot"),
                trigger=str(data.get("trigger", "")),
                index=int(data.get("index", 0)),
                params=dict(data.get("params") or {}),
            )
        )
    return out
