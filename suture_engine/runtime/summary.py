"""``summary.json``: a run's outcome in a few fields, written atomically."""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["RunSummary", "write_summary"]


@dataclass(frozen=True)
class RunSummary:
    """What ``summary.json`` holds.

    Attributes:
        procedure: the procedure's name.
        outcome: "succeeded", "failed" or "aborted".
        final_state: the automaton's last state.
        sim_time_s: simulated time [s].
        wall_time_s: wall time of the run [s].
        real_time_factor: sim_time_s / wall_time_s.
        control_rate_hz: control rate [Hz].
        max_tension_N: largest estimated tension [N].
        tension_limit_N: the procedure's tension limit [N] (None if none).
        violations: invariant violations (dicts: t, tick, state, robot, invariant, value, bound).
        retries: retries the failure policies made.
        operator_events: operator events received.
        metrics: procedure metrics (the skills'), plus the run's evaluation
            (:mod:`suture_engine.runtime.evaluation`): ``peak_tension_N``,
            ``final_tension_N`` (estimate), ``peak_true_tension_N``,
            ``final_true_tension_N`` (simulated thread), ``peak_true_tension_at`` (the
            true peak's ``t_s``, ``state`` and ``joint``, a point of the ground-truth
            centerline; None without a thread) and ``stitches`` (entry/exit
            position error, bite depth, spacing mean and SD, each with its resolution;
            None without a thread),
            plus the backend's own (``run_metrics()``; the PyBullet surgical scene with
            graspers: ``grip_slips``, the times the thread slid through a grasper's
            jaws, ``grip_slip_mm``, how far in all [mm], and ``grip_slips_by_robot``,
            robot -> ``{"slips", "mm"}``; with a stitcher: ``needle_stalls``, the needle
            hand-overs that stopped short; with a thread: ``thread``, the thread model
            the run was made on, ``PyBulletBackend.thread_model``).
        knot: the ground-truth knot evaluation: one entry (a dict with ``type``,
            ``determinant``, ``v2``, ``v3``, ``seated``, ``post_straight``, ``lay``, ...),
            a list of them when the thread has several stitches (one per stitch), or
            None when the backend simulates no thread.
        seed: the random seed.
        backend: the backend's name.
        ticks: ticks run.
        last_fault: the last unpredictable event of a step (skill failure, timeout,
            invariant violated, the monitor's emergency): ``step`` (dotted inside a
            sub-procedure), ``reason`` and ``t_s`` [s] simulated; None when there was
            none. On a run that ends failed or locked it says where and why.
    """

    procedure: str
    outcome: str
    final_state: str
    sim_time_s: float
    wall_time_s: float
    real_time_factor: float
    control_rate_hz: float
    max_tension_N: float
    tension_limit_N: float | None
    violations: list[dict[str, Any]]
    retries: int
    operator_events: int
    metrics: Mapping[str, Any] = field(default_factory=dict)
    knot: Mapping[str, Any] | list[Mapping[str, Any]] | None = None
    seed: int = 0
    backend: str = ""
    ticks: int = 0
    last_fault: Mapping[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict; non-finite numbers (NaN, inf) become ``None`` (JSON has none)."""
        out = asdict(self)
        out["metrics"] = dict(self.metrics)
        cleaned: dict[str, Any] = _finite(out)
        return cleaned


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def write_summary(path: str | Path, summary: RunSummary) -> Path:
    """Write ``summary`` as JSON at ``path`` atomically (temp file in the same folder + rename)."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".summary-", suffix=".json", dir=target.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(summary.to_dict(), fh, indent=2, sort_keys=True, allow_nan=False)
            fh.write("\n")
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target
