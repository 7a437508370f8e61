"""Tests of the MCAP trace writer: round trip, the official reader, determinism, crash safety."""

from __future__ import annotations

import itertools
import json
import math
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from suture_engine.trace import channels
from suture_engine.trace.errors import TraceIOError, TraceMessageError, UnknownChannelError
from suture_engine.trace.reader import TraceReader
from suture_engine.trace.synthetic import synthetic_messages, synthetic_meta
from suture_engine.trace.writer import TraceMeta, TraceWriter


def _write(path: Path, duration_s: float = 0.05, **kwargs: Any) -> list[tuple[str, int, Any]]:
    """Writes a synthetic trace; returns what was written, as JSON would give it back."""
    written: list[tuple[str, int, Any]] = [("/meta", 0, synthetic_meta().to_message())]
    with TraceWriter(path, synthetic_meta(), **kwargs) as writer:
        for topic, t_ns, msg in synthetic_messages(duration_s):
            writer.write(topic, t_ns, msg)
            if topic.startswith("/qp/") and not kwargs.get("include_wall_clock"):
                msg = {k: v for k, v in msg.items() if k != "solve_time_us"}
            written.append((topic, t_ns, json.loads(json.dumps(msg))))
    return written


def test_round_trip_gives_back_every_message(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    written = _write(path, validate=True)
    reader = TraceReader(path)
    got = [(m.topic, m.log_time_ns, m.data) for m in reader.messages()]
    assert got == written
    assert reader.status.complete and not reader.status.truncated
    assert reader.status.message_count == len(written)
    assert reader.meta["procedure"] == "synthetic"
    assert reader.library.startswith("suture-engine/")


@pytest.mark.parametrize("compression", ["lz4", "none"])
def test_round_trip_other_compressions(tmp_path: Path, compression: Any) -> None:
    path = tmp_path / "t.mcap"
    written = _write(path, compression=compression)
    got = [(m.topic, m.log_time_ns, m.data) for m in TraceReader(path).messages()]
    assert got == written


def test_official_mcap_reader_agrees(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    path = tmp_path / "t.mcap"
    _write(path, duration_s=0.2, chunk_size=16 * 1024)
    ours = [(m.topic, m.log_time_ns, m.data) for m in TraceReader(path).messages()]
    with open(path, "rb") as f:
        reader = make_reader(f)
        theirs = []
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            assert schema is not None and schema.encoding == "jsonschema"
            assert channel.message_encoding == "json"
            assert message.publish_time == message.log_time
            theirs.append((channel.topic, message.log_time, json.loads(message.data)))
        summary = reader.get_summary()
        (metadata,) = reader.iter_metadata()
    assert theirs == ours
    assert metadata.name == "suture_engine"
    assert metadata.metadata["procedure"] == "synthetic" and metadata.metadata["seed"] == "0"
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == len(ours)
    assert len(summary.chunk_indexes) > 3  # several chunks were written


def test_chunks_are_bounded(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    path = tmp_path / "t.mcap"
    chunk_size = 8 * 1024
    _write(path, duration_s=0.1, chunk_size=chunk_size)
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    biggest_tick = 6 * 1024  # the messages of one tick, a centerline included, are fewer
    sizes = [c.uncompressed_size for c in summary.chunk_indexes]
    assert len(sizes) > 5
    assert max(sizes) <= chunk_size + biggest_tick
    # chunks hold whole ticks: no time step is split across two chunks (after /meta's)
    spans = [(c.message_start_time, c.message_end_time) for c in summary.chunk_indexes[1:]]
    assert all(end < nxt for (_, end), (nxt, _) in itertools.pairwise(spans))
    assert all(c.compression == "zstd" for c in summary.chunk_indexes)


def test_every_catalogue_schema_is_valid_json_schema() -> None:
    import jsonschema

    for spec in channels.CATALOGUE:
        jsonschema.Draft202012Validator.check_schema(spec.schema)
        jsonschema.Draft202012Validator.check_schema(channels.validation_schema(spec))
        assert json.loads(channels.schema_bytes(spec)) == spec.schema


def test_same_messages_give_byte_identical_files(tmp_path: Path) -> None:
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    _write(a, duration_s=0.1, chunk_size=8 * 1024)
    _write(b, duration_s=0.1, chunk_size=8 * 1024)
    assert a.read_bytes() == b.read_bytes()


def test_byte_identical_across_processes(tmp_path: Path) -> None:
    """Another interpreter (another hash seed) writes the same bytes."""
    here = tmp_path / "here.mcap"
    there = tmp_path / "there.mcap"
    _write(here, duration_s=0.1)
    code = (
        "import sys\n"
        "from suture_engine.trace.synthetic import write_synthetic_trace\n"
        "write_synthetic_trace(sys.argv[1], 0.1)\n"
    )
    env = dict(os.environ, PYTHONHASHSEED="12345")
    subprocess.run([sys.executable, "-c", code, str(there)], check=True, env=env)
    assert here.read_bytes() == there.read_bytes()


def test_key_order_does_not_change_the_bytes(tmp_path: Path) -> None:
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    meta_a = TraceMeta("p", 1, 1000.0, params={"x": 1, "y": {"b": 2, "a": 3}})
    meta_b = TraceMeta("p", 1, 1000.0, params={"y": {"a": 3, "b": 2}, "x": 1})
    with TraceWriter(a, meta_a) as w:
        w.write("/events", 5, {"name": "n", "kind": "info", "state": "s"})
    with TraceWriter(b, meta_b) as w:
        w.write("/events", 5, {"state": "s", "kind": "info", "name": "n"})
    assert a.read_bytes() == b.read_bytes()


def test_different_messages_give_different_files(tmp_path: Path) -> None:
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    meta = TraceMeta("p", seed=1, control_rate_hz=1000.0)
    for path, value in ((a, 0.1), (b, 0.1 + 1e-15)):
        with TraceWriter(path, meta) as w:
            w.write("/tension/estimated", 1000, {"tension_N": value})
    assert a.read_bytes() != b.read_bytes()


def test_no_wall_clock_by_default(tmp_path: Path) -> None:
    qp = {"status": "solved", "iterations": 4, "active_constraints": [], "solve_time_us": 31.0}
    meta = TraceMeta("p", seed=1, control_rate_hz=1000.0)
    for keep in (False, True):
        path = tmp_path / f"{keep}.mcap"
        with TraceWriter(path, meta, include_wall_clock=keep) as w:
            w.write(channels.qp_topic("left"), 0, qp)
        (msg,) = TraceReader(path).messages(["/qp/*"])
        assert ("solve_time_us" in msg.data) is keep


def test_centerline_points_are_stored_as_coordinate_arrays(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    points = np.array([[0.0, 0.1, 0.2], [1.0, 1.1, 1.2]])
    with TraceWriter(path, TraceMeta("p", 1, 1000.0), validate=True) as w:
        w.write(channels.GROUND_TRUTH_SUTURE, 0, {"centerline": points})
        with pytest.raises(TraceMessageError, match="malformed"):
            w.write(channels.GROUND_TRUTH_SUTURE, 1, {"centerline": [[0.0, 1.0]]})
    (msg,) = TraceReader(path).messages([channels.GROUND_TRUTH_SUTURE])
    assert msg.data == {"x": [0.0, 1.0], "y": [0.1, 1.1], "z": [0.2, 1.2]}


_FOXGLOVE_ITEM_TYPES = {"boolean", "string", "number", "integer", "object"}
_FOXGLOVE_FIELD_TYPES = _FOXGLOVE_ITEM_TYPES | {"array"}


def _check_foxglove_parsable(schema: dict[str, Any], where: str) -> None:
    """The subset of JSON Schema that Foxglove's JSON-schema parser accepts.

    An object with ``properties``; each field has one type among boolean, string,
    number, integer, object (recursively the same) and array; array items have one
    type among boolean, string, number, integer and object (no arrays of arrays).
    """
    assert schema.get("type") == "object", where
    assert isinstance(schema.get("properties"), dict), f"{where}: object without properties"
    for name, field in schema["properties"].items():
        here = f"{where}.{name}"
        kind = field.get("type")
        assert kind in _FOXGLOVE_FIELD_TYPES, f"{here}: type {kind!r}"
        if kind == "object":
            _check_foxglove_parsable(field, here)
        elif kind == "array":
            items = field.get("items", {})
            assert items.get("type") in _FOXGLOVE_ITEM_TYPES, f"{here}: items {items!r}"
            if items["type"] == "object":
                _check_foxglove_parsable(items, here + "[]")


def test_every_catalogue_schema_is_foxglove_parsable() -> None:
    for spec in channels.CATALOGUE:
        _check_foxglove_parsable(dict(spec.schema), spec.pattern)


def test_numpy_and_non_finite_values(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    with TraceWriter(path, TraceMeta("p", 1, 1000.0), validate=True) as w:
        w.write(
            "/joint_state/left",
            0,
            {"position": np.array([1.5, np.nan]), "velocity": [np.float32(0.25), math.inf]},
        )
    (msg,) = TraceReader(path).messages(["/joint_state/left"])
    assert msg.data == {"position": [1.5, None], "velocity": [0.25, None]}


def test_floats_round_trip_exactly(tmp_path: Path) -> None:
    rng = random.Random(3)
    values = [rng.uniform(-1e3, 1e3) * 10 ** rng.randint(-12, 12) for _ in range(500)]
    path = tmp_path / "t.mcap"
    with TraceWriter(path, TraceMeta("p", 1, 1000.0)) as w:
        w.write("/command/left", 5, {"kind": "torque", "values": values})
    (msg,) = TraceReader(path).messages(["/command/*"])
    assert msg.data["values"] == values  # bit-exact


def test_bad_input_gives_typed_errors(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    w = TraceWriter(path, TraceMeta("p", 1, 1000.0), validate=True)
    with pytest.raises(UnknownChannelError) as unknown:
        w.write("/nope", 0, {})
    assert "/joint_state/<robot>" in unknown.value.available
    with pytest.raises(UnknownChannelError):
        w.write("/joint_state/a b", 0, {"position": [], "velocity": []})
    w.write("/tension/estimated", 10, {"tension_N": 1.0})
    with pytest.raises(TraceMessageError, match="before"):
        w.write("/tension/estimated", 9, {"tension_N": 1.0})
    with pytest.raises(TraceMessageError, match="encode"):
        w.write("/tension/estimated", 11, {"tension_N": object()})
    with pytest.raises(TraceMessageError, match="does not match"):
        w.write("/tension/estimated", 11, {"tension": 1.0})
    w.close()
    w.close()  # idempotent
    with pytest.raises(TraceMessageError, match="closed"):
        w.write("/tension/estimated", 12, {"tension_N": 1.0})
    assert TraceReader(path).status.complete
    with pytest.raises(TraceIOError):
        TraceWriter(tmp_path / "missing-dir" / "t.mcap", TraceMeta("p", 1, 1000.0))


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (Linux)")
@pytest.mark.parametrize("fsync", [True, False])
def test_disk_full_gives_a_typed_error(fsync: bool) -> None:
    with pytest.raises(TraceIOError, match="No space left"):
        w = TraceWriter("/dev/full", TraceMeta("p", 1, 1000.0), fsync=fsync)
        for k in range(10_000):
            w.write("/tension/estimated", k * 1_000_000, {"tension_N": 1.0})
        w.close()


def test_flush_makes_messages_readable_before_close(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    w = TraceWriter(path, TraceMeta("p", 1, 1000.0), flush_interval_ns=0)
    for k in range(50):
        w.write("/tension/estimated", k * 1_000_000, {"tension_N": float(k)})
    assert TraceReader(path).status.message_count == 1  # /meta only: nothing flushed yet
    w.flush()
    assert w.last_durable_ns == 49_000_000
    status = TraceReader(path).status
    assert status.truncated and status.message_count == 51
    assert status.truncated_at_ns == 49_000_000
    w.close()


def test_flush_interval_is_simulation_time(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    w = TraceWriter(path, TraceMeta("p", 1, 1000.0), flush_interval_ns=100_000_000)
    for k in range(250):  # 0.25 s at 1 kHz: flushes before the ticks at 0.1 s and 0.2 s
        w.write("/tension/estimated", k * 1_000_000, {"tension_N": float(k)})
        w.write("/ground_truth/tension", k * 1_000_000, {"tension_N": float(k)})
    assert w.last_durable_ns == 199_000_000
    status = TraceReader(path).status
    assert status.truncated_at_ns == 199_000_000
    assert status.message_counts["/ground_truth/tension"] == 200  # whole ticks only
    w.close()


_CHILD = """
import sys
from suture_engine.trace.synthetic import synthetic_messages, synthetic_meta
from suture_engine.trace.writer import TraceWriter

w = TraceWriter(sys.argv[1], synthetic_meta(), chunk_size=int(sys.argv[2]))
durable = None
for topic, t_ns, msg in synthetic_messages(600.0):
    w.write(topic, t_ns, msg)
    if w.last_durable_ns != durable:
        durable = w.last_durable_ns
        print(durable, flush=True)
"""


@pytest.mark.parametrize("attempt", range(4))
def test_sigkilled_writer_leaves_a_readable_trace(tmp_path: Path, attempt: int) -> None:
    """A writer killed at a random point leaves a trace readable up to its last flush."""
    rng = random.Random(1000 + attempt)
    path = tmp_path / "killed.mcap"
    chunk_size = rng.choice([2048, 8192, 32768])
    proc = subprocess.Popen(
        [sys.executable, "-c", _CHILD, str(path), str(chunk_size)],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    lines = [proc.stdout.readline()]  # the writer is running and has flushed once
    time.sleep(rng.uniform(0.05, 0.6))
    os.kill(proc.pid, signal.SIGKILL)
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    lines += out.splitlines()
    durable = max(int(x) for x in lines if x.strip() and x.strip() != "None")
    reader = TraceReader(path)  # no exception: a truncated trace
    status = reader.status
    assert status.truncated and not status.complete
    assert status.truncated_at_ns is not None and status.truncated_at_ns >= durable
    # what was read is exactly a prefix of what was written, made of whole ticks
    expected = synthetic_messages(600.0)
    got = list(reader.messages())
    assert got[0].topic == "/meta"
    for msg in got[1:]:
        topic, t_ns, data = next(expected)
        if topic.startswith("/qp/"):
            data = {k: v for k, v in data.items() if k != "solve_time_us"}
        assert (msg.topic, msg.log_time_ns, msg.data) == (topic, t_ns, data)
    assert next(expected)[1] > got[-1].log_time_ns
