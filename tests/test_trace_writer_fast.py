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
