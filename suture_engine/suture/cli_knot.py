"""The ``suture knot`` command: classify a suture centerline stored in a file.

``suture knot FILE`` reads an N x 3 centerline (``.npy``; ``.json`` as a
list of [x, y, z] or ``{"points": [...]}``; anything else as text, comma or
whitespace separated, one point a line) and prints the knot type, chirality
and invariants (``--json`` for one JSON object). Optionally, with
``--tissue-point`` and ``--tissue-normal``, also the geometry: seated, post
straight, loop size.

Exit codes: 0 classified, 1 not a valid centerline, 2 I/O error.
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
