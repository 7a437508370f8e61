"""The ``suture knot`` command: classify a suture centerline stored in a file.

``suture knot FILE`` reads an N x 3 centerline (``.npy``; ``.json`` as a
list of [x, y, z] or ``{"points": [...]}``; anything else as text, comma or
whitespace separated, one point a line) and prints the knot type, chirality
and invariants (``--json`` for one JSON object). Optionally, with
``--tissue-point`` and ``--tissue-normal``, also the geometry: seated, post
straight, loop size.

Given a run's trace (``.mcap``) instead, it prints the knot the simulated thread held
at the end of each visited state, with the peak true tension during the state
(:mod:`suture_engine.suture.timeline`): where a knot formed and where it was lost.

Exit codes: 0 classified, 1 not a valid centerline (or a trace without a thread),
2 I/O error.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

__all__ = ["knot_command", "load_centerline"]


def load_centerline(path: Path) -> object:
    """Read a centerline file into a nested list or array (not yet validated).

    Raises:
        OSError: the file cannot be read.
        ValueError: the file cannot be parsed.
    """
    import numpy as np

    suffix = path.suffix.lower()
    if suffix == ".npy":
        return np.load(path, allow_pickle=False)
    text = path.read_text(encoding="utf-8")
    if suffix == ".json":
        data = json.loads(text)
        return data["points"] if isinstance(data, dict) else data
    rows = [
        [float(x) for x in line.replace(",", " ").split()]
        for line in text.splitlines()
        if line.strip() and not line.lstrip().startswith("#")
    ]
    return rows


def knot_command(
    path: Path,
    *,
    as_json: bool = False,
    seed: int = 0,
    tissue_point: list[float] | None = None,
    tissue_normal: list[float] | None = None,
) -> int:
    """Classify the knot of a centerline file and print the report.

    Args:
        path: the centerline file.
        as_json: print one JSON object instead of text.
        seed: classifier seed.
        tissue_point: a point of the tissue plane [m] (with ``tissue_normal``
            adds the geometry descriptors).
        tissue_normal: tissue normal.

    Returns:
        The exit code.
    """
    from suture_engine.suture.topology import InvalidCenterline, classify_knot

    if path.suffix.lower() == ".mcap":
        return timeline_command(path, as_json=as_json, seed=seed)
    try:
        points = load_centerline(path)
    except OSError as exc:
        print(f"error: cannot read {path}: {exc}", file=sys.stderr)
        return 2
    except (ValueError, KeyError, TypeError) as exc:
        print(f"error: {path}: not a centerline file ({exc})", file=sys.stderr)
        return 1
    try:
        report = classify_knot(points, seed=seed)  # type: ignore[arg-type]
    except InvalidCenterline as exc:
        print(f"error: {path}: {exc.message}", file=sys.stderr)
        return 1
    out = report.to_dict()
    if (tissue_point is None) != (tissue_normal is None):
        print("error: give both --tissue-point and --tissue-normal", file=sys.stderr)
        return 2
    if tissue_point is not None and tissue_normal is not None:
        from suture_engine.suture.geometry import knot_geometry

        geo = knot_geometry(
            points,  # type: ignore[arg-type]
            tissue_point=tissue_point,
            tissue_normal=tissue_normal,
            report=report,
        )
        out.update(geo.to_dict())
    if as_json:
        print(json.dumps(out))
        return 0
    kind = report.type if report.chirality is None else f"{report.type} ({report.chirality})"
    print(f"knot: {kind}")
    print(f"  Alexander polynomial: {report.alexander_text}   determinant: {report.determinant}")
    print(f"  v2: {report.v2}   v3: {report.v3}   writhe: {report.writhe}")
    print(
        f"  crossings: {report.crossings} (projection: {report.raw_crossings})"
        f"   votes: {report.votes}/{report.projections}"
    )
    if "seated" in out:
        print(
            f"  seated: {out['seated']}   height: {out['height']}   "
            f"post straight: {out['post_straight']}   straightness: {out['straightness']}"
        )
    return 0


def timeline_command(path: Path, *, as_json: bool = False, seed: int = 0) -> int:
    """Print the thread's knot at the end of each state of a recorded run.

    Args:
        path: the run's trace (``trace.mcap``).
        as_json: print one JSON list of rows instead of a table.
        seed: classifier seed.

    Returns:
        The exit code.
    """
    from dataclasses import asdict

    from suture_engine.suture.timeline import NoGroundTruth, knot_timeline
    from suture_engine.trace.errors import TraceError, TraceIOError

    try:
        rows = list(knot_timeline(path, seed=seed))
    except TraceIOError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except (TraceError, NoGroundTruth) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    if as_json:
        print(json.dumps([asdict(r) for r in rows]))
        return 0
    width = max([len(r.state) for r in rows] + [5])
    print(f"{'state':<{width}}  {'start s':>8}  {'end s':>8}  {'knot':<12} {'det':>4}  peak true N")
    for r in rows:
        det = "" if r.determinant is None else str(r.determinant)
        peak = "" if r.peak_tension_N is None else f"{r.peak_tension_N:.2f}"
        print(
            f"{r.state:<{width}}  {r.start_s:8.2f}  {r.end_s:8.2f}  {r.knot or '-':<12} "
            f"{det:>4}  {peak}"
        )
    return 0
