"""Typed errors of the trace subsystem.

Every failure to write, read or compare a trace raises a subclass of
:class:`TraceError`, which carries the file and a short reason, so the CLI can
print one located line and never a traceback.
"""

from __future__ import annotations

from suture_engine.errors import SutureError

__all__ = [
    "TraceCorruptError",
    "TraceError",
    "TraceForeignError",
    "TraceIOError",
    "TraceMessageError",
    "TraceTruncatedError",
    "UnknownChannelError",
]


class TraceError(SutureError):
    """Base class of trace errors.

    Attributes:
        path: the trace file concerned, or ``None`` when none is.
        reason: a short human explanation.
    """

    code = "trace-error"

    def __init__(self, path: str | None, reason: str) -> None:
        self.path = path
        self.reason = reason
        where = f"{path}: " if path is not None else ""
        super().__init__(f"{where}{reason}")


class TraceIOError(TraceError):
    """The file could not be opened, read or written (missing, permissions, disk full)."""

    code = "trace-io"


class TraceForeignError(TraceError):
    """The file is not an MCAP file, or an MCAP file that suture-engine did not write."""

    code = "trace-foreign"


class TraceCorruptError(TraceError):
    """The file is damaged in a way that a truncation cannot explain.

    Attributes:
        offset: the byte offset of the damaged record [byte].
    """

    code = "trace-corrupt"

    def __init__(self, path: str | None, reason: str, offset: int) -> None:
        self.offset = offset
        super().__init__(path, f"{reason} (at byte {offset})")
        self.reason = reason


class TraceTruncatedError(TraceError):
    """The trace ends early, and the caller asked for a complete one.

    Attributes:
        truncated_at_ns: simulation time of the last readable message [ns], or ``None``.
    """

    code = "trace-truncated"

    def __init__(self, path: str | None, reason: str, truncated_at_ns: int | None) -> None:
        self.truncated_at_ns = truncated_at_ns
        super().__init__(path, reason)


class UnknownChannelError(TraceError):
    """A topic that is not in the channel catalogue.

    Attributes:
        topic: the offending topic.
        available: the catalogue's topic patterns.
    """

    code = "trace-unknown-channel"

    def __init__(self, topic: str, available: tuple[str, ...]) -> None:
        self.topic = topic
        self.available = available
        super().__init__(None, f"unknown channel {topic!r}; known: {', '.join(available)}")


class TraceMessageError(TraceError):
    """A message that cannot be encoded (not JSON-serialisable) or written.

    Attributes:
        topic: the channel the message was meant for.
    """

    code = "trace-message"

    def __init__(self, path: str | None, topic: str, reason: str) -> None:
        self.topic = topic
        super().__init__(path, f"{topic}: {reason}")
