"""The ``suture trace`` and ``suture diff`` commands: inspect and compare trace files.

``suture trace FILE`` prints whether the trace is complete or where it stops,
its metadata and its channels with message counts (``--json`` for a machine
readable form). ``suture diff EXPECTED ACTUAL`` compares two traces with the
default golden tolerances (:data:`~suture_engine.trace.golden.DEFAULT_TOLERANCES`)
and prints the first divergence.

Exit codes: 0 readable / matching, 1 diverging, corrupt, foreign or empty, 2 I/O error.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = ["diff_command", "trace_command"]


def _fail(exc: Exception) -> int:
    from suture_engine.trace.errors import TraceIOError

    print(f"error: {exc}", file=sys.stderr)
    return 2 if isinstance(exc, TraceIOError) else 1


def trace_command(path: Path, *, as_json: bool = False) -> int:
    """Prints a trace's status, metadata and channels.

    Args:
        path: the trace file.
        as_json: print one JSON object instead of text.

    Returns:
        The exit code: 0 readable (complete, or truncated after at least one message),
        1 corrupt, foreign or without a complete message, 2 I/O error.
    """
    from suture_engine.trace.errors import TraceError
    from suture_engine.trace.reader import TraceReader

    try:
        reader = TraceReader(path)
        meta = reader.meta
    except TraceError as exc:
        return _fail(exc)
    s = reader.status
    channels: list[dict[str, Any]] = [
        {"topic": c.topic, "schema": c.schema_name, "messages": s.message_counts.get(c.topic, 0)}
        for c in reader.channels.values()
    ]
    if as_json:
        report: dict[str, Any] = {
            "path": str(path),
            "complete": s.complete,
            "reason": s.reason,
            "truncated_at_ns": s.truncated_at_ns,
            "last_time_ns": s.last_time_ns,
            "message_count": s.message_count,
            "file_size": s.file_size,
            "meta": meta,
            "channels": channels,
        }
        print(json.dumps(report, indent=2, sort_keys=True))
        return 1 if not s.complete and s.message_count == 0 else 0
    end = "—" if s.last_time_ns is None else f"{s.last_time_ns / 1e9:.3f} s"
    state = "complete" if s.complete else f"TRUNCATED ({s.reason}) at byte {s.stop_offset}"
    print(f"{path}: {state}")
    print(f"  {s.message_count} messages, simulated time to {end}, {s.file_size} bytes")
    for key in ("procedure", "seed", "control_rate_hz", "backend", "engine_version"):
        if key in meta:
            print(f"  {key:<16} {meta[key]}")
    # how the run was set up beyond its procedure (the thread's model among the options)
    for key in ("sets", "backend_options", "calibration_error", "faults"):
        if meta.get(key):
            print(f"  {key:<16} {json.dumps(meta[key], sort_keys=True)}")
    width = max((len(c["topic"]) for c in channels), default=0)
    for c in channels:
        print(f"  {c['topic']:<{width}}  {c['messages']:>9}  {c['schema']}")
    if not s.complete and s.message_count == 0:
        print(f"error: {path}: holds no complete message ({s.reason})", file=sys.stderr)
        return 1
    return 0


def diff_command(expected: Path, actual: Path, *, topics: Sequence[str] | None = None) -> int:
    """Compares two traces with the default tolerances and prints the result.

    Args:
        expected: the reference (golden) trace.
        actual: the trace to check.
        topics: topics or globs to compare (default: all).

    Returns:
        The exit code: 0 match, 1 divergence (or an unreadable trace), 2 I/O error.
    """
    from suture_engine.trace.errors import TraceError
    from suture_engine.trace.golden import compare
    from suture_engine.trace.reader import TraceReader

    try:
        result = compare(expected, actual, topics=list(topics) if topics else None)
    except TraceError as exc:
        return _fail(exc)
    for path in (expected, actual):  # a divergence at a trace's end: say which one stops
        status = TraceReader(path).status
        if not status.complete:
            print(
                f"note: {path}: TRUNCATED ({status.reason}) at byte {status.stop_offset}, "
                f"after {status.message_count} messages"
            )
    print(result.text)
    return 0 if result.ok else 1
