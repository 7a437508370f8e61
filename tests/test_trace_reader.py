"""Tests of the trace reader: truncated, corrupt and foreign files."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from suture_engine.trace.errors import (
    TraceCorruptError,
    TraceError,
    TraceForeignError,
    TraceIOError,
    TraceTruncatedError,
)
from suture_engine.trace.reader import TraceReader
from suture_engine.trace.synthetic import write_synthetic_trace
from suture_engine.trace.writer import TraceMeta, TraceWriter


@pytest.fixture(scope="module")
def trace_bytes(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """A small complete trace with many chunks."""
    path = tmp_path_factory.mktemp("trace") / "t.mcap"
    write_synthetic_trace(path, 0.05, chunk_size=4096)
    return path.read_bytes()


def _read(tmp_path: Path, data: bytes, **kwargs: Any) -> TraceReader:
    path = tmp_path / "x.mcap"
    path.write_bytes(data)
    return TraceReader(path, **kwargs)


def _all(reader: TraceReader) -> list[tuple[str, int, Any]]:
    return [(m.topic, m.log_time_ns, m.data) for m in reader.messages()]


def test_complete_trace_status(tmp_path: Path, trace_bytes: bytes) -> None:
    reader = _read(tmp_path, trace_bytes)
    s = reader.status
    assert s.complete and not s.truncated and s.reason == "complete"
    assert s.truncated_at_ns is None
    assert s.last_time_ns == 49_000_000
    assert s.message_counts["/joint_state/left"] == 50
    assert sum(s.message_counts.values()) == s.message_count == len(reader)
    assert reader.meta["control_rate_hz"] == 1000.0
    assert "/ground_truth/suture" in reader.topics
    assert reader.channels["/qp/left"].schema_name == "suture_engine.QpStatus"


def test_every_truncation_reads_a_prefix(tmp_path: Path, trace_bytes: bytes) -> None:
    """Cut the file at many points: never an exception, always a prefix of the whole."""
    full = _all(_read(tmp_path, trace_bytes))
    previous = 0
    for cut in [*range(0, len(trace_bytes) - 1, 173), len(trace_bytes) - 1]:
        reader = _read(tmp_path, trace_bytes[:cut])
        got = _all(reader)
        s = reader.status
        assert s.truncated and not s.complete
        assert got == full[: len(got)]
        assert len(got) >= previous  # more bytes never give fewer messages
        previous = len(got)
        if got:
            assert s.truncated_at_ns == max(t for _, t, _ in got)
        else:
            assert s.truncated_at_ns is None
    assert previous == len(full)  # only the footer was missing at the last cut


def test_cut_at_a_flush_point_keeps_everything_flushed(tmp_path: Path) -> None:
    """Truncating exactly where a flush ended loses nothing written before it."""
    path = tmp_path / "t.mcap"
    w = TraceWriter(path, TraceMeta("p", 1, 1000.0), flush_interval_ns=0)
    sizes = []
    for k in range(1, 6):
        for j in range(10):
            w.write("/tension/estimated", (10 * k + j) * 1_000_000, {"tension_N": float(j)})
        w.flush()
        sizes.append((path.stat().st_size, (10 * k + 9) * 1_000_000, 1 + 10 * k))
    w.close()
    data = path.read_bytes()
    for size, last_ns, count in sizes:
        reader = _read(tmp_path, data[:size])
        assert reader.status.message_count == count
        assert reader.status.truncated_at_ns == last_ns
        # one byte more is a torn record, and reads the same
        assert _read(tmp_path, data[: size + 1]).status.message_count == count


def test_strict_mode_rejects_truncation(tmp_path: Path, trace_bytes: bytes) -> None:
    with pytest.raises(TraceTruncatedError) as err:
        _read(tmp_path, trace_bytes[: len(trace_bytes) // 2], allow_truncated=False)
    assert err.value.truncated_at_ns is not None and err.value.path is not None
    assert err.value.code == "trace-truncated"


@pytest.mark.parametrize(
    "data",
    [
        b"hello world, this is a text file\n" * 10,
        b"\x89PNG\r\n\x1a\n" + bytes(100),
        bytes(64),
    ],
)
def test_foreign_files_are_rejected(tmp_path: Path, data: bytes) -> None:
    with pytest.raises(TraceForeignError) as err:
        _read(tmp_path, data)
    assert err.value.code == "trace-foreign" and "x.mcap" in str(err.value)


def test_mcap_from_another_program_is_foreign(tmp_path: Path) -> None:
    from mcap.writer import Writer

    buf = io.BytesIO()
    w = Writer(buf)
    w.start(profile="", library="some-other-tool")
    sid = w.register_schema("s", "jsonschema", b"{}")
    cid = w.register_channel("/x", "json", sid)
    w.add_message(cid, log_time=5, data=b'{"a":1}', publish_time=5)
    w.finish()
    with pytest.raises(TraceForeignError, match="some-other-tool"):
        _read(tmp_path, buf.getvalue())
    reader = _read(tmp_path, buf.getvalue(), require_engine=False)
    assert _all(reader) == [("/x", 5, {"a": 1})]
    assert reader.status.complete


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(TraceIOError):
        TraceReader(tmp_path / "nope.mcap")


def test_empty_file_is_an_empty_truncated_trace(tmp_path: Path) -> None:
    s = _read(tmp_path, b"").status
    assert s.truncated and s.message_count == 0 and s.reason == "empty file"


def test_flipped_byte_in_a_chunk_is_corrupt(tmp_path: Path, trace_bytes: bytes) -> None:
    data = bytearray(trace_bytes)
    data[400] ^= 0xFF  # inside the first data chunk's compressed records
    with pytest.raises(TraceCorruptError) as err:
        _read(tmp_path, bytes(data))
    assert err.value.offset > 0 and err.value.code == "trace-corrupt"


def test_bad_opcode_is_corrupt(tmp_path: Path, trace_bytes: bytes) -> None:
    data = bytearray(trace_bytes)
    data[8] = 0x42  # the header's opcode
    with pytest.raises(TraceCorruptError, match="opcode"):
        _read(tmp_path, bytes(data))


def test_record_length_past_the_end_of_a_complete_file_is_corrupt(
    tmp_path: Path, trace_bytes: bytes
) -> None:
    data = bytearray(trace_bytes)
    header_len = int.from_bytes(data[9:17], "little")
    chunk = 8 + 9 + header_len  # the first record after the header
    data[chunk + 1 : chunk + 9] = (2**40).to_bytes(8, "little")
    with pytest.raises(TraceCorruptError, match="past the end"):
        _read(tmp_path, bytes(data))


@given(
    cut=st.integers(min_value=0, max_value=10**9),
    flips=st.lists(
        st.tuples(st.integers(min_value=0, max_value=10**9), st.integers(1, 255)), max_size=4
    ),
)
def test_damage_never_raises_anything_but_trace_errors(
    tmp_path_factory: pytest.TempPathFactory, trace_bytes: bytes, cut: int, flips: list[Any]
) -> None:
    data = bytearray(trace_bytes[: cut % (len(trace_bytes) + 1)])
    for where, mask in flips:
        if data:
            data[where % len(data)] ^= mask
    path = tmp_path_factory.mktemp("h") / "x.mcap"
    path.write_bytes(bytes(data))
    try:
        reader = TraceReader(path)
        for _ in reader.messages():
            pass
    except TraceError:
        pass
