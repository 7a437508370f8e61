"""The knot classifier on hand-built parametric curves, rotated and noisy.

The expected types come from how the curves are built (see
``suture_engine.suture.curves``), never from the classifier. The diagrams
the classifier reads are cross-checked against spherogram through their PD
code: spherogram's crossing signs, writhe and Seifert-matrix Alexander
polynomial must agree with ours.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from suture_engine.suture import curves
from suture_engine.suture.gauss_code import GaussCode
from suture_engine.suture.topology import (
    InvalidCenterline,
    KnotReport,
    classify_invariants,
    classify_knot,
    close_curve,
    project_gauss_code,
    simplify_polyline,
)

spherogram = pytest.importorskip("spherogram")

CASES = {
    # name: (curve, type, chirality, determinant, v2, v3)
    "right trefoil": (lambda: curves.trefoil(right=True), "trefoil", "right", 3, 1, 1),
    "left trefoil": (lambda: curves.trefoil(right=False), "trefoil", "left", 3, 1, -1),
    "figure-eight": (curves.figure_eight, "figure-eight", None, 5, -1, 0),
    "square": (curves.square_knot, "square", None, 9, 2, 0),
    "square, mirrored order": (
        lambda: curves.square_knot(right_first=False),
        "square",
        None,
        9,
        2,
        0,
    ),
    "right granny": (lambda: curves.granny_knot(right=True), "granny", "right", 9, 2, 2),
    "left granny": (lambda: curves.granny_knot(right=False), "granny", "left", 9, 2, -2),
    "right double overhand": (lambda: curves.overhand(2), "double-overhand", "right", 5, 3, 5),
    "left double overhand": (
        lambda: curves.overhand(2, right=False),
        "double-overhand",
        "left",
        5,
        3,
        -5,
    ),
    "surgeon's knot": (curves.surgeons_knot, "surgeons", "right", 15, 4, 4),
    "surgeon's knot, left first": (
        lambda: curves.surgeons_knot(right_first=False),
        "surgeons",
        "left",
        15,
        4,
        -4,
    ),
    "surgeon's granny": (
        lambda: curves.surgeons_knot(mirrored=False),
        "surgeons-granny",
        "right",
        15,
        4,
        6,
    ),
    "wobbly unknot": (curves.wobbly_unknot, "unknot", None, 1, 0, 0),
    "half hitches": (curves.half_hitches, "unknot", None, 1, 0, 0),
}


def _check(report: KnotReport, name: str) -> None:
    _, kind, chirality, det, v2, v3 = CASES[name]
    assert (report.type, report.chirality) == (kind, chirality), name
    assert (report.determinant, report.v2, report.v3) == (det, v2, v3), name
    assert report.agreement == 1.0


@pytest.mark.parametrize("name", sorted(CASES))
def test_parametric_curves(name: str) -> None:
    report = classify_knot(CASES[name][0]())
    _check(report, name)


def test_wobbly_unknot_really_has_many_projected_crossings() -> None:
    report = classify_knot(curves.wobbly_unknot())
    assert report.raw_crossings >= 10
    assert report.crossings == 0


@settings(max_examples=40, deadline=None)
@given(
    name=st.sampled_from(sorted(CASES)),
    rot_seed=st.integers(min_value=0, max_value=2**31 - 1),
    noise=st.floats(min_value=0.0, max_value=0.03),
    scale=st.floats(min_value=1e-3, max_value=10.0),
    seed=st.integers(min_value=0, max_value=1000),
)
def test_rigid_motions_noise_and_scale(
    name: str, rot_seed: int, noise: float, scale: float, seed: int
) -> None:
    pts = CASES[name][0]()
    rng = np.random.default_rng(rot_seed)
    rot = Rotation.random(random_state=rot_seed).as_matrix()
    moved = (pts + rng.normal(scale=noise, size=pts.shape)) @ rot.T
    moved = scale * moved + rng.normal(scale=5.0, size=3)
    _check(classify_knot(moved, seed=seed), name)


def test_reversed_orientation_keeps_the_knot() -> None:
    # knot type and chirality do not depend on the direction of travel
    for name in ("right trefoil", "right granny", "square"):
        _check(classify_knot(CASES[name][0]()[::-1]), name)


def test_mirror_image_flips_chirality() -> None:
    pts = curves.trefoil(right=True) * np.array([1.0, 1.0, -1.0])
    report = classify_knot(pts)
    assert (report.type, report.chirality, report.v3) == ("trefoil", "left", -1)


def test_duplicate_points_are_dropped() -> None:
    pts = curves.trefoil()
    doubled = np.repeat(pts, 3, axis=0)
    assert len(simplify_polyline(doubled)) == len(pts)
    _check(classify_knot(doubled), "right trefoil")


def test_same_seed_same_report() -> None:
    pts = curves.square_knot()
    a, b = classify_knot(pts, seed=4), classify_knot(pts, seed=4)
    assert a.direction == b.direction and a.gauss_code == b.gauss_code


def _pd_oracle(code: GaussCode) -> tuple[tuple[int, ...], int, list[int]]:
    """spherogram on our PD code: Alexander polynomial, writhe and crossing signs."""
    link = spherogram.Link(code.to_pd())
    signs = [c.sign for c in link.crossings]
    link_writhe = link.writhe()
    link.simplify("global")  # spherogram's own reduction keeps the Seifert matrix small
    if not link.crossings:
        return (1,), link_writhe, signs
    v = sympy.Matrix(link.seifert_matrix())
    t = sympy.Symbol("t")
    points = [(k, int((v - k * v.T).det(method="bareiss"))) for k in range(v.shape[0] + 1)]
    coeffs = [int(c) for c in reversed(sympy.Poly(sympy.interpolate(points, t), t).all_coeffs())]
    while coeffs[0] == 0:
        coeffs.pop(0)
    if sum(coeffs) < 0:
        coeffs = [-c for c in coeffs]
    return tuple(coeffs), link_writhe, signs


@pytest.mark.parametrize(
    "name",
    [
        "right trefoil",
        "left trefoil",
        "figure-eight",
        "square",
        "right double overhand",
        "surgeon's knot",
    ],
)
def test_projected_diagram_agrees_with_spherogram(name: str) -> None:
    report = classify_knot(CASES[name][0]())
    code = report.gauss_code  # the raw projection, before any reduction
    alex, link_writhe, signs = _pd_oracle(code)
    assert signs == [code.signs[lab] for lab in code.labels()]
    assert link_writhe == sum(c.sign for c in report.crossing_list)
    assert alex == report.alexander


def test_crossing_signs_follow_the_right_hand_rule() -> None:
    # Two straight strands seen from +z: the over strand (z = 1) runs along
    # +x, the under strand (z = 0) along +y. Rotating +x counterclockwise by
    # 90 deg gives +y, so the crossing is positive. Joined into a closed
    # polygon far away (the far edges add no crossing).
    closed = np.array(
        [
            [-1.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [3.0, -3.0, 0.5],
            [0.0, -1.0, 0.0],
            [0.0, 1.0, 0.0],
            [-3.0, 3.0, 0.5],
        ]
    )
    _, crossings = project_gauss_code(closed, [0.0, 0.0, 1.0])
    assert len(crossings) == 1
    assert crossings[0].sign == 1
    assert crossings[0].point == pytest.approx((0.0, 0.0, 0.5))
    _, crossings2 = project_gauss_code(closed * np.array([1.0, 1.0, -1.0]), [0.0, 0.0, 1.0])
    assert crossings2[0].sign == -1


def test_closure_reaches_far_and_keeps_the_suture_first() -> None:
    pts = curves.trefoil()
    closed, n = close_curve(pts, radius_factor=10.0)
    assert n == len(pts)
    np.testing.assert_allclose(closed[:n], pts)
    centre = pts.mean(axis=0)
    radius = np.max(np.linalg.norm(pts - centre, axis=1))
    far = np.linalg.norm(closed[n:] - centre, axis=1)
    np.testing.assert_allclose(far, 10.0 * radius)


def test_classify_invariants_table() -> None:
    assert classify_invariants((1,), 0, 0) == ("unknot", None)
    assert classify_invariants((1, -1, 1), 1, 1) == ("trefoil", "right")
    assert classify_invariants((1, -2, 3, -2, 1), 2, 0) == ("square", None)
    assert classify_invariants((1, -2, 3, -2, 1), 2, -2) == ("granny", "left")
    assert classify_invariants((2, -5, 2), -2, 1) == ("other", None)  # 6_1, det 9 too
    assert classify_invariants((1, -1, 1, -1, 1), 3, 5) == ("double-overhand", "right")
    assert classify_invariants((1, -1, 1, -1, 1), 3, 3) == ("other", None)
    assert classify_invariants((1, -2, 3, -3, 3, -2, 1), 4, -4) == ("surgeons", "left")
    assert classify_invariants((1, -2, 3, -3, 3, -2, 1), 4, 6) == ("surgeons-granny", "right")
    assert classify_invariants((1, -2, 3, -3, 3, -2, 1), 4, 2) == ("other", None)


def _torus_2(q: int, n: int = 200) -> NDArray[np.float64]:
    """The (2, q) torus knot, right-handed, cut open at its outermost point."""
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    r = 2.0 + np.cos(q * t)
    pts: NDArray[np.float64] = np.c_[r * np.cos(2 * t), r * np.sin(2 * t), -np.sin(q * t)]
    k = int(np.argmax(np.linalg.norm(pts[:, :2], axis=1)))
    return np.roll(pts, -k, axis=0)[1:]


def _v3_from_jones(coeffs: dict[int, int]) -> float:
    """v3 = -(V'''(1) + 3 V''(1)) / 36 from a Jones polynomial {power: coefficient}."""
    d2 = sum(c * k * (k - 1) for k, c in coeffs.items())
    d3 = sum(c * k * (k - 1) * (k - 2) for k, c in coeffs.items())
    return -(d3 + 3 * d2) / 36


def test_the_double_overhand_is_the_cinquefoil() -> None:
    # Oracles: the (2,5) torus knot built parametrically, and the knot table's values for
    # 5_1: Delta = t^4 - t^3 + t^2 - t + 1, Conway 1 + 3z^2 + z^4 (v2 = 3), and v3 from
    # its Jones polynomial (the formula gives +1 on the right trefoil's t + t^3 - t^4).
    assert _v3_from_jones({1: 1, 3: 1, 4: -1}) == 1
    right_cinquefoil_jones = {2: 1, 4: 1, 5: -1, 6: 1, 7: -1}
    for report in (classify_knot(_torus_2(5)), classify_knot(curves.overhand(2))):
        assert report.alexander == (1, -1, 1, -1, 1)
        assert report.v2 == 3
        assert report.v3 == _v3_from_jones(right_cinquefoil_jones) == 5
        assert (report.type, report.chirality) == ("double-overhand", "right")


def test_one_pass_of_the_end_is_the_trefoil() -> None:
    # the same construction with one pass: the overhand knot, same hand as curves.trefoil
    for right in (True, False):
        tied = classify_knot(curves.overhand(1, right=right))
        torus = classify_knot(curves.trefoil(right=right))
        assert (tied.type, tied.chirality, tied.v3) == (torus.type, torus.chirality, torus.v3)
    with pytest.raises(ValueError, match="turns"):
        curves.overhand(0)


def test_other_knots_are_other() -> None:
    report = classify_knot(_torus_2(7))  # 7_1
    assert report.type == "other"
    assert (report.determinant, report.v2, abs(report.v3)) == (7, 6, 14)


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((5, 2)),
        np.zeros(3),
        np.array([[0.0, 0.0, np.nan], [1.0, 0.0, 0.0]]),
        np.zeros((1, 3)),
        [["a", "b", "c"]],
    ],
)
def test_bad_input_is_a_typed_error(bad: object) -> None:
    with pytest.raises(InvalidCenterline):
        classify_knot(bad)  # type: ignore[arg-type]


def test_report_to_dict_is_json_ready() -> None:
    import json

    data = classify_knot(curves.square_knot()).to_dict()
    assert json.loads(json.dumps(data))["type"] == "square"
