"""The trace writer's fast message path against mcap's own ``Writer.add_message``."""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

import pytest

from suture_engine.trace import writer as writer_mod
from suture_engine.trace.reader import TraceReader
from suture_engine.trace.writer import TraceMeta, TraceWriter


def _public(mcap_writer: Any) -> Any:
    def add(channel_id: int, time_ns: int, data: bytes) -> None:
        mcap_writer.add_message(channel_id, log_time=time_ns, data=data, publish_time=time_ns)

    return add


def _write(path: Path, seed: int) -> tuple[Path, str]:
    rng = random.Random(seed)
    meta = TraceMeta("fast-path", seed=seed, control_rate_hz=1000.0)
    with TraceWriter(path, meta, flush_interval_ns=37_000_000, fsync=False) as w:
        kind = w._add.__name__
        for k in range(400):
            t = k * 1_000_000
            for robot in ("left", "right"):
                q = [rng.uniform(-1, 1) for _ in range(4)]
                w.write(f"/joint_state/{robot}", t, {"position": q, "velocity": q[::-1]})
                w.write(f"/command/{robot}", t, {"kind": "torque", "values": q, "mode": "lock"})
            if rng.random() < 0.3:
                w.write("/tension/estimated", t, {"tension_N": rng.random(), "robot": "left"})
            if k % 97 == 0:
                w.write("/events", t, {"name": f"e{k}", "kind": "planned", "state": "s"})
    return path, kind


@pytest.mark.parametrize("seed", [0, 1])
def test_fast_path_writes_the_same_bytes_as_mcap(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, seed: int
) -> None:
    fast, kind = _write(tmp_path / "fast.mcap", seed)
    assert kind == "fast", "the fast path is not in use with this mcap version"
    monkeypatch.setattr(writer_mod, "_message_adder", _public)
    slow, kind = _write(tmp_path / "slow.mcap", seed)
    assert kind == "add"
    assert fast.read_bytes() == slow.read_bytes()
    msgs = list(TraceReader(fast).messages())
    assert len(msgs) > 1600
    assert msgs[-1].log_time_ns == 399_000_000


def test_other_chunking_uses_the_public_call(tmp_path: Path) -> None:
    from mcap.writer import Writer

    with open(tmp_path / "x.mcap", "wb") as f:
        w = Writer(f, chunk_size=1024)
        assert writer_mod._message_adder(w).__name__ == "public"


def _write_batches(path: Path, seed: int, batched: bool, **kwargs: Any) -> bytes:
    """The same messages through write() one by one, or per time step through
    write_encoded(); channels first appear in the middle of a batch."""
    from suture_engine.trace import codec

    rng = random.Random(seed)
    meta = TraceMeta("batches", seed=seed, control_rate_hz=1000.0)
    with TraceWriter(path, meta, flush_interval_ns=23_000_000, fsync=False, **kwargs) as w:
        for k in range(300):
            t = k * 1_000_000
            step: list[tuple[str, dict[str, Any]]] = []
            robots = ("left", "right") if k >= 5 else ("left",)
            for robot in robots:
                q = [rng.uniform(-1, 1) for _ in range(4)]
                step.append((f"/joint_state/{robot}", {"position": q, "velocity": q[::-1]}))
                if k % 3:
                    step.append(
                        (f"/command/{robot}", {"kind": "torque", "values": q, "mode": None})
                    )
            if k % 50 == 7:
                step.insert(1, ("/events", {"name": f"e{k}", "kind": "planned", "state": "s"}))
            if batched:
                w.write_encoded(t, [(topic, codec.encode(msg)) for topic, msg in step])
            else:
                for topic, msg in step:
                    w.write(topic, t, msg)
    return path.read_bytes()


@pytest.mark.parametrize(("seed", "message_index"), [(0, False), (3, False), (4, True)])
def test_write_encoded_writes_the_same_bytes_as_write(
    tmp_path: Path, seed: int, message_index: bool
) -> None:
    one = _write_batches(tmp_path / "one.mcap", seed, batched=False, message_index=message_index)
    batch = _write_batches(tmp_path / "batch.mcap", seed, batched=True, message_index=message_index)
    assert one == batch
    assert len(list(TraceReader(tmp_path / "batch.mcap").messages())) > 900


def test_write_encoded_through_mcaps_own_call(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for message_index in (False, True):
        fast = _write_batches(tmp_path / "f.mcap", 1, batched=True, message_index=message_index)
        with monkeypatch.context() as m:
            m.setattr(writer_mod, "_message_adder", _public)
            public = _write_batches(
                tmp_path / "p.mcap", 1, batched=True, message_index=message_index
            )
        assert fast == public


def test_write_encoded_checks_time_schema_and_state(tmp_path: Path) -> None:
    from suture_engine.trace.errors import TraceMessageError, UnknownChannelError

    meta = TraceMeta("checks", seed=0, control_rate_hz=1000.0)
    w = TraceWriter(tmp_path / "c.mcap", meta, fsync=False, validate=True)
    w.write_encoded(5, [("/tension/estimated", b'{"tension_N":1.0}')])
    w.write_encoded(5, [])
    with pytest.raises(TraceMessageError, match="before the previous"):
        w.write_encoded(4, [("/tension/estimated", b'{"tension_N":1.0}')])
    with pytest.raises(TraceMessageError, match="does not match"):
        w.write_encoded(6, [("/tension/estimated", b'{"tension_N":"high"}')])
    with pytest.raises(UnknownChannelError):
        w.write_encoded(6, [("/nowhere", b"{}")])
    w.close()
    with pytest.raises(TraceMessageError, match="closed"):
        w.write_encoded(7, [("/tension/estimated", b'{"tension_N":1.0}')])
    assert [m.log_time_ns for m in TraceReader(tmp_path / "c.mcap").messages()] == [0, 5]
