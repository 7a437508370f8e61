"""Knot geometry descriptors: seating, post-strand straightness, loop size.

Expected values come from how each curve is built (a straight post, a
helix of known pitch, a semicircular loop), computed here in closed form.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from suture_engine.suture import curves
from suture_engine.suture.geometry import knot_geometry, knot_region, knot_summary, straightness
from suture_engine.suture.topology import classify_knot

UP = np.array([0.0, 0.0, 1.0])


def test_straightness_closed_forms() -> None:
    line = np.c_[np.linspace(0, 1, 10), np.zeros(10), np.zeros(10)]
    assert straightness(line) == pytest.approx(1.0)
    s = np.linspace(0.0, math.pi, 2001)
    half_circle = np.c_[np.cos(s), np.sin(s), np.zeros_like(s)]
    assert straightness(half_circle) == pytest.approx(2.0 / math.pi, rel=1e-5)
    # helix radius r, pitch p per turn, n turns: chord n p, arc n sqrt((2 pi r)^2 + p^2)
    t = np.linspace(0.0, 2 * 2 * math.pi, 4001)
    helix = np.c_[0.6 * np.cos(t), 0.6 * np.sin(t), 0.8 * t / (2 * math.pi)]
    expected = 0.8 / math.hypot(2 * math.pi * 0.6, 0.8)
    assert straightness(helix) == pytest.approx(expected, rel=1e-5)


def test_half_hitches_have_a_straight_post() -> None:
    pts = curves.half_hitches(240)
    geo = knot_geometry(
        pts, tissue_point=[0.0, 0.0, -0.5], tissue_normal=UP, region=([0.0, 0.0, 0.0], 1.2)
    )
    assert geo.straightness[0] == pytest.approx(1.0)
    assert geo.straightness[1] < 0.5
    assert geo.post_straight
    # The loop outside the region: the post from x = 1.2 to 3 (1.8), the
    # step to y = 0.6 (0.6), and the half ellipse of semi-axes 1.1 (x) and
    # 2.5 (z) (Ramanujan: 5.87) less its last stretch inside the region
    # (about 0.7): about 7.6.
    ramanujan = math.pi * (3 * 3.6 - math.sqrt((3 * 1.1 + 2.5) * (1.1 + 3 * 2.5))) / 2
    assert geo.loop_length == pytest.approx(1.8 + 0.6 + ramanujan - 0.7, rel=0.05)
    # deepest point of the loop is 2.5 below the post; the diameter is a bit more
    assert geo.loop_diameter is not None and 2.5 < geo.loop_diameter < 3.2


def _square_like(wrap_turns: float) -> NDArray[np.float64]:
    """Two strands that wrap around each other symmetrically (a flat square knot's core)."""
    n = 200
    w = np.linspace(-1.0, 1.0, n)
    ang = math.pi * wrap_turns * w
    s1 = np.c_[w, 0.3 * np.cos(ang), 0.3 * np.sin(ang)]
    s2 = np.c_[w[::-1], -0.3 * np.cos(ang[::-1]), -0.3 * np.sin(ang[::-1])]
    lead_in = np.c_[np.linspace(-4, -1.05, 20), np.full(20, 0.3), np.zeros(20)]
    s = np.linspace(0.0, math.pi, 60)
    loop = np.c_[1.05 + 0.0 * s + 0.5 * np.sin(s), 0.3 * np.cos(s) * -1, -2.0 * np.sin(s)]
    lead_out = np.c_[np.linspace(-1.05, -4, 20), np.full(20, -0.3), np.full(20, 0.5)]
    return np.vstack([lead_in, s1, loop, s2, lead_out])


def test_symmetric_wrap_is_not_a_straight_post() -> None:
    geo = knot_geometry(
        _square_like(1.0), tissue_point=[0, 0, -2], tissue_normal=UP, region=([0, 0, 0], 1.0)
    )
    assert len(geo.straightness) == 2
    assert max(geo.straightness) < 0.9
    assert not geo.post_straight


def test_seated_uses_the_knot_centre_from_the_classifier() -> None:
    pts = curves.long_knot(curves.trefoil(120))
    report = classify_knot(pts)
    region = knot_region(report)
    assert region is not None
    centre, radius = region
    # every essential crossing lies within the region
    keep = set(report.essential)
    for c in report.crossing_list:
        if c.label in keep:
            assert np.linalg.norm(np.array(c.point) - centre) <= radius + 1e-12
    for offset, seated in ((0.0, True), (0.0009, True), (0.002, False), (-0.002, False)):
        plane_point = centre - offset * UP
        geo = knot_geometry(
            pts,
            tissue_point=plane_point,
            tissue_normal=UP * 3.0,
            seat_tolerance=1e-3,
            report=report,
        )
        assert geo.height == pytest.approx(offset, abs=1e-12)
        assert geo.seated is seated


def test_centre_moves_with_the_curve() -> None:
    pts = curves.long_knot(curves.trefoil(120))
    shift = np.array([0.3, -2.0, 5.0])
    a = knot_geometry(pts, tissue_point=[0, 0, 0], tissue_normal=UP)
    b = knot_geometry(pts + shift, tissue_point=[0, 0, 0], tissue_normal=UP)
    assert a.centre is not None and b.centre is not None
    np.testing.assert_allclose(np.array(b.centre) - np.array(a.centre), shift, atol=1e-9)
    assert b.height == pytest.approx(a.height + 5.0)  # type: ignore[operator]


def test_no_knot_no_centre() -> None:
    line = np.c_[np.linspace(0, 1, 20), np.zeros(20), np.zeros(20)]
    geo = knot_geometry(line, tissue_point=[0, 0, 0], tissue_normal=UP)
    assert geo.centre is None and not geo.seated and not geo.post_straight
    assert geo.to_dict()["centre"] is None


def test_knot_summary_is_json_ready_and_complete() -> None:
    import json

    pts = 0.001 * curves.square_knot()  # millimetre-sized
    summary = json.loads(
        json.dumps(knot_summary(pts, tissue_point=[0, 0, -0.05], tissue_normal=UP))
    )
    assert summary["type"] == "square"
    assert (summary["determinant"], summary["v2"], summary["v3"]) == (9, 2, 0)
    for key in ("seated", "post_straight", "height", "straightness", "alexander", "writhe"):
        assert key in summary
    assert summary["seated"] is False  # 5 cm above the plane
