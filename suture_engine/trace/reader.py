"""Reads suture-engine traces, complete or truncated.

:class:`TraceReader` parses the MCAP file itself (record framing, chunks,
schemas, channels, messages), so it can read what a killed run left behind: a
file without summary or footer, or with a torn chunk at the end. It stops at
the last complete chunk and reports where (:class:`TraceStatus`). Damage that
a truncation cannot explain (a bad magic, an unknown record type, a chunk whose
CRC or compression is wrong, a record that runs past the end of a file that
has its footer) raises :class:`~suture_engine.trace.errors.TraceCorruptError`;
a file that is not MCAP, or not written by suture-engine, raises
:class:`~suture_engine.trace.errors.TraceForeignError`.

Example:
    >>> reader = TraceReader("runs/demo/trace.mcap")
    >>> reader.status.truncated, reader.status.truncated_at_ns
    (False, None)
    >>> for msg in reader.messages(["/events"]):
    ...     print(msg.log_time_ns, msg.data["name"])
"""

from __future__ import annotations

import fnmatch
import json
import os
import struct
import zlib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, NamedTuple

from suture_engine.trace.errors import (
    TraceCorruptError,
    TraceForeignError,
    TraceIOError,
    TraceTruncatedError,
)

__all__ = ["TraceChannel", "TraceMessage", "TraceReader", "TraceStatus"]

MAGIC = b"\x89MCAP0\r\n"
_LIBRARY_PREFIX = "suture-engine/"  # see writer.LIBRARY_PREFIX (not imported: no mcap import)

_OP_HEADER = 0x01
_OP_FOOTER = 0x02
_OP_SCHEMA = 0x03
_OP_CHANNEL = 0x04
_OP_MESSAGE = 0x05
_OP_CHUNK = 0x06
_OP_DATA_END = 0x0F
_KNOWN_OPS = frozenset(range(0x01, 0x10))

_decode_json = json.JSONDecoder().decode
_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_RECORD = struct.Struct("<BQ")
_MESSAGE = struct.Struct("<HIQQ")
_CHUNK = struct.Struct("<QQQI")


class TraceMessage(NamedTuple):
    """One decoded message.

    Attributes:
        topic: the channel's topic.
        log_time_ns: simulation time [ns].
        data: the decoded JSON message.
    """

    topic: str
    log_time_ns: int
    data: Any


@dataclass(frozen=True)
class TraceChannel:
    """A channel as declared in the file.

    Attributes:
        id: the MCAP channel id.
        topic: the topic.
        message_encoding: ``"json"`` for suture-engine traces.
        schema_name: the schema's name, or ``""`` without schema.
        schema: the decoded JSON schema, or ``None``.
    """

    id: int
    topic: str
    message_encoding: str
    schema_name: str
    schema: Mapping[str, Any] | None


@dataclass(frozen=True)
class TraceStatus:
    """How far a trace could be read.

    Attributes:
        complete: the file has its data-end record, footer and closing magic.
        truncated: the file ends early (a killed run); messages up to ``stop_offset``.
        truncated_at_ns: the simulation time of the last readable message [ns] when
            truncated, else ``None``.
        last_time_ns: the simulation time of the last readable message [ns] (``None``
            when there is none).
        stop_offset: the byte offset where reading stopped [byte].
        file_size: the file size [byte].
        message_count: messages read.
        message_counts: messages read, per topic.
        reason: why reading stopped (``"complete"``, ``"no footer"``, ``"torn chunk"``...).
    """

    complete: bool
    truncated: bool
    truncated_at_ns: int | None
    last_time_ns: int | None
    stop_offset: int
    file_size: int
    message_count: int
    message_counts: Mapping[str, int]
    reason: str


class _Loose(NamedTuple):
    """A message outside any chunk (only in files of other writers)."""

    channel_id: int
    log_time_ns: int
    data: bytes


class _ChunkRef(NamedTuple):
    """Where a verified chunk's record body lies in the file."""

    offset: int  # of the record [byte]
    body_start: int
    body_length: int


class _Truncated(Exception):
    """Internal: the data ends inside a record."""


class TraceReader:
    """Reads a trace file: checks it at once, decodes messages lazily.

    Opening scans the whole file (record framing, every chunk decompressed and its
    CRC checked) but keeps only the chunks' positions, so memory does not grow
    with the trace; :meth:`messages` reads and decodes the chunks again.

    Args:
        path: the trace file.
        allow_truncated: accept a file that ends early (default); when False such a
            file raises :class:`~suture_engine.trace.errors.TraceTruncatedError`.
        require_engine: reject MCAP files not written by suture-engine.

    Raises:
        TraceIOError: the file cannot be read.
        TraceForeignError: not an MCAP file, or not a suture-engine trace.
        TraceCorruptError: damage that a truncation cannot explain.
        TraceTruncatedError: with ``allow_truncated=False``, the file ends early.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        allow_truncated: bool = True,
        require_engine: bool = True,
    ) -> None:
        self.path = Path(path)
        self._name = str(self.path)
        self.profile = ""
        self.library = ""
        self._schemas: dict[int, tuple[str, Mapping[str, Any] | None]] = {}
        self._channels: dict[int, TraceChannel] = {}
        self._segments: list[_ChunkRef | _Loose] = []
        self._counts: dict[int, int] = {}
        self._last_ns: int | None = None
        try:
            with open(self.path, "rb") as f:
                self.status = self._parse(f, require_engine)
        except OSError as exc:
            raise TraceIOError(self._name, f"cannot read trace: {exc.strerror}") from exc
        if self.status.truncated and not allow_truncated:
            raise TraceTruncatedError(
                self._name,
                f"trace ends early ({self.status.reason}) at byte {self.status.stop_offset}",
                self.status.truncated_at_ns,
            )

    # -- public API -------------------------------------------------------------------------

    @property
    def channels(self) -> dict[str, TraceChannel]:
        """The channels by topic, in file order."""
        return {c.topic: c for c in self._channels.values()}

    @property
    def topics(self) -> list[str]:
        """The topics, in file order."""
        return [c.topic for c in self._channels.values()]

    @property
    def meta(self) -> dict[str, Any]:
        """The ``/meta`` message (empty when the file has none)."""
        for msg in self.messages(["/meta"]):
            return dict(msg.data)
        return {}

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[TraceMessage]:
        """The messages in file order, optionally only on some topics.

        Only the part of the file that was readable when the reader was opened is read.

        Args:
            topics: topics or glob patterns (``/joint_state/*``); ``None`` for all.

        Raises:
            TraceCorruptError: a message is not valid JSON, or the file changed.
            TraceIOError: the file can no longer be read.
        """
        channels = self._channels
        wanted = set(channels)
        if topics is not None:
            patterns = list(topics)
            wanted = {
                cid
                for cid, ch in channels.items()
                if any(fnmatch.fnmatchcase(ch.topic, p) for p in patterns)
            }
        if not wanted or not self._segments:
            return
        try:
            f = open(self.path, "rb")
        except OSError as exc:
            raise TraceIOError(self._name, f"cannot read trace: {exc.strerror}") from exc
        with f:
            for seg in self._segments:
                if isinstance(seg, _Loose):
                    if seg.channel_id in wanted:
                        yield self._decode(seg.channel_id, seg.log_time_ns, seg.data)
                    continue
                try:
                    f.seek(seg.body_start)
                    body = f.read(seg.body_length)
                except OSError as exc:
                    raise TraceIOError(self._name, f"cannot read trace: {exc.strerror}") from exc
                if len(body) != seg.body_length:
                    raise self._corrupt("the file changed while it was read", seg.offset)
                records = self._chunk_records(memoryview(body), seg.offset)
                pos, n = 0, len(records)
                while pos < n:
                    op, length = _RECORD.unpack_from(records, pos)
                    start = pos + _RECORD.size
                    pos = start + length
                    if op != _OP_MESSAGE:
                        continue
                    cid, _seq, log_time, _pub = _MESSAGE.unpack_from(records, start)
                    if cid in wanted:
                        yield self._decode(cid, log_time, records[start + _MESSAGE.size : pos])

    def __len__(self) -> int:
        return self.status.message_count

    def __repr__(self) -> str:
        s = self.status
        state = "complete" if s.complete else f"truncated at {s.truncated_at_ns} ns ({s.reason})"
        return f"TraceReader({self._name!r}, {s.message_count} messages, {state})"

    # -- parsing ----------------------------------------------------------------------------

    def _decode(self, channel_id: int, log_time_ns: int, data: bytes) -> TraceMessage:
        topic = self._channels[channel_id].topic
        try:
            value = _decode_json(data.decode("utf-8"))
        except ValueError as exc:
            raise TraceCorruptError(self._name, f"message on {topic} is not JSON: {exc}", -1) from (
                exc
            )
        return TraceMessage(topic, log_time_ns, value)

    def _corrupt(self, reason: str, offset: int) -> TraceCorruptError:
        return TraceCorruptError(self._name, reason, offset)

    def _parse(self, f: BinaryIO, require_engine: bool) -> TraceStatus:
        size = os.fstat(f.fileno()).st_size
        head = f.read(len(MAGIC))
        if len(head) < len(MAGIC) or head != MAGIC:
            if len(head) < len(MAGIC) and MAGIC.startswith(head):
                return self._status(False, len(head), len(head), "empty file")
            raise TraceForeignError(self._name, "not an MCAP file (bad magic)")
        has_tail = False
        if size >= 2 * len(MAGIC) + _RECORD.size:
            f.seek(size - len(MAGIC))
            has_tail = f.read(len(MAGIC)) == MAGIC
        pos = len(MAGIC)
        saw_header = False
        saw_data_end = False
        saw_footer = False
        reason = "no footer"
        while pos < size:
            f.seek(pos)
            frame = f.read(_RECORD.size)
            if len(frame) < _RECORD.size:
                if has_tail:
                    raise self._corrupt("record header runs past the end", pos)
                reason = "torn record header"
                break
            op, length = _RECORD.unpack(frame)
            if op not in _KNOWN_OPS and op < 0x80:
                raise self._corrupt(f"unknown record opcode 0x{op:02x}", pos)
            start = pos + _RECORD.size
            end = start + length
            if end > size:
                if has_tail:
                    raise self._corrupt("record runs past the end of the file", pos)
                reason = "torn chunk" if op == _OP_CHUNK else "torn record"
                break
            if not saw_header:
                if op != _OP_HEADER:
                    raise self._corrupt("first record is not a header", pos)
                self._parse_header(memoryview(f.read(length)), pos, require_engine)
                saw_header = True
            elif op == _OP_CHUNK:
                self._scan_chunk(memoryview(f.read(length)), pos)
            elif op in (_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE):
                if not saw_data_end:  # the summary repeats schemas and channels
                    self._parse_record(op, memoryview(f.read(length)), pos)
            elif op == _OP_HEADER:
                raise self._corrupt("second header record", pos)
            elif op == _OP_DATA_END:
                saw_data_end = True
            elif op == _OP_FOOTER:
                saw_footer = True
                pos = end
                break
            pos = end
        if not saw_header and has_tail:
            raise self._corrupt("no header record", pos)
        complete = saw_footer and saw_data_end and pos + len(MAGIC) == size and has_tail
        if saw_footer and not complete:
            f.seek(pos)
            if not MAGIC.startswith(f.read(len(MAGIC) + 1)):
                raise self._corrupt("footer not followed by the closing magic", pos)
            reason = "no closing magic"
        if complete:
            reason = "complete"
        elif not saw_header:
            reason = "torn header"
        elif saw_data_end and reason == "no footer":
            reason = "no footer after the data end"
        return self._status(complete, pos, size, reason)

    def _status(self, complete: bool, pos: int, size: int, reason: str) -> TraceStatus:
        counts = {self._channels[cid].topic: n for cid, n in self._counts.items()}
        last = self._last_ns
        return TraceStatus(
            complete=complete,
            truncated=not complete,
            truncated_at_ns=None if complete else last,
            last_time_ns=last,
            stop_offset=pos,
            file_size=size,
            message_count=sum(counts.values()),
            message_counts=counts,
            reason=reason,
        )

    def _parse_header(self, body: memoryview, offset: int, require_engine: bool) -> None:
        try:
            profile, p = _string(body, 0)
            library, p = _string(body, p)
        except (_Truncated, UnicodeDecodeError) as exc:
            raise self._corrupt("malformed header record", offset) from exc
        self.profile, self.library = profile, library
        if require_engine and not library.startswith(_LIBRARY_PREFIX):
            raise TraceForeignError(
                self._name,
                f"MCAP file written by {library or 'an unknown library'!r}, not by suture-engine",
            )

    def _chunk_records(self, body: memoryview, offset: int) -> bytes:
        """Decompresses a chunk record's body and checks its size and CRC."""
        try:
            _start, _end, usize, crc = _CHUNK.unpack_from(body, 0)
            compression, p = _string(body, _CHUNK.size)
            (clen,) = _U64.unpack_from(body, p)
        except (struct.error, _Truncated, UnicodeDecodeError) as exc:
            raise self._corrupt("malformed chunk record", offset) from exc
        p += 8
        if p + clen > len(body):
            raise self._corrupt("chunk records run past the chunk", offset)
        payload = bytes(body[p : p + clen])
        try:
            if compression == "":
                records = payload
            elif compression == "zstd":
                import zstandard

                records = zstandard.ZstdDecompressor().decompress(payload, max_output_size=usize)
            elif compression == "lz4":
                try:
                    import lz4.frame
                except ImportError as exc:
                    raise TraceIOError(
                        self._name, "the trace has lz4 chunks: reading it needs the lz4 package"
                    ) from exc
                records = lz4.frame.decompress(payload)
            else:
                raise self._corrupt(f"unsupported chunk compression {compression!r}", offset)
        except (TraceCorruptError, TraceIOError):
            raise
        except Exception as exc:  # the decompressors raise their own error types
            raise self._corrupt(f"chunk does not decompress ({compression}): {exc}", offset) from (
                exc
            )
        if len(records) != usize:
            raise self._corrupt("chunk size differs from its declared size", offset)
        if crc != 0 and zlib.crc32(records) != crc:
            raise self._corrupt("chunk CRC mismatch", offset)
        return records

    def _scan_chunk(self, body: memoryview, offset: int) -> None:
        """Checks a chunk and its records; notes its schemas, channels and messages."""
        records = self._chunk_records(body, offset)
        view = memoryview(records)
        counts, channels = self._counts, self._channels
        last = self._last_ns
        pos, n = 0, len(records)
        while pos < n:
            if n - pos < _RECORD.size:
                raise self._corrupt("torn record inside a chunk", offset)
            op, length = _RECORD.unpack_from(records, pos)
            start = pos + _RECORD.size
            end = start + length
            if end > n:
                raise self._corrupt("record runs past the end of its chunk", offset)
            if op == _OP_MESSAGE:
                if length < _MESSAGE.size:
                    raise self._corrupt("message record too short", offset)
                cid, _seq, log_time, _pub = _MESSAGE.unpack_from(records, start)
                if cid not in channels:
                    raise self._corrupt(f"message on undeclared channel {cid}", offset)
                counts[cid] = counts.get(cid, 0) + 1
                if last is None or log_time > last:
                    last = log_time
            elif op in (_OP_SCHEMA, _OP_CHANNEL):
                self._parse_record(op, view[start:end], offset)
            elif op not in _KNOWN_OPS and op < 0x80:
                raise self._corrupt(f"unknown record opcode 0x{op:02x} in a chunk", offset)
            pos = end
        self._last_ns = last
        self._segments.append(_ChunkRef(offset, offset + _RECORD.size, len(body)))

    def _parse_record(self, op: int, body: memoryview, offset: int) -> None:
        try:
            if op == _OP_MESSAGE:
                cid, _seq, log_time, _pub = _MESSAGE.unpack_from(body, 0)
                if cid not in self._channels:
                    raise self._corrupt(f"message on undeclared channel {cid}", offset)
                self._segments.append(_Loose(cid, log_time, bytes(body[_MESSAGE.size :])))
                self._counts[cid] = self._counts.get(cid, 0) + 1
                if self._last_ns is None or log_time > self._last_ns:
                    self._last_ns = log_time
            elif op == _OP_SCHEMA:
                (sid,) = _U16.unpack_from(body, 0)
                name, p = _string(body, 2)
                _encoding, p = _string(body, p)
                (dlen,) = _U32.unpack_from(body, p)
                raw = bytes(body[p + 4 : p + 4 + dlen])
                schema: Mapping[str, Any] | None = json.loads(raw) if raw else None
                self._schemas[sid] = (name, schema)
            else:
                cid, sid = struct.unpack_from("<HH", body, 0)
                topic, p = _string(body, 4)
                encoding, p = _string(body, p)
                name, schema = self._schemas.get(sid, ("", None))
                if sid != 0 and sid not in self._schemas:
                    raise self._corrupt(f"channel {topic!r} on undeclared schema {sid}", offset)
                self._channels[cid] = TraceChannel(cid, topic, encoding, name, schema)
        except TraceCorruptError:
            raise
        except (struct.error, _Truncated, ValueError) as exc:
            raise self._corrupt(f"malformed record (opcode 0x{op:02x}): {exc}", offset) from exc


def _string(buf: memoryview, pos: int) -> tuple[str, int]:
    """Reads an MCAP string (uint32 length + UTF-8) at ``pos``; returns it and the next offset."""
    if pos + 4 > len(buf):
        raise _Truncated
    (n,) = _U32.unpack_from(buf, pos)
    end = pos + 4 + n
    if end > len(buf):
        raise _Truncated
    return bytes(buf[pos + 4 : end]).decode("utf-8"), end
