"""Synthetic traces with the channel mix of a real run, for tests and benchmarks.

The messages are plausible but made up (sinusoidal joint motion with seeded
noise); they exercise the writer, reader and golden comparison without a
simulator. Per control tick and robot: joint state, command, base wrench and
QP status; per tick: estimated and true tension; the suture centerline at a
lower rate; events and transitions now and then.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from suture_engine.trace import channels
from suture_engine.trace.writer import TraceMeta, TraceWriter

__all__ = ["synthetic_messages", "synthetic_meta", "write_synthetic_trace"]


def synthetic_meta(
    control_rate_hz: float = 1000.0, robots: Sequence[str] = ("left", "right"), seed: int = 0
) -> TraceMeta:
    """The ``/meta`` of a synthetic trace.

    Args:
        control_rate_hz: control rate [Hz].
        robots: robot names.
        seed: the seed recorded.
    """
    return TraceMeta(
        procedure="synthetic",
        seed=seed,
        control_rate_hz=control_rate_hz,
        params={"amplitude_rad": 0.2},
        robots=tuple(robots),
        backend="synthetic",
    )


def synthetic_messages(
    duration_s: float,
    *,
    control_rate_hz: float = 1000.0,
    robots: Sequence[str] = ("left", "right"),
    seed: int = 0,
    n_joints: int = 7,
    centerline_rate_hz: float = 50.0,
    centerline_points: int = 60,
    event_period_s: float = 0.5,
) -> Iterator[tuple[str, int, dict[str, Any]]]:
    """The messages of a synthetic run, in time order.

    Args:
        duration_s: simulated duration [s].
        control_rate_hz: control rate [Hz].
        robots: robot names.
        seed: seed of the noise.
        n_joints: joints per robot.
        centerline_rate_hz: rate of ``/ground_truth/suture`` [Hz].
        centerline_points: points per centerline.
        event_period_s: period of the planned events [s].

    Yields:
        ``(topic, time [ns], message)``.
    """
    import numpy as np

    rng = np.random.default_rng(seed)
    period_ns = round(1e9 / control_rate_hz)
    ticks = round(duration_s * control_rate_hz)
    centerline_every = max(1, round(control_rate_hz / centerline_rate_hz))
    event_every = max(1, round(event_period_s * control_rate_hz))
    phase = np.arange(n_joints) * 0.3
    state = "approach"
    for k in range(ticks):
        t_ns = k * period_ns
        t = t_ns / 1e9
        for r, robot in enumerate(robots):
            q = 0.2 * np.sin(2.0 * math.pi * 0.5 * t + phase + r)
            dq = 0.2 * math.pi * np.cos(2.0 * math.pi * 0.5 * t + phase + r)
            dq = dq + 1e-3 * rng.standard_normal(n_joints)
            yield (
                channels.joint_state_topic(robot),
                t_ns,
                {"position": q.tolist(), "velocity": dq.tolist()},
            )
            yield (
                channels.command_topic(robot),
                t_ns,
                {"kind": "torque", "values": (-5.0 * q - 0.5 * dq).tolist(), "mode": "Autonomous"},
            )
            wrench = rng.standard_normal(6) * 0.05
            yield (
                channels.base_wrench_topic(robot),
                t_ns,
                {"force": wrench[:3].tolist(), "torque": wrench[3:].tolist()},
            )
            yield (
                channels.qp_topic(robot),
                t_ns,
                {
                    "status": "solved",
                    "iterations": int(5 + k % 7),
                    "active_constraints": ["line"] if k % 3 == 0 else [],
                    "solve_time_us": float(30 + rng.random() * 10),
                },
            )
        tension = 1.0 + 0.5 * math.sin(2.0 * math.pi * 0.2 * t)
        yield channels.TENSION_ESTIMATED, t_ns, {"tension_N": tension + 0.01 * rng.random()}
        yield channels.GROUND_TRUTH_TENSION, t_ns, {"tension_N": tension}
        if k % centerline_every == 0:
            s = np.linspace(0.0, 0.3, centerline_points)
            y = (0.01 * np.sin(20 * s + t)).round(6)
            yield (
                channels.GROUND_TRUTH_SUTURE,
                t_ns,
                {"x": s.round(6).tolist(), "y": y.tolist(), "z": [0.0] * centerline_points},
            )
        if k > 0 and k % event_every == 0:
            nxt = "tighten" if state == "approach" else "approach"
            yield channels.EVENTS, t_ns, {"name": f"reached_{nxt}", "kind": "planned"}
            yield (
                channels.TRANSITIONS,
                t_ns,
                {"source": state, "dest": nxt, "trigger": f"reached_{nxt}"},
            )
            state = nxt


def write_synthetic_trace(
    path: str | os.PathLike[str], duration_s: float, *, seed: int = 0, **writer_kwargs: Any
) -> Path:
    """Writes a synthetic trace of ``duration_s`` seconds at 1 kHz and two robots.

    Args:
        path: the output file.
        duration_s: simulated duration [s].
        seed: seed of the noise.
        **writer_kwargs: passed to :class:`~suture_engine.trace.writer.TraceWriter`.

    Returns:
        The path written.
    """
    with TraceWriter(path, synthetic_meta(seed=seed), **writer_kwargs) as writer:
        for topic, t_ns, message in synthetic_messages(duration_s, seed=seed):
            writer.write(topic, t_ns, message)
    return Path(path)
