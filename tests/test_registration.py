"""Touch registration of a robot's base (suture_engine/robot/registration.py).

Oracles: the closest points by a dense grid refined with scipy's bounded minimiser, and
touches synthesised from a base displaced by a known error (true distances computed
directly, not through the first-order model the estimator uses).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from suture_engine.robot.registration import (
    Touch,
    estimate_offset,
    segment_closest,
    shaft_segment,
)

R1 = np.array([-0.07, -0.05, 0.12])
R2 = np.array([0.07, -0.05, 0.12])


def _brute(p0, p1, q0, q1):
    """min |p(s) - q(t)| over the unit square: a 201 x 201 grid, then L-BFGS-B from its best."""
    grid = np.linspace(0.0, 1.0, 201)
    pts_p = p0 + np.outer(grid, p1 - p0)
    pts_q = q0 + np.outer(grid, q1 - q0)
    dist = np.linalg.norm(pts_p[:, None, :] - pts_q[None, :, :], axis=2)
    i, j = np.unravel_index(np.argmin(dist), dist.shape)

    def f(x):
        return float(np.sum((p0 + x[0] * (p1 - p0) - q0 - x[1] * (q1 - q0)) ** 2))

    res = minimize(f, [grid[i], grid[j]], bounds=[(0, 1), (0, 1)], method="L-BFGS-B", tol=1e-16)
    return float(np.sqrt(res.fun)), res.x


@pytest.mark.parametrize("seed", range(40))
def test_closest_points_agree_with_a_brute_force_search(seed):
    rng = np.random.default_rng(seed)
    p0, p1, q0, q1 = (rng.uniform(-0.05, 0.05, 3) for _ in range(4))
    if seed % 4 == 0:  # parallel segments, offset sideways
        side = np.array([0.0, 0.01, 0.0])
        q0, q1 = p0 + side, p1 + side + 0.5 * (p1 - p0)
    got = segment_closest(p0, p1, q0, q1)
    want, _ = _brute(p0, p1, q0, q1)
    assert got.distance == pytest.approx(want, abs=1e-9)
    a = p0 + got.s * (p1 - p0)
    b = q0 + got.t * (q1 - q0)
    # the normal points from the second segment's point to the first's
    np.testing.assert_allclose(b + got.distance * got.normal, a, atol=1e-12)


def test_crossing_segments_have_no_normal():
    got = segment_closest([-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0])
    assert got.distance == 0.0
    assert np.all(got.normal == 0.0)


def test_the_shaft_lies_on_the_line_to_the_rcm():
    tip = np.array([0.01, 0.0, 0.03])
    a, b = shaft_segment(R1, tip, 0.006, 0.1)
    axis = (R1 - tip) / np.linalg.norm(R1 - tip)
    np.testing.assert_allclose(a, tip + 0.006 * axis)
    np.testing.assert_allclose(b, tip + 0.1 * axis)


def _post_touches(e, crossings, rng):
    """Touches synthesised exactly: a shaft from an RCM displaced by ``e`` rests against a
    vertical post (or over its top) at each crossing; the model sees the declared RCM and
    the same tip displacement undone (the joints are what the robot measures)."""
    touches = []
    for point, top in crossings:
        foot = point - np.array([0.0, 0.0, 0.0 if not top else 0.04])
        post = (foot, foot + np.array([0.0, 0.0, 0.04]))
        z = np.array([0.0, 0.0, 1.0])
        u = (point - R1) / np.linalg.norm(point - R1)
        n = np.cross(z, u) if not top else z - (z @ u) * u
        n /= np.linalg.norm(n)
        # the true shaft touches the post: its axis passes 5 mm from the post's axis
        axis_true = point + 0.005 * n
        tip_true = axis_true + 0.03 * (axis_true - (R1 + e)) / np.linalg.norm(axis_true - R1 - e)
        true = segment_closest(*shaft_segment(R1 + e, tip_true, 0.006, 0.3), *post)
        # the robot measures its joints; the model puts the tip where the declared base does
        model = shaft_segment(R1, tip_true - e, 0.006, 0.3)
        touches.append(Touch(model, post, true.distance))
    return touches


CROSSINGS = [
    (np.array([-0.03, -0.05, 0.036]), False),
    (np.array([-0.02, 0.04, 0.036]), False),
    (np.array([-0.02, 0.04, 0.042]), True),
]


@pytest.mark.parametrize("seed", range(10))
def test_post_touches_recover_the_base_error(seed):
    rng = np.random.default_rng(seed)
    e = rng.normal(0.0, 1e-3, 3)
    touches = _post_touches(e, CROSSINGS, rng)
    # a touch's gap known to 0.02 mm: the prior's pull stays well under that
    est = estimate_offset(touches, sigma=1e-3, noise=2e-5)
    np.testing.assert_allclose(est.offset, e, atol=2e-5)
    # exact gaps and a negligible prior: the Gauss-Newton steps converge on the error
    exact = estimate_offset(touches, sigma=1e-3, noise=1e-8)
    np.testing.assert_allclose(exact.offset, e, atol=1e-8)
    assert exact.residual < 1e-10
    assert est.observed[-1] > 0.3  # the layout sees every direction


def test_shafts_see_nothing_along_the_line_between_their_rcms():
    # two shafts that meet: the normal between their axes is square to both lines through
    # the RCM points, hence to the line joining those points (why posts are needed)
    rng = np.random.default_rng(3)
    for _ in range(20):
        c = np.array([rng.uniform(-0.02, 0.02), rng.uniform(-0.05, 0.04), rng.uniform(0.03, 0.08)])
        a = shaft_segment(R1, c + 0.02 * (c - R1) / np.linalg.norm(c - R1), 0.006, 0.3)
        side = np.cross(c - R1, c - R2)
        side /= np.linalg.norm(side)
        b0 = c + 1e-4 * side
        b = shaft_segment(R2, b0 + 0.02 * (b0 - R2) / np.linalg.norm(b0 - R2), 0.006, 0.3)
        n = segment_closest(*a, *b).normal
        assert abs(n @ (R2 - R1)) / np.linalg.norm(R2 - R1) < 0.01


def _line_touch(n, gap):
    """A long shaft parallel to a long post, ``n`` from it, ``gap`` short of contact."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    along = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    along /= np.linalg.norm(along)
    post = (-along, along)
    shaft = (0.01 * n - 0.5 * along, 0.01 * n + 0.5 * along)
    return Touch(shaft, post, 0.01 + gap)


def test_one_touch_moves_the_estimate_only_along_its_normal():
    n = np.array([0.0, 0.6, 0.8])
    est = estimate_offset([_line_touch(n, 1e-3)], sigma=1e-3, noise=1e-5)
    np.testing.assert_allclose(np.cross(est.offset, n), 0.0, atol=1e-12)
    # the prior pulls it in a little: gap / (1 + noise^2 / sigma^2)
    assert est.offset @ n == pytest.approx(1e-3 / (1 + 1e-10 / 1e-6), rel=1e-9)


@pytest.mark.parametrize(
    ("touches", "sigma", "noise", "match"),
    [
        ([], 1e-3, 1e-5, "at least one"),
        ([_line_touch([0, 1.0, 0], 0.0)], 0.0, 1e-5, "positive"),
    ],
)
def test_bad_arguments_are_refused(touches, sigma, noise, match):
    with pytest.raises(ValueError, match=match):
        estimate_offset(touches, sigma, noise)
