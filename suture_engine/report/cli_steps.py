"""The ``suture steps`` command: what the robots measured in each state of one or more runs.

``suture steps TRACE...`` prints, per visited state, each robot's tool-tip travel and
its base sensor's tension estimate (start, end, peak), and the true peak beside them
(ground truth, marked). ``--state GLOB`` keeps the states whose names match.
``--csv FILE`` writes one row per state and run, labelled with the run's outcome and
knot from its ``summary.json``: the table a new check's threshold is set from.
``--json`` prints the same rows as one JSON array.

Exit codes: 0 every trace read; 1 a trace corrupt, foreign or without states; 2 a
missing trace or an output that cannot be written. Nothing is written unless every
trace was read.
"""

from __future__ import annotations

import csv
import io
import json
import sys
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any, TextIO

__all__ = ["steps_command"]


def _rows(trace: Path, label: dict[str, Any], states: Sequence[str]) -> list[dict[str, Any]]:
    """One flat dict per state of ``trace``, labelled with its run's ``label``."""
    from suture_engine.report.steps import state_measures

    rows: list[dict[str, Any]] = []
    for s in state_measures(trace, states=states):
        row: dict[str, Any] = {
            "trace": str(trace),
            "outcome": label.get("outcome"),
            "knot": label.get("knot"),
            "state": s.state,
            "start_s": round(s.start_s, 4),
            "end_s": round(s.end_s, 4),
            "duration_s": round(s.duration_s, 4),
        }
        for robot, m in s.robots.items():
            for key, value in asdict(m).items():
                if key == "displacement_mm":
                    for axis, v in zip("xyz", value or (None, None, None), strict=True):
                        row[f"{robot}.displacement_{axis}_mm"] = v
                else:
                    row[f"{robot}.{key}"] = value
        row["true_peak_N (ground truth)"] = s.true_peak_N
        row["true_peak_joint (ground truth)"] = s.true_peak_joint
        rows.append(row)
    return rows


def _num(value: Any, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _at(row: dict[str, Any]) -> str:
    joint = row.get("true_peak_joint (ground truth)")
    return "" if joint is None else f" (joint {joint})"


def _text(trace: Path, label: dict[str, Any], rows: list[dict[str, Any]], out: TextIO) -> None:
    robots = sorted({k.split(".", 1)[0] for r in rows for k in r if k.endswith(".travel_mm")})
    out.write(
        f"{trace}  (outcome {label.get('outcome') or '?'}, knot {label.get('knot') or '?'})\n"
    )
    cols = "".join(f"  {r + ': travel mm, estimate start/end/peak N':<46}" for r in robots)
    width = max([len("state"), *(len(r["state"]) for r in rows)])
    out.write(
        f"{'state':<{width}} {'from [s]':>9} {'to [s]':>9}{cols}  true peak N (ground truth)\n"
    )
    for r in rows:
        cells = "".join(
            f"  {_num(r[f'{b}.travel_mm'], 1):>6} (path {_num(r[f'{b}.path_mm'], 1):>6})"
            f"  {_num(r[f'{b}.estimate_start_N'], 2):>5}/{_num(r[f'{b}.estimate_end_N'], 2):>5}"
            f"/{_num(r[f'{b}.estimate_peak_N'], 2):>5}     "
            for b in robots
        )
        out.write(
            f"{r['state']:<{width}} {r['start_s']:>9.2f} {r['end_s']:>9.2f}{cells}"
            f"  {_num(r['true_peak_N (ground truth)'], 2)}{_at(r)}\n"
        )


def steps_command(
    traces: Sequence[Path],
    *,
    states: Sequence[str] = (),
    as_json: bool = False,
    csv_path: Path | None = None,
    out: TextIO | None = None,
    err: TextIO | None = None,
) -> int:
    """Prints (or writes as CSV) what the robots measured in each state of each trace.

    Args:
        traces: trace files (``trace.mcap``).
        states: glob patterns of the states to give; all when empty.
        as_json: print one JSON array of rows instead of text.
        csv_path: write the rows here as CSV (and print nothing but where).
        out, err: streams (default: stdout, stderr).

    Returns:
        The exit code (see the module doc).
    """
    from suture_engine.trace.errors import TraceError, TraceIOError

    out = out or sys.stdout
    err = err or sys.stderr
    for trace in traces:
        if not trace.is_file():
            err.write(f"error: {trace}: no such file\n")
            return 2
    if csv_path is not None and (csv_path.is_dir() or not csv_path.parent.is_dir()):
        err.write(f"error: {csv_path}: cannot write a CSV file there\n")
        return 2
    from suture_engine.report.steps import run_label

    per_trace: list[tuple[Path, dict[str, Any], list[dict[str, Any]]]] = []
    for trace in traces:
        try:
            label = run_label(trace)
            rows = _rows(trace, label, states)
        except TraceError as exc:
            err.write(f"error: {exc}\n")
            return 2 if isinstance(exc, TraceIOError) else 1
        if not states and all(r["state"] == "(start)" for r in rows):
            err.write(f"error: {trace}: no states recorded (no /transitions messages)\n")
            return 1
        per_trace.append((trace, label, rows))
    flat = [r for _, _, rows in per_trace for r in rows]
    if csv_path is not None:
        fields: list[str] = []
        for r in flat:
            fields.extend(k for k in r if k not in fields)
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=fields)
        writer.writeheader()
        writer.writerows(flat)
        csv_path.write_text(buf.getvalue())
        out.write(f"{len(flat)} rows from {len(per_trace)} trace(s) written to {csv_path}\n")
        return 0
    if as_json:
        out.write(json.dumps(flat, indent=1) + "\n")
        return 0
    for trace, label, rows in per_trace:
        _text(trace, label, rows, out)
    return 0
