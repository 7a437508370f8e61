"""Cost of writing a trace: microseconds per message and megabytes per simulated minute.

Writes the channel mix of a two-robot run at 1 kHz (joint state, command, base
wrench and QP status per robot, estimated and true tension per tick, the suture
centerline at 50 Hz, events now and then; see ``suture_engine.trace.synthetic``)
with the default writer settings, and prints the time spent in
``TraceWriter.write`` (messages are generated beforehand, so only writing counts)
and the file size scaled to one simulated minute.

With ``--trace FILE`` it re-writes the messages of a recorded trace instead (the
channel mix and values of a real run).

Usage:
    python benchmarks/trace_write_cost.py [--seconds 10] [--trace runs/x/trace.mcap]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from suture_engine.trace.reader import TraceReader
from suture_engine.trace.synthetic import synthetic_messages, synthetic_meta
from suture_engine.trace.writer import TraceWriter


def _run(messages: list[tuple[str, int, Any]], seconds: float, **kwargs: Any) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "trace.mcap"
        per_tick: list[float] = []
        writer = TraceWriter(path, synthetic_meta(), **kwargs)
        clock = time.perf_counter
        total = 0.0
        cpu0 = time.process_time()
        tick_time, tick_ns = 0.0, 0
        for topic, t_ns, msg in messages:
            if t_ns != tick_ns:
                per_tick.append(tick_time)
                tick_time, tick_ns = 0.0, t_ns
            t0 = clock()
            writer.write(topic, t_ns, msg)
            dt = clock() - t0
            tick_time += dt
            total += dt
        t0 = clock()
        writer.close()
        total += clock() - t0
        cpu = time.process_time() - cpu0
        size = path.stat().st_size
        assert TraceReader(path, allow_truncated=False).status.message_count == len(messages) + 1
    per_tick.sort()
    return {
        "us_per_message": total / len(messages) * 1e6,
        "cpu_us_per_message": cpu / len(messages) * 1e6,
        "tick_median_us": statistics.median(per_tick) * 1e6,
        "tick_p99_us": per_tick[int(0.99 * (len(per_tick) - 1))] * 1e6,
        "mb_per_min": size / 1e6 * 60.0 / seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated duration [s]")
    parser.add_argument("--trace", type=Path, help="re-write this recorded trace's messages")
    args = parser.parse_args()
    if args.trace is not None:
        reader = TraceReader(args.trace)
        messages = [
            (m.topic, m.log_time_ns, m.data) for m in reader.messages() if m.topic != "/meta"
        ]
        seconds = (messages[-1][1] - messages[0][1]) / 1e9 + 1e-3
        source = f"the messages of {args.trace}"
    else:
        messages = list(synthetic_messages(args.seconds))
        seconds = args.seconds
        source = "synthetic messages (1 kHz, 2 robots)"
    rate = len(messages) / seconds
    print(
        f"{len(messages)} {source} over {seconds:g} s simulated "
        f"({rate:.0f} messages per simulated second)"
    )
    per_tick = rate / 1000.0
    print(
        "us/message: mean wall time over all messages, chunk compression and fsync included;"
        " CPU us/msg: the same in process CPU time (not inflated by other processes);"
        f" median us/msg: the median tick's wall time / {per_tick:.1f} messages per tick"
    )
    header = (
        f"{'setting':<34} {'us/message':>10} {'CPU us/msg':>10} {'median us/msg':>14} "
        f"{'tick median us':>15} "
        f"{'tick p99 us':>12} {'MB/sim-min':>11}"
    )
    print(header)
    for label, kwargs in (
        ("default (zstd, 256 KiB, fsync)", {}),
        ("zstd, no fsync", {"fsync": False}),
        ("lz4, fsync", {"compression": "lz4"}),
        ("zstd + message indexes, fsync", {"message_index": True}),
    ):
        r = _run(messages, seconds, **kwargs)
        print(
            f"{label:<34} {r['us_per_message']:>10.2f} {r['cpu_us_per_message']:>10.2f} "
            f"{r['tick_median_us'] / per_tick:>14.2f} {r['tick_median_us']:>15.1f} "
            f"{r['tick_p99_us']:>12.1f} {r['mb_per_min']:>11.1f}"
        )


if __name__ == "__main__":
    main()
