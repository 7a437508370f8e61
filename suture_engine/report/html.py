"""One self-contained HTML page per run.

The page holds the figures of :mod:`suture_engine.report.figures` as base64 PNG,
the run summary, the knot classification, and the procedure's state machine as
Mermaid text. Nothing is fetched from the network: mermaid.js is not bundled, so
the graph is shown as its readable Mermaid source in a ``<pre class="mermaid">``
block (a page that loads mermaid.js itself would draw it). The file is written
atomically: a temporary file in the output folder, then a rename.

Example:
    >>> data = load_trace("runs/demo/trace.mcap")
    >>> write_report(build_report(data), "runs/demo/report.html")
"""

from __future__ import annotations

import base64
import html
import json
import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

from suture_engine.report.figures import RenderedFigure, TraceData, render_figures
from suture_engine.trace import channels

__all__ = ["KnotInfo", "build_report", "knot_info", "procedure_graph", "write_report"]

_CSS = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 980px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; } td, th { padding: 2px 10px; text-align: left; }
tr:nth-child(even) { background: #f4f4f4; }
.figure { margin: 1em 0; } .figure img { width: 100%; border: 1px solid #ddd; }
.warn { background: #fff3cd; padding: 6px 10px; border: 1px solid #e0c36c; }
.note { color: #666; font-size: 0.9em; }
pre.mermaid { background: #f7f7f7; padding: 8px; border: 1px solid #ddd; overflow-x: auto; }
"""


class KnotInfo(NamedTuple):
    """The knot classification shown in the report.

    Attributes:
        source: where it comes from (``/ground_truth/knot``, ``summary.json``,
            ``classified from /ground_truth/suture``) or ``""`` when there is none.
        fields: the classification's fields (type, crossings, seated, ...).
    """

    source: str
    fields: Mapping[str, Any]


def knot_info(data: TraceData, classify: bool = True) -> KnotInfo:
    """The run's knot classification.

    In order: the last ``/ground_truth/knot`` message, the ``knot`` of
    ``summary.json``, or (with ``classify``) the classifier run on the last
    ``/ground_truth/suture`` centerline (evaluation only, never seen by skills).

    Args:
        data: the trace.
        classify: run the knot classifier when the trace holds only a centerline.
    """
    knots = data.get(channels.GROUND_TRUTH_KNOT)
    if knots and isinstance(knots[-1][1], dict):
        return KnotInfo(channels.GROUND_TRUTH_KNOT, dict(knots[-1][1]))
    if data.summary and isinstance(data.summary.get("knot"), dict):
        return KnotInfo("summary.json", dict(data.summary["knot"]))
    if data.summary and isinstance(data.summary.get("knot"), list):
        # one entry per stitch (a multi-stitch procedure): "stitch N <field>" rows
        fields = {
            f"stitch {i} {key}": value
            for i, entry in enumerate(data.summary["knot"], 1)
            if isinstance(entry, dict)
            for key, value in entry.items()
        }
        return KnotInfo("summary.json (one entry per stitch)", fields)
    lines = data.get(channels.GROUND_TRUTH_SUTURE)
    if classify and lines and isinstance(lines[-1][1], dict):
        from suture_engine.errors import SutureError
        from suture_engine.suture.topology import classify_knot

        m = lines[-1][1]
        try:
            points = [
                (float(x), float(y), float(z))
                for x, y, z in zip(m["x"], m["y"], m["z"], strict=True)
            ]
            report = classify_knot(points)
        except (SutureError, KeyError, TypeError, ValueError) as exc:
            return KnotInfo(
                f"{channels.GROUND_TRUTH_SUTURE} (not classifiable)", {"error": str(exc)}
            )
        return KnotInfo(
            f"classified from the last {channels.GROUND_TRUTH_SUTURE}",
            {
                "type": report.type,
                "chirality": report.chirality,
                "crossings": report.crossings,
                "determinant": report.determinant,
                "alexander": report.alexander_text,
                "agreement": round(report.agreement, 3),
            },
        )
    return KnotInfo("", {})


def procedure_graph(data: TraceData) -> str | None:
    """The Mermaid drawing of the procedure named in ``/meta`` (None if it does not load)."""
    name = data.meta.get("procedure_file")
    if not isinstance(name, str) or not Path(name).is_file():
        return None
    from suture_engine.language.loader import load
    from suture_engine.validation.graph import to_mermaid

    try:
        result = load(Path(name), allow_outside=True)
    except Exception:  # the procedure changed or is unreadable: no graph, said on the page
        return None
    if result.problems or result.procedure is None:
        return None
    return to_mermaid(result.procedure)


def _table(rows: Sequence[tuple[str, Any]]) -> str:
    body = "".join(
        f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(_fmt(v))}</td></tr>" for k, v in rows
    )
    return f"<table>{body}</table>"


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, dict | list):
        return json.dumps(value, sort_keys=True)
    return "" if value is None else str(value)


def _figure(fig: RenderedFigure) -> str:
    b64 = base64.b64encode(fig.png).decode("ascii")
    note = ""
    if fig.missing:
        note = (
            "<p class='note'>no data on: " + ", ".join(html.escape(m) for m in fig.missing) + "</p>"
        )
    return (
        f"<div class='figure' id='fig-{fig.name}'><h3>{html.escape(fig.title)}</h3>"
        f"<img alt='{html.escape(fig.title)}' src='data:image/png;base64,{b64}'>{note}</div>"
    )


def build_report(data: TraceData, figures: Sequence[RenderedFigure] | None = None) -> str:
    """The HTML page of one run.

    Args:
        data: the trace, from :func:`~suture_engine.report.figures.load_trace`.
        figures: figures already drawn (default: draw all of them).
    """
    figs = list(figures) if figures is not None else render_figures(data)
    meta = data.meta
    title = f"suture-engine run: {meta.get('procedure', data.path.name)}"
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        f"<title>{html.escape(str(title))}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(str(title))}</h1>",
    ]
    status = data.status
    if status.truncated:
        parts.append(
            f"<p class='warn'>The trace ends early ({html.escape(status.reason)}): figures "
            f"stop at t = {data.duration_s:.3f} s.</p>"
        )
    parts.append("<h2>Run</h2>")
    run_rows: list[tuple[str, Any]] = [
        ("trace", str(data.path)),
        ("messages", status.message_count),
        ("simulated time [s]", data.duration_s),
    ]
    run_rows += [
        (k, meta[k])
        for k in ("procedure", "seed", "backend", "control_rate_hz", "params")
        if k in meta
    ]
    parts.append(_table(run_rows))
    parts.append("<h2>Summary</h2>")
    if data.summary:
        keys = [k for k in data.summary if k not in ("knot", "violations", "metrics")]
        rows = [(k, data.summary[k]) for k in keys]
        rows.append(("violations", len(data.summary.get("violations") or [])))
        parts.append(_table(rows))
        violations = data.summary.get("violations") or []
        if violations:
            parts.append("<h3>Invariant violations</h3>")
            parts.append(_table([(str(i + 1), v) for i, v in enumerate(violations)]))
        metrics = data.summary.get("metrics") or {}
        if metrics:
            parts.append("<h3>Metrics</h3>")
            parts.append(_table(sorted(metrics.items())))
    else:
        parts.append("<p class='note'>no summary.json beside the trace</p>")
    parts.append("<h2>Knot</h2>")
    knot = knot_info(data)
    if knot.source:
        parts.append(f"<p class='note'>from {html.escape(knot.source)}</p>")
        parts.append(_table(sorted(knot.fields.items())))
    else:
        parts.append(
            f"<p class='note'>no data on {channels.GROUND_TRUTH_KNOT} or "
            f"{channels.GROUND_TRUTH_SUTURE}, and no knot in summary.json</p>"
        )
    parts.append("<h2>Figures</h2>")
    parts.extend(_figure(f) for f in figs)
    parts.append("<h2>Procedure graph</h2>")
    graph = procedure_graph(data)
    if graph is None:
        parts.append(
            "<p class='note'>the procedure file named in the trace is not available or does "
            "not load: no graph</p>"
        )
    else:
        parts.append(
            "<p class='note'>Mermaid source (mermaid.js is not embedded: the page works "
            "offline; paste it into any Mermaid viewer to draw it)</p>"
        )
        parts.append(f"<pre class='mermaid'>{html.escape(graph)}</pre>")
    parts.append("</body></html>\n")
    return "".join(parts)


def write_report(page: str, path: str | os.PathLike[str]) -> Path:
    """Write ``page`` at ``path`` atomically (temp file in the same folder + rename)."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".report-", suffix=".html", dir=target.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(page)
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target
