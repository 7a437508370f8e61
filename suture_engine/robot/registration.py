"""Registration of a robot's base by touch: its calibration error from contacts with posts.

The skills place the tools through the scene's declared base poses, so a calibration
error of a base moves every target of that robot by the error. The thesis calibrated the
bases with a 3D digitizer (Fig. 4.31) and asks for a more automatic method in its closing
chapter. This module estimates a base's error from touches: the robot brings its shaft
against a rigid post the scene declares, a guarded move stops at contact, and the joints
measured there say where the model puts the shaft.

Geometry. An instrument's shaft is a cylinder of radius ``r`` on the line through its RCM
point (the base origin) and its tool tip. A post is a capsule of radius ``r_p`` about a
segment. With the declared base, the model's shaft axis and the post's axis are ``d``
apart, ``n`` the unit vector from the post's closest point to the shaft's. If the true
base is the declared one displaced by ``e`` (a translation), the true distance is, to
first order, ``d + n . e``; at contact it is ``r + r_p``. Each touch measures

    n . e = r + r_p - d.

Touches whose normals span space determine ``e``. The least-squares solve is regularised
by the prior on ``e`` (:func:`estimate_offset`), so a direction the touches hardly see
stays near the declared value instead of following the noise; it is repeated about each
estimate (Gauss-Newton), since at a post's top the distance is to a point and the first
order model is off by about ``|e|^2 / 2d``.

Why posts and not the other robot's shaft: each shaft's axis passes through its own RCM
point, so the normal between two shafts that (nearly) meet is (nearly) square to the line
joining the RCM points; shaft-on-shaft touches cannot see the robots' relative error along
that line. A post's axis passes through neither.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Closest",
    "Estimate",
    "Touch",
    "estimate_offset",
    "segment_closest",
    "shaft_segment",
]

FloatArray = NDArray[np.float64]


class Closest(NamedTuple):
    """The closest points of two segments.

    Attributes:
        distance: between the closest points [m].
        normal: unit vector from the second segment's closest point to the first's (zero
            when the segments meet).
        s: the first segment's parameter at its closest point, in [0, 1].
        t: the second segment's parameter, in [0, 1].
    """

    distance: float
    normal: FloatArray
    s: float
    t: float


def segment_closest(
    p0: Sequence[float] | FloatArray,
    p1: Sequence[float] | FloatArray,
    q0: Sequence[float] | FloatArray,
    q1: Sequence[float] | FloatArray,
) -> Closest:
    """Closest points of segments ``p0-p1`` and ``q0-q1`` [m].

    The points ``p0 + s d1`` and ``q0 + t d2`` minimise ``|r + s d1 - t d2|^2``
    (``r = p0 - q0``) over ``s, t`` in [0, 1]: the unconstrained stationary point with
    ``s`` clamped, then ``t`` for that ``s``; a ``t`` outside [0, 1] is clamped and
    ``s`` re-optimised for it (parallel segments start from ``s = 0``). Segments that
    meet have no normal: it is then zero.
    """
    a0, a1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    b0, b1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a, e, f = float(d1 @ d1), float(d2 @ d2), float(d2 @ r)
    c, b = float(d1 @ r), float(d1 @ d2)
    denom = a * e - b * b
    s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > 1e-18 * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0 or t > 1.0:
        t = min(max(t, 0.0), 1.0)
        s = min(max((b * t - c) / a, 0.0), 1.0)
    gap = a0 + s * d1 - b0 - t * d2
    distance = float(np.linalg.norm(gap))
    normal = gap / distance if distance > 0.0 else np.zeros(3)
    return Closest(distance, normal, s, t)


def shaft_segment(
    rcm: Sequence[float] | FloatArray,
    tip: Sequence[float] | FloatArray,
    bare: float,
    length: float,
) -> tuple[FloatArray, FloatArray]:
    """The shaft's axis as a segment in the world frame [m].

    Args:
        rcm: the RCM point (the base origin) [m].
        tip: the tool tip [m].
        bare: how far behind the tip the shaft's surface starts [m] (the jaws).
        length: the shaft's length behind the tip [m].

    Returns:
        The segment's ends: ``bare`` and ``length`` behind the tip, on the line to the RCM.
    """
    rcm_, tip_ = np.asarray(rcm, float), np.asarray(tip, float)
    axis = rcm_ - tip_
    axis = axis / np.linalg.norm(axis)
    return tip_ + bare * axis, tip_ + length * axis


class Touch(NamedTuple):
    """One contact of a shaft with a post, as the model (the declared base) sees it.

    Attributes:
        shaft: the shaft's axis segment from the measured joints and the declared base [m].
        post: the post's axis segment [m].
        contact: the distance between the axes at contact: the two radii [m].
    """

    shaft: tuple[FloatArray, FloatArray]
    post: tuple[FloatArray, FloatArray]
    contact: float

    def at(self, offset: FloatArray) -> tuple[FloatArray, float]:
        """The normal and the gap ``contact - d`` with the base displaced by ``offset`` [m]
        (the whole shaft moves with the base: the joints are what was measured)."""
        a, b = self.shaft
        closest = segment_closest(a + offset, b + offset, *self.post)
        return closest.normal, self.contact - closest.distance


class Estimate(NamedTuple):
    """The estimated base error of one robot.

    Attributes:
        offset: the displacement of the true base from the declared one [m], world frame.
        residual: RMS of the touches' residuals after the fit [m].
        observed: the singular values of the touches' normals [-]: how well each direction
            is seen (near 0: hardly).
    """

    offset: FloatArray
    residual: float
    observed: FloatArray


def estimate_offset(
    touches: Sequence[Touch], sigma: float, noise: float, iterations: int = 5
) -> Estimate:
    """A base's error from touches, with a Gaussian prior.

    Minimises ``sum (contact_i - d_i(e))^2 / noise^2 + |e|^2 / sigma^2`` (the posterior
    mode for independent Gaussian gaps and a zero-mean prior of spread ``sigma``) by
    Gauss-Newton: ``d_i`` is linearised about the current estimate (``n_i . e``, exact
    for a line against a line, first order where a post's top is a point), solved, and
    linearised again.

    Args:
        touches: at least one.
        sigma: the prior spread of each component of the base's error [m], > 0.
        noise: the spread of one touch's gap [m], > 0.
        iterations: Gauss-Newton steps (the first is the plain linear solve).

    Raises:
        ValueError: no touches, or a spread that is not positive.
    """
    if not touches:
        raise ValueError("registration needs at least one touch")
    if not (sigma > 0.0 and noise > 0.0):
        raise ValueError(f"sigma and noise must be positive (got {sigma}, {noise})")
    offset = np.zeros(3)
    for _ in range(max(1, iterations)):
        rows = [t.at(offset) for t in touches]
        a = np.array([n for n, _ in rows], dtype=float)
        b = np.array([gap + n @ offset for n, gap in rows], dtype=float)
        lhs = a.T @ a / noise**2 + np.eye(3) / sigma**2
        offset = np.linalg.solve(lhs, a.T @ b / noise**2)
    rows = [t.at(offset) for t in touches]
    residual = float(np.sqrt(np.mean([gap**2 for _, gap in rows])))
    observed = np.linalg.svd(np.array([n for n, _ in rows]), compute_uv=False)
    return Estimate(offset, residual, observed)
