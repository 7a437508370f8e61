"""Knot mechanics of placement and securing (thesis 4.5 and 7.1).

Angle conventions (thesis Figs. 4.12-4.14, symmetric case 4.21-4.23).
Work in the knot-tying plane spanned by ``u`` (in the tissue plane, along
the line from the entry point ``pa`` to the exit point ``pb``) and ``v``
(the tissue normal, pointing out of the tissue). Each suture strand crosses
the other inside the knot and has two legs:

- the *pulled* leg, from the knot towards the robot holding that end, at
  angle ``beta`` above the tissue plane, heading away from the side where the
  strand is anchored in the tissue;
- the *bridge* leg, from the knot down to its tissue point (pa or pb), at
  angle ``gamma`` below the tissue plane.

Free-body diagram of the knot with the two-point contact model (4.12-4.16),
strand tensions F_a on the pulled legs and F_b on the bridge legs:
``u: F1a cos b - F2a cos b - F1b cos g + F2b cos g = 0`` and
``v: 2 F_a sin b - (F1b + F2b) sin g = 0``, so ``F_b = F_a sin b / sin g``
(4.26). The normal forces at the two contact points of one strand are the
normal components ``F_a sin b`` and ``F_b sin g`` (4.27-4.28). Coulomb's law:
the strands slide over each other, and the knot moves down, when the
tangential pull exceeds friction,
``F_a cos b - F_b cos g > mu (F_a sin b + F_b sin g)`` (4.29); substituting
F_b and dividing by ``F_a sin b > 0`` gives

    1/tan(beta) - 1/tan(gamma) > 2 mu                      (4.30)

that is ``0 < beta < beta_max = atan(tan g / (1 + 2 mu tan g))`` (4.31).
The bridge tension ``F_a sin b / sin g`` grows with beta, so the
minimum-tension choice is the smallest admissible pulling angle
``beta = beta_min`` (4.40; the thesis takes beta_min = 0, pulling parallel
to the tissue).

The *lay* of a tied knot (:func:`knot_lay`, :func:`post_straight`): with opposite
pulls on its two throws a square knot lies as two interlocked bights, both strands
turning inside the knot; with the second throw pulled the wrong way (7.4) one strand
is pulled straight and the other is wound round it, two half hitches (Fig. 7.4),
which slide. It is judged from the centerline where the suture touches itself.
"""

from __future__ import annotations

import math
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from suture_engine.arithmetic import arcsin, cos, sin
from suture_engine.errors import SutureError

__all__ = [
    "KnotLay",
    "PlacementError",
    "PlacementInfeasible",
    "PlacementTrajectory",
    "ThrowDirections",
    "beta_max",
    "bridge_tension",
    "knot_lay",
    "placement_error",
    "placement_trajectory",
    "post_straight",
    "securing_directions",
    "sliding_condition",
]


class PlacementInfeasible(SutureError):
    """The knot cannot slide with the requested pulling angle.

    Attributes:
        beta: requested pulling angle [rad].
        beta_max: largest angle that still slides at that point [rad].
        height: knot height above the tissue where it fails [m].
    """

    code = "placement-infeasible"

    def __init__(self, beta: float, beta_max: float, height: float) -> None:
        super().__init__(
            f"pulling angle {math.degrees(beta):.2f} deg exceeds the sliding limit "
            f"{math.degrees(beta_max):.2f} deg at knot height {height * 1e3:.2f} mm (4.31)"
        )
        self.beta = beta
        self.beta_max = beta_max
        self.height = height


def _check_angle(name: str, value: float) -> None:
    if not (0.0 < value < math.pi / 2):
        raise ValueError(f"{name} must lie in (0, pi/2) rad, got {value!r}")


def sliding_condition(beta: float, gamma: float, mu: float) -> bool:
    """Whether symmetric pulling slides the knot towards the tissue (4.30).

    Args:
        beta: angle of the pulled legs above the tissue plane [rad], in
            (0, pi/2).
        gamma: angle of the bridge legs below the tissue plane [rad], in
            (0, pi/2).
        mu: suture-suture friction coefficient [-], >= 0.

    Returns:
        True when ``1/tan(beta) - 1/tan(gamma) > 2 mu``.
    """
    _check_angle("beta", beta)
    _check_angle("gamma", gamma)
    if mu < 0:
        raise ValueError(f"mu must be >= 0, got {mu!r}")
    return 1.0 / math.tan(beta) - 1.0 / math.tan(gamma) > 2.0 * mu


def beta_max(gamma: float, mu: float) -> float:
    """Largest pulling angle that still slides the knot (4.31) [rad].

    Args:
        gamma: bridge-leg angle below the tissue plane [rad], in [0, pi/2).
        mu: suture-suture friction coefficient [-], >= 0.
    """
    if not (0.0 <= gamma < math.pi / 2) or mu < 0:
        raise ValueError(f"need 0 <= gamma < pi/2 and mu >= 0, got {gamma!r}, {mu!r}")
    tg = math.tan(gamma)
    return math.atan(tg / (1.0 + 2.0 * mu * tg))


def bridge_tension(applied: float, beta: float, gamma: float) -> float:
    """Tension in the bridge legs, ``F_b = F_a sin(beta) / sin(gamma)`` (4.26) [N].

    Args:
        applied: tension applied at each pulled leg F_a [N].
        beta: pulled-leg angle [rad].
        gamma: bridge-leg angle [rad], > 0.
    """
    return applied * math.sin(beta) / math.sin(gamma)


class PlacementTrajectory(NamedTuple):
    """Suture-end trajectories that slide a knot down the tissue normal (4.36-4.40).

    Attributes:
        time: sample times [s], shape (T,).
        knot: knot position p_n(t) [m], (T, 3) (4.36).
        height: knot height above the tissue plane [m], (T,).
        gamma: bridge-leg angles [rad], (T, 2), strand 1 (anchored at the
            entry point) and strand 2 (anchored at the exit point) (4.38).
        beta: pulling angles used [rad], (T, 2).
        beta_max: sliding limits (4.31) [rad], (T, 2).
        delta: bridge-leg shortening since t = 0 [m], (T, 2) (4.37).
        end1: end of strand 1 p_1e(t) [m], (T, 3) (4.39).
        end2: end of strand 2 p_2e(t) [m], (T, 3).
        tension_ratio: bridge tension per applied tension F_b/F_a [-], (T, 2).
    """

    time: NDArray[np.float64]
    knot: NDArray[np.float64]
    height: NDArray[np.float64]
    gamma: NDArray[np.float64]
    beta: NDArray[np.float64]
    beta_max: NDArray[np.float64]
    delta: NDArray[np.float64]
    end1: NDArray[np.float64]
    end2: NDArray[np.float64]
    tension_ratio: NDArray[np.float64]


def _unit(v: NDArray[np.float64], what: str) -> NDArray[np.float64]:
    n = float(np.linalg.norm(v))
    if n < 1e-12:
        raise ValueError(f"{what} has zero length")
    return v / n


def placement_trajectory(
    entry: ArrayLike,
    exit: ArrayLike,
    knot_start: ArrayLike,
    normal: ArrayLike,
    *,
    rate: float,
    mu: float,
    lengths: tuple[float, float],
    beta_min: float = 0.0,
    beta: float | Literal["max"] | None = None,
    max_margin: float = 0.95,
    seat_height: float = 0.0,
    dt: float = 0.01,
) -> PlacementTrajectory:
    """End trajectories that move the knot straight down the tissue normal.

    The knot follows ``p_n(t) = p_n0 + s t xi`` with ``xi = -normal``
    (4.36) until its height above the tissue is ``seat_height``. Each strand
    keeps its length (4.32-4.35): the bridge leg to its tissue point shortens
    by ``delta_i(t) = |p_n0 - a_i| - |p_n(t) - a_i|`` (4.37), so the pulled
    leg lengthens by the same amount. The end of strand i is placed on the
    ray from the knot at angle ``beta`` above the tissue, heading away from
    its anchor: ``p_ie(t) = p_n(t) + (L_i + delta_i(t))(cos(beta) u_i +
    sin(beta) v)`` (4.39); with ``beta = beta_min = 0`` this is
    ``p_ie0 + delta_i u_i + s t xi`` (4.40), the minimum-tension choice.

    Args:
        entry: tissue entry point p_a [m], the anchor of strand 1.
        exit: tissue exit point p_b [m], the anchor of strand 2.
        knot_start: initial knot position p_n0 [m] (above the tissue).
        normal: tissue normal, pointing out of the tissue (any length).
        rate: sliding rate s [m/s], > 0.
        mu: suture-suture friction coefficient [-].
        lengths: pulled-leg lengths L_1, L_2 at t = 0 (knot to grasp) [m].
        beta_min: smallest pulling angle allowed [rad] (>= 0).
        beta: pulling angle to use [rad]; default ``beta_min`` (4.40);
            ``"max"`` follows ``max_margin * beta_max(gamma(t))``, the
            steepest pull that still slides (the other curve of Fig. 4.19).
        max_margin: fraction of beta_max used when ``beta="max"``.
        seat_height: knot height where placement stops [m].
        dt: sample period [s].

    Returns:
        the :class:`PlacementTrajectory`.

    Raises:
        PlacementInfeasible: ``beta`` exceeds beta_max(gamma(t)) (4.31)
            somewhere on the way (the knot would stick).
        ValueError: inconsistent geometry or non-positive rate.
    """
    pa = np.asarray(entry, dtype=float)
    pb = np.asarray(exit, dtype=float)
    p0 = np.asarray(knot_start, dtype=float)
    n = _unit(np.asarray(normal, dtype=float), "normal")
    if rate <= 0 or dt <= 0:
        raise ValueError("rate and dt must be > 0")
    if beta_min < 0:
        raise ValueError("beta_min must be >= 0")
    follow_max = beta == "max"
    use_beta = beta_min if beta is None or follow_max else float(beta)
    if use_beta < beta_min:
        raise ValueError(f"beta {use_beta!r} below beta_min {beta_min!r}")
    if follow_max and not (0.0 < max_margin < 1.0):
        raise ValueError(f"max_margin must lie in (0, 1), got {max_margin!r}")
    plane_pt = 0.5 * (pa + pb)
    h0 = float((p0 - plane_pt) @ n)
    if h0 <= seat_height:
        raise ValueError(f"knot height {h0!r} m is not above the seat height {seat_height!r} m")
    across = pb - pa
    u1 = _unit(across - (across @ n) * n, "entry-exit line in the tissue plane")
    dirs = (u1, -u1)
    anchors = (pa, pb)
    duration = (h0 - seat_height) / rate
    steps = max(1, math.ceil(duration / dt - 1e-9))
    time = np.linspace(0.0, duration, steps + 1)
    knot = p0[None, :] - (rate * time)[:, None] * n[None, :]
    height = h0 - rate * time
    gamma = np.empty((len(time), 2))
    bmax = np.empty_like(gamma)
    delta = np.empty_like(gamma)
    dists = []
    for i, a in enumerate(anchors):
        leg = a[None, :] - knot
        dist = np.linalg.norm(leg, axis=1)
        gamma[:, i] = arcsin(np.clip(-(leg @ n) / dist, -1.0, 1.0))
        bmax[:, i] = [beta_max(max(g, 0.0), mu) for g in gamma[:, i]]
        delta[:, i] = dist[0] - dist
        dists.append(dist)
    if follow_max:
        betas = np.maximum(max_margin * bmax, beta_min)
    else:
        betas = np.full_like(gamma, use_beta)
    if np.any(betas > 0):
        bad = np.argwhere((betas > 0) & (betas >= bmax))
        if len(bad):
            k, i = bad[0]
            raise PlacementInfeasible(float(betas[k, i]), float(bmax[k, i]), float(height[k]))
    ends = []
    for i, u in enumerate(dirs):
        ray = cos(betas[:, i])[:, None] * u[None, :] + sin(betas[:, i])[:, None] * n[None, :]
        ends.append(knot + (lengths[i] + delta[:, i])[:, None] * ray)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(gamma > 0, sin(betas) / sin(gamma), np.inf)
    return PlacementTrajectory(
        time=time,
        knot=knot,
        height=height,
        gamma=gamma,
        beta=betas,
        beta_max=bmax,
        delta=delta,
        end1=ends[0],
        end2=ends[1],
        tension_ratio=ratio,
    )


class ThrowDirections(NamedTuple):
    """Securing directions of one throw of a square knot (7.1-7.3).

    Attributes:
        throw: throw index i_T (1, 2, ...).
        loop_end: unit direction e_l to pull the loop end (the stitcher,
            whose strand leaves the tissue at the exit point p_b).
        post_end: unit direction e_p to pull the post end (the grasper,
            strand at the entry point p_a).
    """

    throw: int
    loop_end: NDArray[np.float64]
    post_end: NDArray[np.float64]


def securing_directions(
    entry: ArrayLike, exit: ArrayLike, throw: int, *, normal: ArrayLike | None = None
) -> ThrowDirections:
    """Square-knot direction rule: throws are pulled in alternating directions.

    With h_a, h_b the unit vectors from the suturing line towards the entry
    point p_a and the exit point p_b (h_a = -h_b), the rule is
    ``e_l(i) . h_b = (-1)^i`` and ``e_p(i) . h_a = (-1)^i`` (7.3): on the
    first throw the loop end is pulled towards p_a and the post end towards
    p_b (7.1); on the second throw the other way round (7.2). Pulling the
    second throw like the first turns the knot into two half hitches (7.4,
    Fig. 7.4).

    Args:
        entry: entry point p_a [m].
        exit: exit point p_b [m].
        throw: throw index i_T >= 1.
        normal: tissue normal; when given, h_a and h_b are projected into
            the tissue plane.

    Returns:
        the :class:`ThrowDirections`.
    """
    if throw < 1:
        raise ValueError(f"throw index must be >= 1, got {throw!r}")
    pa = np.asarray(entry, dtype=float)
    pb = np.asarray(exit, dtype=float)
    hb = pb - pa
    if normal is not None:
        nn = _unit(np.asarray(normal, dtype=float), "normal")
        hb = hb - (hb @ nn) * nn
    hb = _unit(hb, "entry-exit line")
    ha = -hb
    sign = -1.0 if throw % 2 else 1.0
    return ThrowDirections(throw=throw, loop_end=sign * hb, post_end=sign * ha)


class PlacementError(NamedTuple):
    """How far a knot ended from where it should sit (4.5.1).

    Attributes:
        height: knot height above the tissue plane [m] (0 when seated).
        lateral: distance from the seat point p_0 within the tissue plane [m].
        total: distance from p_0 [m].
    """

    height: float
    lateral: float
    total: float


def placement_error(
    knot: ArrayLike, entry: ArrayLike, exit: ArrayLike, normal: ArrayLike
) -> PlacementError:
    """Knot placement error relative to the seat point p_0 = (p_a + p_b) / 2.

    Args:
        knot: knot position p_n [m].
        entry: entry point p_a [m].
        exit: exit point p_b [m].
        normal: tissue normal (out of the tissue).
    """
    n = _unit(np.asarray(normal, dtype=float), "normal")
    seat = 0.5 * (np.asarray(entry, dtype=float) + np.asarray(exit, dtype=float))
    d = np.asarray(knot, dtype=float) - seat
    height = float(d @ n)
    lateral = float(np.linalg.norm(d - height * n))
    return PlacementError(height=height, lateral=lateral, total=float(np.linalg.norm(d)))


# ------------------------------------------------------------ knot lay (Fig. 7.4)


class KnotLay(NamedTuple):
    """How two tied strands lie in their knot: square lay or two half hitches (Fig. 7.4).

    The knot is where the suture touches itself: segment pairs whose axes come within
    the contact distance, and that are farther apart along the suture than that (so
    a tight bend does not count). The stitch loop (through the tissue) is the longest
    stretch between two touching segments; it separates strand 1 (from the first
    point) from strand 2. Each strand's *knot zone* runs along it from its first to
    its last contact point (the closest point of its first touching segment to the
    segments it touches, and likewise at the end), and its straightness is chord /
    arc length over that zone (1 = straight).

    - ``"square"``: both strands turn inside the knot (straightness below the
      threshold): each is a bight round the other, as in a square (or granny) knot
      laid with opposite pulls.
    - ``"half-hitches"``: one strand runs straight through the knot and the other is
      wrapped round it: a square knot capsized by pulling the second throw the wrong
      way (7.4, Fig. 7.4). It slides along the straight strand.
    - ``"undetermined"``: both strands straight (they only touch side by side).
    - ``"no-knot"``: the strands do not touch, or only one stretch touches.

    Attributes:
        lay: one of the four above.
        post_straight: the run summary's field: True for the square lay, False for
            two half hitches, None otherwise. (The issue's wording: the post stays
            straight in a square knot and is bent round the other strand in two
            half hitches. Geometrically, in two half hitches one strand, called
            ``straight_strand`` here, is straight and the other wraps it.)
        straightness: chord / arc over each strand's knot zone [-], strand 1 first;
            empty for ``"no-knot"``.
        straight_strand: 1 or 2 for two half hitches (the strand that is straight),
            else None.
        zones: each strand's knot zone as (first, last) segment index.
        contact_distance: the contact distance used [m].
    """

    lay: Literal["square", "half-hitches", "undetermined", "no-knot"]
    post_straight: bool | None
    straightness: tuple[float, ...]
    straight_strand: int | None
    zones: tuple[tuple[int, int], ...]
    contact_distance: float


def _segment_distances(
    p0: NDArray[np.float64],
    p1: NDArray[np.float64],
    q0: NDArray[np.float64],
    q1: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Distances between segments [p0, p1] and [q0, q1], broadcast over leading axes [m]."""
    return _segment_closest(p0, p1, q0, q1)[0]


def _segment_closest(
    p0: NDArray[np.float64],
    p1: NDArray[np.float64],
    q0: NDArray[np.float64],
    q1: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Distance [m] and closest-point parameters s, t in [0, 1] of two segments.

    Closest points of two segments: minimise ``|p0 + s d1 - q0 - t d2|`` over
    s, t in [0, 1] (clamp s, solve t, clamp t, re-solve s).
    """
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a = np.einsum("...k,...k->...", d1, d1)
    e = np.einsum("...k,...k->...", d2, d2)
    f = np.einsum("...k,...k->...", d2, r)
    c = np.einsum("...k,...k->...", d1, r)
    b = np.einsum("...k,...k->...", d1, d2)
    tiny = 1e-300
    a_ok, e_ok = a > tiny, e > tiny
    denom = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(
            denom > 1e-12 * a * e,
            np.clip((b * f - c * e) / np.where(denom > 0, denom, 1), 0, 1),
            0.0,
        )
        s = np.where(e_ok, s, np.clip(-c / np.where(a_ok, a, 1), 0, 1))  # q a point
        t = np.where(e_ok, (b * s + f) / np.where(e_ok, e, 1), 0.0)
        s_lo = np.clip(-c / np.where(a_ok, a, 1), 0, 1)
        s_hi = np.clip((b - c) / np.where(a_ok, a, 1), 0, 1)
        s = np.where(t < 0, s_lo, np.where(t > 1, s_hi, s))
        t = np.clip(t, 0, 1)
        s = np.where(a_ok, s, 0.0)  # p a point
        t = np.where(a_ok, t, np.clip(f / np.where(e_ok, e, 1), 0, 1))
    gap = r + s[..., None] * d1 - t[..., None] * d2
    return np.asarray(np.linalg.norm(gap, axis=-1), dtype=np.float64), s, t


def knot_lay(
    points: ArrayLike,
    *,
    diameter: float,
    contact_factor: float = 1.5,
    straight_threshold: float = 0.9,
) -> KnotLay:
    """Square lay or two half hitches, from the suture's centerline (Fig. 7.4).

    Meant for the ground-truth centerline of a stitch tied off: strand 1 from the
    first point to the tissue, the stitch loop, strand 2 from the tissue to the last
    point, the two strands knotted round each other (see :class:`KnotLay` for the
    definition). Scale-free apart from the contact distance, invariant under rigid
    motions and under reversing the point order (which swaps the strands).

    Args:
        points: N x 3 centerline [m], N >= 2.
        diameter: suture diameter [m] (the simulator's contact diameter for a
            simulated thread): axes of touching strands are about this far apart.
        contact_factor: contact distance / diameter [-].
        straight_threshold: straightness at or above which a strand is straight [-].

    Returns:
        the :class:`KnotLay`.

    Raises:
        ValueError: bad points or non-positive diameter.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2 or not np.all(np.isfinite(pts)):
        raise ValueError(f"points must be a finite N x 3 array with N >= 2, got {pts.shape}")
    if not (diameter > 0 and contact_factor > 0):
        raise ValueError("diameter and contact_factor must be > 0")
    contact = contact_factor * diameter
    seg_len = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    keep = np.concatenate([[True], seg_len > 1e-12 * max(float(seg_len.max()), 1e-300)])
    pts = pts[keep]
    seg_len = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg_len)])
    mid = 0.5 * (arc[:-1] + arc[1:])
    a0, a1 = pts[:-1], pts[1:]
    dist, par, _ = _segment_closest(a0[:, None, :], a1[:, None, :], a0[None, :, :], a1[None, :, :])
    # farther apart along the suture than a half turn round a neighbour (pi x contact)
    apart = np.abs(mid[:, None] - mid[None, :]) - 0.5 * (seg_len[:, None] + seg_len[None, :])
    pairs = (dist < contact) & (apart > math.pi * contact)
    touching = np.any(pairs, axis=1)
    idx = np.flatnonzero(touching)
    none = KnotLay("no-knot", None, (), None, (), contact)
    if len(idx) < 2:
        return none
    gaps = arc[idx[1:]] - arc[idx[:-1] + 1]
    k = int(np.argmax(gaps))
    if gaps[k] <= 0:
        return none
    zones = ((int(idx[0]), int(idx[k])), (int(idx[k + 1]), int(idx[-1])))
    straight: list[float] = []
    for first, last in zones:
        # from the first segment's earliest closest point to the last one's latest
        s0 = float(np.min(par[first][pairs[first]]))
        s1 = float(np.max(par[last][pairs[last]]))
        start = pts[first] + s0 * (pts[first + 1] - pts[first])
        end = pts[last] + s1 * (pts[last + 1] - pts[last])
        length = float(arc[last] + s1 * seg_len[last] - arc[first] - s0 * seg_len[first])
        chord = float(np.linalg.norm(end - start))
        straight.append(chord / length if length > 0 else 1.0)
    is_straight = [s >= straight_threshold for s in straight]
    if all(is_straight):
        lay: Literal["square", "half-hitches", "undetermined", "no-knot"] = "undetermined"
        post, which = None, None
    elif any(is_straight):
        lay, post, which = "half-hitches", False, 1 + is_straight.index(True)
    else:
        lay, post, which = "square", True, None
    return KnotLay(lay, post, tuple(straight), which, zones, contact)


def post_straight(
    points: ArrayLike,
    *,
    diameter: float,
    contact_factor: float = 1.5,
    straight_threshold: float = 0.9,
) -> bool | None:
    """The run summary's ``post_straight``: True for a square lay, False for two half hitches.

    ``knot_lay(...).post_straight`` (see :class:`KnotLay`): None when the strands form
    no knot or the lay is undetermined.

    Args:
        points: N x 3 centerline [m].
        diameter: suture (contact) diameter [m].
        contact_factor: contact distance / diameter [-].
        straight_threshold: straightness at or above which a strand is straight [-].
    """
    return knot_lay(
        points,
        diameter=diameter,
        contact_factor=contact_factor,
        straight_threshold=straight_threshold,
    ).post_straight
