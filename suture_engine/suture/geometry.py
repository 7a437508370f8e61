"""Geometric descriptors of a tied suture: is the knot seated, is it capsized?

The thesis cares about where the knot sits and how it lies (4.5, 7.1):

- *seated*: the knot (the densest crossing region of the centerline, i.e.
  the crossings that survive the Reidemeister reduction of the classifier's
  diagram) lies on the tissue plane, within a tolerance;
- *post straight*: a square knot pulled the wrong way on its second throw
  capsizes into two half hitches around a straight post strand (Fig. 7.4).
  Each strand through the knot region is measured by its straightness,
  chord length / arc length of the strand inside the region (1 = straight);
- *loop size*: length and diameter of the stitch loop (the part of the
  suture that leaves the knot region and comes back, through the tissue).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from suture_engine.suture.topology import KnotReport, classify_knot, simplify_polyline

__all__ = ["KnotGeometry", "knot_geometry", "knot_region", "knot_summary", "straightness"]


@dataclass(frozen=True)
class KnotGeometry:
    """Where the knot is and how it lies.

    Attributes:
        centre: knot centre [m] (mean of its essential crossings), or None
            when the curve holds no knot.
        radius: radius of the knot region around the centre [m].
        height: signed distance of the centre above the tissue plane [m]
            (positive on the normal's side), or None.
        seated: ``|height| <= seat_tolerance``.
        straightness: chord / arc length of each strand inside the knot
            region, strand 1 first (the one nearer the first point) [-].
        post_straight: some strand runs straight through the knot
            (straightness >= the threshold) while another wraps around it:
            the two-half-hitch (capsized) configuration of Fig. 7.4.
        loop_length: arc length of the stitch loop outside the knot region
            [m], or None.
        loop_diameter: largest distance between two loop points [m], or None.
    """

    centre: tuple[float, float, float] | None
    radius: float
    height: float | None
    seated: bool
    straightness: tuple[float, ...]
    post_straight: bool
    loop_length: float | None
    loop_diameter: float | None

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready summary."""
        return {
            "centre": list(self.centre) if self.centre is not None else None,
            "radius": self.radius,
            "height": self.height,
            "seated": self.seated,
            "straightness": list(self.straightness),
            "post_straight": self.post_straight,
            "loop_length": self.loop_length,
            "loop_diameter": self.loop_diameter,
        }


def straightness(points: ArrayLike) -> float:
    """Chord length over arc length of a polyline [-] (1 for a straight one)."""
    pts = np.asarray(points, dtype=float)
    if len(pts) < 2:
        return 1.0
    arc = float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
    if arc <= 0:
        return 1.0
    return float(np.linalg.norm(pts[-1] - pts[0]) / arc)


def knot_region(
    report: KnotReport, *, scale: float = 1.5, min_radius: float = 0.0
) -> tuple[NDArray[np.float64], float] | None:
    """Centre and radius of the knot region from a classifier report.

    Args:
        report: the classifier's report (its essential crossings locate the
            knot).
        scale: region radius / largest distance of an essential crossing to
            the centre.
        min_radius: lower bound of the radius [m].

    Returns:
        ``(centre [m], radius [m])`` or None when no crossing is essential.
    """
    keep = set(report.essential)
    pts = np.array([c.point for c in report.crossing_list if c.label in keep])
    if len(pts) == 0:
        return None
    centre = pts.mean(axis=0)
    spread = float(np.max(np.linalg.norm(pts - centre, axis=1)))
    return centre, max(scale * spread, min_radius)


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Index ranges [start, stop) where mask is True."""
    runs: list[tuple[int, int]] = []
    start = None
    for i, m in enumerate(mask):
        if m and start is None:
            start = i
        elif not m and start is not None:
            runs.append((start, i))
            start = None
    if start is not None:
        runs.append((start, len(mask)))
    return runs


def knot_geometry(
    points: ArrayLike,
    *,
    tissue_point: ArrayLike,
    tissue_normal: ArrayLike,
    seat_tolerance: float = 1e-3,
    straight_threshold: float = 0.9,
    region_scale: float = 1.5,
    report: KnotReport | None = None,
    seed: int = 0,
    region: tuple[ArrayLike, float] | None = None,
) -> KnotGeometry:
    """Seating, post-strand straightness and loop size of a tied suture.

    Args:
        points: N x 3 suture centerline [m].
        tissue_point: a point of the tissue plane [m].
        tissue_normal: tissue normal (out of the tissue).
        seat_tolerance: largest |height| of a seated knot [m].
        straight_threshold: straightness above which a strand is straight.
        region_scale: knot region radius / spread of essential crossings.
        report: the classifier's report of ``points`` (computed when None).
        seed: classifier seed when the report is computed here.
        region: ``(centre [m], radius [m])`` of the knot region, to skip
            locating it from the classifier's crossings.

    Returns:
        the :class:`KnotGeometry`.
    """
    pts = simplify_polyline(points)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    if region is None:
        rep = report if report is not None else classify_knot(pts, seed=seed)
        found = knot_region(rep, scale=region_scale, min_radius=2.0 * float(np.median(seg)))
        if found is None:
            return KnotGeometry(None, 0.0, None, False, (), False, None, None)
        centre, radius = found
    else:
        centre, radius = np.asarray(region[0], dtype=float), float(region[1])
    n = np.asarray(tissue_normal, dtype=float)
    n = n / np.linalg.norm(n)
    height = float((centre - np.asarray(tissue_point, dtype=float)) @ n)
    inside = np.linalg.norm(pts - centre, axis=1) <= radius
    runs = _runs(inside)
    loop: tuple[int, int] | None = None
    if len(runs) >= 2:
        gaps = [(runs[k][1], runs[k + 1][0]) for k in range(len(runs) - 1)]
        lengths = [float(np.sum(seg[a - 1 : b])) for a, b in gaps]
        loop = gaps[int(np.argmax(lengths))]
    if loop is None:
        strands = [pts[runs[0][0] : runs[-1][1]]] if runs else []
        loop_length = loop_diameter = None
    else:
        strands = [pts[runs[0][0] : loop[0]], pts[loop[1] : runs[-1][1]]]
        loop_pts = pts[loop[0] - 1 : loop[1] + 1]
        loop_length = float(np.sum(np.linalg.norm(np.diff(loop_pts, axis=0), axis=1)))
        diff = loop_pts[:, None, :] - loop_pts[None, :, :]
        loop_diameter = float(np.sqrt(np.max(np.sum(diff * diff, axis=-1))))
    straight = tuple(straightness(s) for s in strands)
    post_straight = (
        len(straight) >= 2
        and max(straight) >= straight_threshold
        and min(straight) < straight_threshold
    )
    return KnotGeometry(
        centre=(float(centre[0]), float(centre[1]), float(centre[2])),
        radius=float(radius),
        height=height,
        seated=abs(height) <= seat_tolerance,
        straightness=straight,
        post_straight=bool(post_straight),
        loop_length=loop_length,
        loop_diameter=loop_diameter,
    )


def knot_summary(
    points: ArrayLike,
    *,
    tissue_point: ArrayLike,
    tissue_normal: ArrayLike,
    seat_tolerance: float = 1e-3,
    straight_threshold: float = 0.9,
    seed: int = 0,
) -> dict[str, object]:
    """The ``knot`` entry of a run summary: topology plus geometry, JSON-ready.

    Args:
        points: N x 3 suture centerline (ground truth) [m].
        tissue_point: a point of the tissue plane [m].
        tissue_normal: tissue normal (out of the tissue).
        seat_tolerance: largest |height| of a seated knot [m].
        straight_threshold: straightness above which a strand is straight.
        seed: classifier seed.

    Returns:
        the classifier's fields (type, chirality, determinant, alexander,
        v2, v3, crossings, writhe, votes, ...) and the geometry's (seated,
        post_straight, height, straightness, loop_length, ...).
    """
    pts = simplify_polyline(points)
    report = classify_knot(pts, seed=seed)
    geo = knot_geometry(
        pts,
        tissue_point=tissue_point,
        tissue_normal=tissue_normal,
        seat_tolerance=seat_tolerance,
        straight_threshold=straight_threshold,
        report=report,
    )
    out = report.to_dict()
    out.update(geo.to_dict())
    return out
