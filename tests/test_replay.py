"""The replay backend: a run's replay reproduces the engine's outputs to the bit."""

from __future__ import annotations

import fnmatch
from pathlib import Path
from typing import Any

import pytest

from suture_engine.arithmetic import CANONICAL_CORE, arithmetic_record
from suture_engine.runtime.run import COMPARED_TOPICS, replay_trace, run_procedure
from suture_engine.trace.reader import TraceReader

ROOT = Path(__file__).resolve().parent.parent
GOLDEN = ROOT / "tests" / "golden"


def _outputs(trace: Path, last_ns: int | None = None) -> list[tuple[str, int, Any]]:
    """The compared topics' messages in order (no tolerance: their data as recorded)."""
    out = []
    for m in TraceReader(trace).messages():
        if last_ns is not None and m.log_time_ns > last_ns:
            continue
        if any(fnmatch.fnmatch(m.topic, pat) for pat in COMPARED_TOPICS):
            out.append((m.topic, m.log_time_ns, m.data))
    return out


def _first_difference(a: list[Any], b: list[Any]) -> str:
    for x, y in zip(a, b, strict=False):
        if x != y:
            return f"first at {x[0]} t={x[1] / 1e9:.3f} s: {x[2]} != {y[2]}"
    return f"lengths {len(a)} != {len(b)}" if len(a) != len(b) else ""


def test_a_runs_replay_reproduces_its_commands_to_the_bit(tmp_path: Path) -> None:
    # The replayed tick's time is the live backend's tick * dt, to the bit: with
    # tick * period_ns * 1e-9 the move's trajectory was sampled at a time one ULP off on
    # some ticks and its torques differed in the last bit from 15 ms on.
    run = run_procedure(
        ROOT / "tests" / "procedures" / "reach.yaml",
        backend="pybullet",
        sets=["speed=100 mm/s"],
        out=tmp_path / "run",
    )
    rep = replay_trace(run.trace, out=tmp_path / "replay.mcap")
    recorded, replayed = _outputs(run.trace), _outputs(rep.trace)
    assert len(recorded) > 5000
    assert recorded == replayed, _first_difference(recorded, replayed)


@pytest.mark.parametrize("golden", sorted(p.name for p in GOLDEN.glob("*.mcap")))
def test_goldens_replay_to_the_bit_under_the_canonical_blas_kernel(
    golden: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The goldens were recorded with OpenBLAS' canonical kernel (suture_engine.arithmetic);
    # under it their replay gives the recorded commands exactly, on any CPU that runs it.
    if arithmetic_record()["blas_kernel"] != CANONICAL_CORE:
        pytest.skip(f"OpenBLAS kernel not pinned to {CANONICAL_CORE}: {arithmetic_record()}")
    path = GOLDEN / golden
    monkeypatch.chdir(ROOT)  # the golden names its procedure relative to the repository
    rep = replay_trace(path.relative_to(ROOT), out=tmp_path / "replay.mcap")
    last_ns = (rep.ticks - 1) * 1_000_000
    recorded = _outputs(path, last_ns)
    replayed = [m for m in _outputs(rep.trace, last_ns) if not m[0].startswith("/joint_state")]
    recorded = [m for m in recorded if not m[0].startswith("/joint_state")]
    assert len(recorded) > 1000
    assert recorded == replayed, _first_difference(recorded, replayed)


def test_a_check_notes_a_trace_recorded_under_another_blas_kernel() -> None:
    from suture_engine.runtime.run import _arithmetic_note

    now = arithmetic_record()["blas_kernel"]
    note = _arithmetic_note({"blas_kernel": "SkylakeX", "pin": "user"})
    assert "SkylakeX" in note and now in note
    assert "unrecorded" in _arithmetic_note(None)
    if now != "auto":
        assert _arithmetic_note({"blas_kernel": now, "pin": "pinned"}) == ""
