"""Deterministic, crash-safe MCAP trace writer.

:class:`TraceWriter` writes one run's trace: JSON messages on the channels of
:mod:`suture_engine.trace.channels`, in compressed MCAP chunks of bounded size.

- **Time** is simulation time in nanoseconds (the MCAP log and publish time).
- **Deterministic**: the same messages in the same order give a byte-identical
  file. Nothing depends on the wall clock, the host or the mcap library version
  (the header names suture-engine, not the library); JSON keys are sorted and
  floats use the shortest round-trip form. Wall-clock fields (the QP solve
  time) are dropped unless ``include_wall_clock=True``.
- **Crash-safe**: each finished chunk is written, flushed and fsync'ed at once,
  and a chunk is also closed every ``flush_interval_ns`` of simulation time, so a
  process killed with SIGKILL leaves a file that
  :class:`~suture_engine.trace.reader.TraceReader` reads up to its last flush.
  Chunks are closed only between time steps, so what survives a crash is a
  sequence of whole ticks (every message of its last tick is there).

Example:
    >>> with TraceWriter(path, TraceMeta("demo", seed=1, control_rate_hz=1000.0)) as w:
    ...     w.write("/joint_state/left", 1_000_000, {"position": q, "velocity": dq})
"""

from __future__ import annotations

import os
import struct
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from suture_engine import __version__
from suture_engine.trace import channels, codec
from suture_engine.trace.errors import TraceIOError, TraceMessageError

__all__ = ["LIBRARY_PREFIX", "TraceMeta", "TraceWriter"]

LIBRARY_PREFIX = "suture-engine/"
"""The MCAP header's ``library`` field starts with this; the reader checks it."""

Compression = Literal["zstd", "lz4", "none"]

_MESSAGE_OVERHEAD = 9 + 22
"""Bytes of an MCAP message record besides its data (opcode, length, header fields)."""


@dataclass(frozen=True)
class TraceMeta:
    """What the ``/meta`` channel records (no wall-clock data).

    Attributes:
        procedure: the procedure's name.
        seed: the run's random seed.
        control_rate_hz: the control rate [Hz].
        params: the procedure parameters as run (JSON-like).
        robots: the robot names.
        backend: the backend name.
        engine_version: the suture-engine version.
        extra: more JSON-like fields to record.
    """

    procedure: str
    seed: int
    control_rate_hz: float
    params: Mapping[str, Any] = field(default_factory=dict)
    robots: tuple[str, ...] = ()
    backend: str | None = None
    engine_version: str = __version__
    extra: Mapping[str, Any] = field(default_factory=dict)

    def to_message(self) -> dict[str, Any]:
        """The ``/meta`` message."""
        message: dict[str, Any] = dict(self.extra)
        message.update(
            procedure=self.procedure,
            seed=int(self.seed),
            control_rate_hz=float(self.control_rate_hz),
            params=dict(self.params),
            robots=list(self.robots),
            engine_version=self.engine_version,
        )
        if self.backend is not None:
            message["backend"] = self.backend
        return message

    def to_mcap_metadata(self) -> dict[str, str]:
        """The main fields as an MCAP metadata record (string values; Foxglove shows it)."""
        fields = {
            "procedure": self.procedure,
            "seed": str(int(self.seed)),
            "control_rate_hz": repr(float(self.control_rate_hz)),
            "engine_version": self.engine_version,
            "robots": ",".join(self.robots),
        }
        if self.backend is not None:
            fields["backend"] = self.backend
        return fields


class TraceWriter:
    """Writes a trace to an MCAP file.

    Args:
        path: the output file (created or overwritten).
        meta: the run metadata, written on ``/meta`` at t = 0.
        compression: chunk compression: ``"zstd"`` (default), ``"lz4"`` or ``"none"``.
        chunk_size: a chunk is closed at the first new time step after its uncompressed
            size reaches this [byte] (chunks hold whole time steps).
        flush_interval_ns: a chunk is also closed at the first new time step once this
            much simulation time has passed since the last flush [ns]; 0 disables it.
        fsync: fsync the file at every flush (crash safety against power loss too).
        include_wall_clock: keep wall-clock fields (breaks byte-identical traces).
        validate: check every message against its channel's JSON schema (slow; tests).
        message_index: also write MCAP message indexes (optional in MCAP; about 16 bytes
            per message; readers, Foxglove included, use the chunk indexes without them).

    Raises:
        TraceIOError: the file cannot be created.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        meta: TraceMeta,
        *,
        compression: Compression = "zstd",
        chunk_size: int = 256 * 1024,
        flush_interval_ns: int = 1_000_000_000,
        fsync: bool = True,
        include_wall_clock: bool = False,
        validate: bool = False,
        message_index: bool = False,
    ) -> None:
        from mcap.writer import CompressionType, IndexType, Writer

        if compression not in ("zstd", "lz4", "none"):
            raise ValueError(f"compression must be zstd, lz4 or none, not {compression!r}")
        if chunk_size <= 0:
            raise ValueError(f"chunk_size must be positive, not {chunk_size}")
        if compression == "lz4":
            try:
                import lz4.frame  # noqa: F401 - optional; mcap needs it for lz4 chunks
            except ImportError as exc:
                raise ValueError("lz4 compression needs the lz4 package (pip install lz4)") from exc
        self.path = Path(path)
        self._fsync = fsync
        self._include_wall_clock = include_wall_clock
        self._validate = validate
        self._flush_interval_ns = int(flush_interval_ns)
        self._chunk_size = int(chunk_size)
        try:
            raw = open(self.path, "wb")
        except OSError as exc:
            raise TraceIOError(str(self.path), f"cannot create trace: {exc.strerror}") from exc
        self._file = raw
        kind = {
            "zstd": CompressionType.ZSTD,
            "lz4": CompressionType.LZ4,
            "none": CompressionType.NONE,
        }[compression]
        index = IndexType.CHUNK | IndexType.ATTACHMENT | IndexType.METADATA
        if message_index:
            index |= IndexType.MESSAGE
        # Chunks are closed here, between time steps, never inside the mcap writer.
        self._mcap = Writer(
            raw,
            chunk_size=1 << 62,
            compression=kind,
            index_types=index,
        )
        self._add = _message_adder(self._mcap)
        self._add_batch = _batch_adder(self._mcap, self._add)
        self._schema_ids: dict[str, int] = {}
        self._channel_ids: dict[str, tuple[int, channels.ChannelSpec]] = {}
        self._fast_ids: dict[str, int] = {}
        self._validators: dict[str, Any] = {}
        self._closed = False
        self._last_time_ns = 0
        self._last_flush_ns = 0
        self._pending = 0
        self._chunk_bytes = 0
        self.message_count = 0
        self.last_durable_ns: int | None = None
        """Simulation time of the last message known to be on disk [ns]."""
        try:
            self._mcap.start(profile="", library=LIBRARY_PREFIX + meta.engine_version)
            self._sync()
            self.write(channels.META, 0, meta.to_message())
            self._mcap.add_metadata("suture_engine", meta.to_mcap_metadata())
            self.flush()  # a killed run's trace still says what it is
        except OSError as exc:
            _close_quietly(raw)
            raise TraceIOError(str(self.path), f"cannot write trace: {exc.strerror}") from exc
        except TraceIOError:
            _close_quietly(raw)
            raise

    @property
    def include_wall_clock(self) -> bool:
        """Whether wall-clock fields are kept (then traces are not byte-identical)."""
        return self._include_wall_clock

    # -- writing ----------------------------------------------------------------------------

    def write(self, topic: str, time_ns: int, message: Mapping[str, Any]) -> None:
        """Writes one message.

        Args:
            topic: a concrete topic of the catalogue (``/joint_state/left``).
            time_ns: simulation time [ns]; must not decrease.
            message: the message, a JSON-like mapping that matches the channel's schema.

        Raises:
            UnknownChannelError: the topic is not in the catalogue.
            TraceMessageError: the message cannot be encoded, fails its schema
                (with ``validate=True``), its time goes backwards, or the writer is closed.
            TraceIOError: the disk write failed.
        """
        if self._closed:
            raise TraceMessageError(str(self.path), topic, "the writer is closed")
        time_ns = int(time_ns)
        if time_ns < self._last_time_ns:
            raise TraceMessageError(
                str(self.path),
                topic,
                f"time {time_ns} ns is before the previous message's {self._last_time_ns} ns",
            )
        entry = self._channel_ids.get(topic)
        if entry is None:
            entry = self._register(topic)
        channel_id, spec = entry
        if spec.adapt is not None:
            try:
                message = spec.adapt(message)
            except (TypeError, ValueError, IndexError) as exc:
                raise TraceMessageError(str(self.path), topic, f"malformed message: {exc}") from exc
        if spec.wall_clock_fields and not self._include_wall_clock:
            message = {k: v for k, v in message.items() if k not in spec.wall_clock_fields}
        try:
            data = codec.encode(message)
        except (TypeError, ValueError) as exc:
            raise TraceMessageError(str(self.path), topic, f"cannot encode: {exc}") from exc
        if self._validate:
            self._check_schema(topic, spec, data)
        try:
            if self._pending and time_ns > self._last_time_ns:  # a new time step begins
                if self._chunk_bytes >= self._chunk_size or (
                    self._flush_interval_ns > 0
                    and time_ns - self._last_flush_ns >= self._flush_interval_ns
                ):
                    self.flush()  # the chunk holds whole time steps
                    self._last_flush_ns = time_ns
            self._last_time_ns = time_ns
            self._add(channel_id, time_ns, data)
            self.message_count += 1
            self._pending += 1
            self._chunk_bytes += len(data) + _MESSAGE_OVERHEAD
        except OSError as exc:
            raise TraceIOError(str(self.path), f"write failed: {exc.strerror}") from exc

    def write_encoded(self, time_ns: int, messages: Sequence[tuple[str, bytes]]) -> None:
        """Writes messages already encoded by the caller, all at one time step, in order.

        The same file as :meth:`write` called once per message with the decoded message:
        the caller guarantees that each ``data`` is what :func:`codec.encode` gives for
        it (sorted keys, shortest round-trip floats, no wall-clock field unless
        ``include_wall_clock``, no channel adapter). The recorder's per-tick fast path
        uses it; one bookkeeping pass and one buffer write serve the whole batch.

        Args:
            time_ns: simulation time of every message [ns]; must not decrease.
            messages: (topic, encoded JSON) pairs.

        Raises:
            UnknownChannelError: a topic is not in the catalogue.
            TraceMessageError: the time goes backwards, the writer is closed, or (with
                ``validate=True``) a message fails its schema.
            TraceIOError: the disk write failed.
        """
        if not messages:
            return
        if self._closed:
            raise TraceMessageError(str(self.path), messages[0][0], "the writer is closed")
        time_ns = int(time_ns)
        if time_ns < self._last_time_ns:
            raise TraceMessageError(
                str(self.path),
                messages[0][0],
                f"time {time_ns} ns is before the previous message's {self._last_time_ns} ns",
            )
        if not self._validate:
            ids = self._fast_ids
            try:  # the common case: every channel known, nothing to validate
                records = [(ids[topic], data) for topic, data in messages]
            except KeyError:
                pass
            else:
                try:
                    self._new_step(time_ns)
                    self._add_records(time_ns, records)
                except OSError as exc:
                    raise TraceIOError(str(self.path), f"write failed: {exc.strerror}") from exc
                return
        records = []
        channel_ids = self._channel_ids
        first = True
        try:
            for topic, data in messages:
                entry = channel_ids.get(topic)
                if entry is None:
                    if records:  # a new channel's record goes between messages, as in write
                        self._add_records(time_ns, records)
                        records = []
                    entry = self._register(topic)
                if self._validate:
                    self._check_schema(topic, entry[1], data)
                if first:
                    first = False
                    self._new_step(time_ns)
                records.append((entry[0], data))
            self._add_records(time_ns, records)
        except OSError as exc:
            raise TraceIOError(str(self.path), f"write failed: {exc.strerror}") from exc

    def _new_step(self, time_ns: int) -> None:
        """Before the first message at ``time_ns``: close the chunk when it is full or
        the flush interval has passed, and only at a new time step (as ``write`` does)."""
        if self._pending and time_ns > self._last_time_ns:  # a new time step begins
            if self._chunk_bytes >= self._chunk_size or (
                self._flush_interval_ns > 0
                and time_ns - self._last_flush_ns >= self._flush_interval_ns
            ):
                self.flush()
                self._last_flush_ns = time_ns
        self._last_time_ns = time_ns

    def _add_records(self, time_ns: int, records: list[tuple[int, bytes]]) -> None:
        n = len(records)
        self._chunk_bytes += self._add_batch(time_ns, records) + n * _MESSAGE_OVERHEAD
        self.message_count += n
        self._pending += n

    def flush(self) -> None:
        """Closes the chunk in progress and makes everything written so far durable.

        Raises:
            TraceIOError: the disk write failed.
        """
        if self._closed:
            return
        try:
            self._mcap.flush()
            self._pending = 0
            self._chunk_bytes = 0
            self._sync()
        except OSError as exc:
            raise TraceIOError(str(self.path), f"flush failed: {exc.strerror}") from exc

    def close(self) -> None:
        """Writes the summary and footer and closes the file. Idempotent.

        Raises:
            TraceIOError: the disk write failed.
        """
        if self._closed:
            return
        self._closed = True
        try:
            self._mcap.finish()
            self._file.flush()
            if self._fsync:
                os.fsync(self._file.fileno())
        except OSError as exc:
            _close_quietly(self._file)
            raise TraceIOError(str(self.path), f"close failed: {exc.strerror}") from exc
        self._file.close()
        self.last_durable_ns = self._last_time_ns

    def __enter__(self) -> TraceWriter:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # -- internals --------------------------------------------------------------------------

    def _register(self, topic: str) -> tuple[int, channels.ChannelSpec]:
        spec = channels.spec_for(topic)
        schema_id = self._schema_ids.get(spec.schema_name)
        if schema_id is None:
            schema_id = self._mcap.register_schema(
                name=spec.schema_name, encoding="jsonschema", data=channels.schema_bytes(spec)
            )
            self._schema_ids[spec.schema_name] = schema_id
        channel_id = self._mcap.register_channel(
            topic=topic, message_encoding="json", schema_id=schema_id
        )
        self._channel_ids[topic] = (channel_id, spec)
        self._fast_ids[topic] = channel_id
        return channel_id, spec

    def _sync(self) -> None:
        """Flushes the file (and fsyncs it) after the mcap writer emitted bytes."""
        self._file.flush()
        if self._fsync:
            os.fsync(self._file.fileno())
        self._last_flush_ns = self._last_time_ns
        if self.message_count and self._pending == 0:
            self.last_durable_ns = self._last_time_ns

    def _check_schema(self, topic: str, spec: channels.ChannelSpec, data: bytes) -> None:
        import jsonschema

        validator = self._validators.get(spec.schema_name)
        if validator is None:
            validator = jsonschema.Draft202012Validator(channels.validation_schema(spec))
            self._validators[spec.schema_name] = validator
        try:
            validator.validate(codec.decode(data))
        except jsonschema.ValidationError as exc:
            raise TraceMessageError(
                str(self.path), topic, f"does not match {spec.schema_name}: {exc.message}"
            ) from exc


_MESSAGE_HEADER = struct.Struct("<BQHIQQ")
"""An MCAP Message record's opcode, length, channel id, sequence, log and publish time."""


def _message_adder(writer: Any) -> Callable[[int, int, bytes], None]:
    """``writer.add_message(channel, time, data)`` for a sequence-0 message logged and
    published at the same time, the same bytes and bookkeeping at a fraction of the cost.

    mcap 1.6's ``Writer.add_message`` spends ~10 us a message in Python (a Message
    dataclass, a dozen small ``struct.pack`` and buffer writes); a 1 kHz tick writes about
    eight. The fast path does the same updates (statistics, the chunk's message index,
    the record) in one pack. It relies on mcap 1.6's writer internals, so it is used only
    when they are all there and the writer never closes a chunk itself (this module's
    ``chunk_size=1 << 62``: chunks close in ``flush``); otherwise, the public call.
    ``tests/test_trace_writer_fast.py`` checks both give the same file, byte for byte.
    """

    def public(channel_id: int, time_ns: int, data: bytes) -> None:
        writer.add_message(channel_id, log_time=time_ns, data=data, publish_time=time_ns)

    try:
        from mcap.records import MessageIndex

        builder = writer._Writer__chunk_builder
        stats = writer._Writer__statistics
        chunk_size = writer._Writer__chunk_size
        builder.record_writer._buffer.write  # noqa: B018 - the attributes used below
        builder.message_indices, builder.num_messages, stats.channel_message_counts  # noqa: B018
    except (AttributeError, ImportError):
        return public
    if builder is None or chunk_size < 1 << 62:
        return public
    counts = stats.channel_message_counts
    indices = builder.message_indices
    pack = _MESSAGE_HEADER.pack

    def fast(channel_id: int, time_ns: int, data: bytes) -> None:
        if stats.message_count == 0:
            stats.message_start_time = time_ns
        elif time_ns < stats.message_start_time:
            stats.message_start_time = time_ns
        if time_ns > stats.message_end_time:
            stats.message_end_time = time_ns
        counts[channel_id] += 1
        stats.message_count += 1
        if builder.num_messages == 0:
            builder.message_start_time = time_ns
        elif time_ns < builder.message_start_time:
            builder.message_start_time = time_ns
        if time_ns > builder.message_end_time:
            builder.message_end_time = time_ns
        buf = builder.record_writer._buffer
        index = indices.get(channel_id)
        if not index:
            index = indices[channel_id] = MessageIndex(channel_id=channel_id, records=[])
        index.records.append((time_ns, buf.tell()))
        builder.num_messages += 1
        buf.write(pack(0x05, 22 + len(data), channel_id, 0, time_ns, time_ns))
        buf.write(data)

    return fast


def _batch_adder(
    writer: Any, single: Callable[[int, int, bytes], None]
) -> Callable[[int, Sequence[tuple[int, bytes]]], int]:
    """Adds several (channel id, data) messages logged and published at one time: the
    same bytes and bookkeeping as ``single`` called for each, in one pass. Returns the
    number of data bytes added.

    Like :func:`_message_adder`'s fast path it relies on mcap 1.6's writer internals and
    is used only when ``single`` is that fast path; otherwise it calls ``single`` per
    message. The chunk's message indexes are kept only when the writer writes them
    (``IndexType.MESSAGE``). ``tests/test_trace_writer_fast.py`` checks the bytes
    against mcap's own call.
    """

    def loop(time_ns: int, records: Sequence[tuple[int, bytes]]) -> int:
        size = 0
        for channel_id, data in records:
            single(channel_id, time_ns, data)
            size += len(data)
        return size

    if getattr(single, "__name__", "") != "fast":
        return loop
    from mcap.records import MessageIndex
    from mcap.writer import IndexType

    builder = writer._Writer__chunk_builder
    stats = writer._Writer__statistics
    indexed = bool(writer._Writer__index_types & IndexType.MESSAGE)
    counts = stats.channel_message_counts
    indices = builder.message_indices
    pack = _MESSAGE_HEADER.pack

    def batch(time_ns: int, records: Sequence[tuple[int, bytes]]) -> int:
        if not records:
            return 0
        if stats.message_count == 0 or time_ns < stats.message_start_time:
            stats.message_start_time = time_ns
        if time_ns > stats.message_end_time:
            stats.message_end_time = time_ns
        if builder.num_messages == 0 or time_ns < builder.message_start_time:
            builder.message_start_time = time_ns
        if time_ns > builder.message_end_time:
            builder.message_end_time = time_ns
        buf = builder.record_writer._buffer
        parts = []
        size = 0
        if indexed:
            offset = buf.tell()
            for channel_id, data in records:
                index = indices.get(channel_id)
                if not index:
                    index = indices[channel_id] = MessageIndex(channel_id=channel_id, records=[])
                index.records.append((time_ns, offset))
                offset += 31 + len(data)
        for channel_id, data in records:
            counts[channel_id] += 1
            n = len(data)
            size += n
            parts.append(pack(0x05, 22 + n, channel_id, 0, time_ns, time_ns))
            parts.append(data)
        n_records = len(records)
        stats.message_count += n_records
        builder.num_messages += n_records
        buf.write(b"".join(parts))
        return size

    return batch


def _close_quietly(f: Any) -> None:
    """Closes a file after a failed write; a second failure (the buffer) is ignored."""
    try:
        f.close()
    except OSError:
        pass
