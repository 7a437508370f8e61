"""Knot placement mechanics (thesis 4.5) and the square-knot direction rule (7.1-7.3).

Oracles: the force balance of the two-point contact model solved
numerically (a 2 x 2 linear system for the bridge tensions, then Coulomb's
law at the contacts); root finding for the sliding limit; brute force over
beta for the minimum tension; scipy's fsolve for the knot position implied
by the length-invariant constraints (4.34-4.35).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq, fsolve

from suture_engine.suture.knot import (
    PlacementInfeasible,
    beta_max,
    bridge_tension,
    knot_lay,
    placement_error,
    placement_trajectory,
    post_straight,
    securing_directions,
    sliding_condition,
)


def force_balance(beta: float, gamma: float, applied: float = 1.0) -> tuple[float, float]:
    """Bridge tensions (F1b, F2b) from the knot's equilibrium (4.12), solved numerically."""
    e1a = np.array([math.cos(beta), math.sin(beta)])
    e2a = np.array([-math.cos(beta), math.sin(beta)])
    e1b = np.array([-math.cos(gamma), -math.sin(gamma)])
    e2b = np.array([math.cos(gamma), -math.sin(gamma)])
    rhs = -(applied * e1a + applied * e2a)
    f1b, f2b = np.linalg.solve(np.column_stack([e1b, e2b]), rhs)
    return float(f1b), float(f2b)


def slide_margin(beta: float, gamma: float, mu: float) -> float:
    """Tangential pull minus Coulomb friction on strand 1 (4.19-4.20) [N per N applied]."""
    f1b, _ = force_balance(beta, gamma)
    pull = np.array([math.cos(beta), math.sin(beta)])
    bridge = f1b * np.array([-math.cos(gamma), -math.sin(gamma)])
    e_t, e_n = np.array([1.0, 0.0]), np.array([0.0, 1.0])
    tangential = (pull + bridge) @ e_t
    normal = abs(pull @ e_n) + abs(bridge @ e_n)
    return float(tangential - mu * normal)


angles = st.floats(min_value=0.02, max_value=math.pi / 2 - 0.02)
frictions = st.floats(min_value=0.0, max_value=1.5)


@settings(max_examples=300, deadline=None)
@given(angles, angles, frictions)
def test_sliding_condition_matches_the_numeric_force_balance(
    beta: float, gamma: float, mu: float
) -> None:
    margin = slide_margin(beta, gamma, mu)
    if abs(margin) < 1e-9:
        return  # on the boundary either answer is right
    assert sliding_condition(beta, gamma, mu) == (margin > 0)


@settings(max_examples=100, deadline=None)
@given(st.floats(min_value=0.05, max_value=1.5), frictions)
def test_beta_max_is_the_root_of_the_force_balance(gamma: float, mu: float) -> None:
    if mu < 1e-6:
        # no friction: sliding for every beta below gamma
        assert beta_max(gamma, mu) == pytest.approx(gamma)
        return
    root = brentq(lambda b: slide_margin(b, gamma, mu), 1e-9, gamma - 1e-12, xtol=1e-14)
    assert beta_max(gamma, mu) == pytest.approx(root, abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(angles, angles)
def test_bridge_tension_matches_the_linear_solve(beta: float, gamma: float) -> None:
    f1b, f2b = force_balance(beta, gamma, applied=2.5)
    assert f1b == pytest.approx(f2b, rel=1e-9)
    assert bridge_tension(2.5, beta, gamma) == pytest.approx(f1b, rel=1e-9)


@pytest.mark.parametrize("gamma", [0.2, 0.6, 1.2])
@pytest.mark.parametrize("beta_min", [0.0, 0.05])
def test_beta_min_minimises_the_bridge_tension(gamma: float, beta_min: float) -> None:
    mu = 0.3
    grid = np.linspace(beta_min, beta_max(gamma, mu), 400)[1:-1] if beta_min == 0 else None
    if grid is None:
        grid = np.linspace(beta_min, beta_max(gamma, mu), 400)[:-1]
    feasible = [b for b in grid if b == 0 or slide_margin(b, gamma, mu) > 0]
    tensions = [force_balance(b, gamma)[0] for b in feasible]
    best = feasible[int(np.argmin(tensions))]
    assert best == pytest.approx(grid[0])
    # the trajectory generator uses that minimum by default (4.40); with
    # beta_min > 0 it can only go down to where beta_max(gamma) = beta_min
    t = math.tan(beta_min)
    h_crit = 0.005 * t / (1 - 2 * mu * t)
    traj = placement_trajectory(
        [-0.005, 0, 0],
        [0.005, 0, 0],
        [0, 0, 0.005 * math.tan(gamma)],
        [0, 0, 1],
        rate=1e-3,
        mu=mu,
        lengths=(0.03, 0.03),
        beta_min=beta_min,
        seat_height=max(1e-4, 1.05 * h_crit),
    )
    assert np.all(traj.beta == beta_min)


def test_bad_arguments() -> None:
    with pytest.raises(ValueError):
        sliding_condition(0.0, 0.5, 0.2)
    with pytest.raises(ValueError):
        sliding_condition(0.3, math.pi / 2, 0.2)
    with pytest.raises(ValueError):
        sliding_condition(0.3, 0.5, -0.1)


# ------------------------------------------------------------- trajectories

PA = np.array([0.01, -0.004, 0.002])
PB = np.array([0.01, 0.006, 0.002])
NORMAL = np.array([0.0, 0.0, 1.0])
KNOT0 = 0.5 * (PA + PB) + 0.012 * NORMAL


def _traj(beta: float | str | None = None, **kw: float) -> object:
    args: dict = dict(rate=0.004, mu=0.3, lengths=(0.025, 0.03), dt=0.01)
    args.update(kw)
    return placement_trajectory(PA, PB, KNOT0, NORMAL, beta=beta, **args)


def test_knot_moves_down_the_normal_at_the_sliding_rate() -> None:
    tr = _traj()
    np.testing.assert_allclose(tr.knot, KNOT0 - np.outer(0.004 * tr.time, NORMAL))  # (4.36)
    assert tr.height[-1] == pytest.approx(0.0, abs=1e-12)
    assert tr.time[-1] == pytest.approx(0.012 / 0.004)
    half = np.linalg.norm(PB - PA) / 2
    np.testing.assert_allclose(tr.gamma[:, 0], np.arctan2(tr.height, half), atol=1e-12)  # (4.38)


@pytest.mark.parametrize("beta", [None, 0.1, 0.2, "max"])
def test_strand_lengths_are_invariant(beta: float | str | None) -> None:
    tr = _traj(beta, seat_height=0.004)
    for end, anchor, length in ((tr.end1, PA, 0.025), (tr.end2, PB, 0.03)):
        total = np.linalg.norm(end - tr.knot, axis=1) + np.linalg.norm(tr.knot - anchor, axis=1)
        np.testing.assert_allclose(total, length + np.linalg.norm(KNOT0 - anchor), rtol=1e-12)


def test_minimum_tension_trajectory_is_4_40() -> None:
    tr = _traj()
    u = (PB - PA) / np.linalg.norm(PB - PA)
    xi = -NORMAL
    expected = tr.end1[0] + np.outer(tr.delta[:, 0], u) + np.outer(0.004 * tr.time, xi)
    np.testing.assert_allclose(tr.end1, expected, atol=1e-15)
    np.testing.assert_allclose(tr.tension_ratio[:-1], 0.0)


@pytest.mark.parametrize("beta", [0.0, 0.15, "max"])
def test_knot_position_follows_from_the_ends(beta: float | str) -> None:
    """Solve (4.34)-(4.35) for q given the end trajectories; it must be p_n(t)."""
    tr = _traj(beta, seat_height=0.005)
    c1 = 0.025 + np.linalg.norm(KNOT0 - PA)
    c2 = 0.03 + np.linalg.norm(KNOT0 - PB)
    u = (PB - PA) / np.linalg.norm(PB - PA)
    origin = 0.5 * (PA + PB)
    for k in range(0, len(tr.time), 50):

        def residual(x: np.ndarray, k: int = k) -> list[float]:
            q = origin + x[0] * u + x[1] * NORMAL
            return [
                float(np.linalg.norm(tr.end1[k] - q) + np.linalg.norm(q - PA) - c1),
                float(np.linalg.norm(tr.end2[k] - q) + np.linalg.norm(q - PB) - c2),
            ]

        guess = np.array([0.0005, tr.height[k] + 0.0005])
        x = fsolve(residual, guess, xtol=1e-13)
        np.testing.assert_allclose(origin + x[0] * u + x[1] * NORMAL, tr.knot[k], atol=1e-9)


def test_steep_pull_sticks_near_the_tissue() -> None:
    beta, mu = 0.2, 0.4
    half = np.linalg.norm(PB - PA) / 2
    # beta = beta_max(gamma)  <=>  tan(gamma) = tan(beta) / (1 - 2 mu tan(beta))
    h_crit = half * math.tan(beta) / (1 - 2 * mu * math.tan(beta))
    _traj(beta, mu=mu, seat_height=h_crit * 1.01)
    with pytest.raises(PlacementInfeasible) as err:
        _traj(beta, mu=mu, seat_height=h_crit * 0.95)
    assert err.value.height <= h_crit * 1.0 + 1e-12
    assert err.value.beta == beta


def test_placement_rejects_bad_geometry() -> None:
    with pytest.raises(ValueError):
        placement_trajectory(
            PA,
            PB,
            0.5 * (PA + PB) - 0.001 * NORMAL,
            NORMAL,
            rate=0.01,
            mu=0.3,
            lengths=(0.02, 0.02),
        )
    with pytest.raises(ValueError):
        placement_trajectory(PA, PB, KNOT0, NORMAL, rate=0.0, mu=0.3, lengths=(0.02, 0.02))


# ------------------------------------------------------- direction rule


@settings(max_examples=50, deadline=None)
@given(
    st.lists(st.floats(min_value=-0.05, max_value=0.05), min_size=6, max_size=6),
    st.integers(min_value=1, max_value=5),
)
def test_square_knot_direction_rule_7_3(coords: list[float], throw: int) -> None:
    pa, pb = np.array(coords[:3]), np.array(coords[3:]) + np.array([0.02, 0.0, 0.0])
    # B: where the suturing line (the wound, midway between the bites) meets p_a-p_b
    b = 0.5 * (pa + pb)
    h_a = (pa - b) / np.linalg.norm(pa - b)
    h_b = (pb - b) / np.linalg.norm(pb - b)
    d = securing_directions(pa, pb, throw)
    assert d.loop_end @ h_b == pytest.approx((-1) ** throw)
    assert d.post_end @ h_a == pytest.approx((-1) ** throw)
    assert np.linalg.norm(d.loop_end) == pytest.approx(1.0)


def test_first_and_second_throw_are_opposite() -> None:
    pa, pb = [0.0, 0.0, 0.0], [0.01, 0.0, 0.0]
    first, second = securing_directions(pa, pb, 1), securing_directions(pa, pb, 2)
    np.testing.assert_allclose(first.loop_end, [-1.0, 0.0, 0.0])  # stitcher towards p_a (7.1)
    np.testing.assert_allclose(first.post_end, [1.0, 0.0, 0.0])  # grasper towards p_b
    np.testing.assert_allclose(second.loop_end, -first.loop_end)  # (7.2)
    np.testing.assert_allclose(second.post_end, -first.post_end)


def test_directions_stay_in_the_tissue_plane() -> None:
    d = securing_directions([0.0, 0.0, 0.0], [0.01, 0.0, 0.004], 1, normal=[0.0, 0.0, 1.0])
    np.testing.assert_allclose(d.loop_end, [-1.0, 0.0, 0.0], atol=1e-15)
    with pytest.raises(ValueError):
        securing_directions([0, 0, 0], [1, 0, 0], 0)


def test_steepest_sliding_pull_costs_more_tension() -> None:
    """Fig. 4.19: beta = beta_max(t) against beta = 0; the latter has less bridge tension."""
    steep, flat = _traj("max", seat_height=0.001), _traj(None, seat_height=0.001)
    assert np.all(steep.beta < steep.beta_max)
    assert np.all(steep.tension_ratio > flat.tension_ratio)
    for k in range(0, len(steep.time), 25):
        for i in range(2):
            b, g = float(steep.beta[k, i]), float(steep.gamma[k, i])
            assert slide_margin(b, g, 0.3) > 0  # still slides, by the force balance


def test_placement_error_components() -> None:
    seat = 0.5 * (PA + PB)
    u = (PB - PA) / np.linalg.norm(PB - PA)
    err = placement_error(seat + 0.002 * NORMAL + 0.0015 * u, PA, PB, 2.0 * NORMAL)
    assert err.height == pytest.approx(0.002)
    assert err.lateral == pytest.approx(0.0015)
    assert err.total == pytest.approx(0.0025)


# ------------------------------------------- sliding as a friction LP (scipy)


def sticks_by_lp(beta: float, gamma: float, mu: float) -> bool:
    """Whether the knot can stay put: a static-friction feasibility LP (scipy's HiGHS).

    Unknowns: the bridge tensions F1b, F2b and the friction forces phi_a, phi_b of
    strand 1 at its two contacts (along u). Equalities: the knot's force balance in u
    and v (4.15-4.16, F1a = F2a = 1) and strand 1's balance along u. Coulomb only
    resists the pull towards the tissue: phi >= -mu N with N the contact's normal
    force (the leg's normal component, F1a sin(beta) and F1b sin(gamma)); sliding
    the other way does not count as placement. Infeasible: the knot slides down.
    No closed form of (4.30) is used.
    """
    from scipy.optimize import linprog

    cb, sb, cg, sg = math.cos(beta), math.sin(beta), math.cos(gamma), math.sin(gamma)
    # x = [F1b, F2b, phi_a, phi_b]
    a_eq = [
        [-cg, cg, 0.0, 0.0],  # u: cb - cb - F1b cg + F2b cg = 0
        [-sg, -sg, 0.0, 0.0],  # v: sb + sb - (F1b + F2b) sg = 0
        [-cg, 0.0, 1.0, 1.0],  # strand 1 along u: cb - F1b cg + phi_a + phi_b = 0
    ]
    b_eq = [0.0, -2.0 * sb, -cb]
    a_ub = [[-mu * sg, 0.0, 0.0, -1.0]]  # -phi_b <= mu F1b sg
    b_ub = [0.0]
    bounds = [(0.0, None), (0.0, None), (-mu * sb, None), (None, None)]
    res = linprog(np.zeros(4), A_ub=a_ub, b_ub=b_ub, A_eq=a_eq, b_eq=b_eq, bounds=bounds)
    assert res.status in (0, 2), res.message  # 0 feasible, 2 infeasible
    return bool(res.status == 0)


@settings(max_examples=80, deadline=None)
@given(angles, angles, frictions)
def test_sliding_condition_matches_the_friction_lp(beta: float, gamma: float, mu: float) -> None:
    lo, hi = sticks_by_lp(beta, gamma, mu * (1 - 1e-6)), sticks_by_lp(beta, gamma, mu * (1 + 1e-6))
    if lo != hi:
        return  # on the boundary (to 1 ppm in mu) either answer is right
    assert sliding_condition(beta, gamma, mu) == (not lo)


def test_friction_lp_has_both_outcomes() -> None:
    """The oracle is not trivially one-sided: flat pulls slide, steep ones stick."""
    assert not sticks_by_lp(0.05, 0.8, 0.3)
    assert sticks_by_lp(0.7, 0.8, 0.3)
    assert sticks_by_lp(0.3, 0.31, 0.0) is False  # frictionless: slides while beta < gamma
    assert sticks_by_lp(0.32, 0.31, 0.0)


# --------------------------------------------------- knot lay (Fig. 7.4)
#
# Hand-built two-strand centerlines [mm]: strand 1 from the tail end to the tissue,
# a stitch loop below, strand 2 from the tissue to the needle end. Suture diameter
# 1 mm: where two strands cross, their axes are 1 mm apart (they touch).

DIA = 1.0


def _leg(x0: float, x1: float, yfun: object, n: int) -> np.ndarray:
    xs = np.linspace(x0, x1, n)
    return np.column_stack([xs, yfun(xs)])  # type: ignore[operator]


def _arc(cx: float, cy: float, r: float, t0: float, t1: float, n: int = 40) -> np.ndarray:
    t = np.linspace(t0, t1, n)
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


def _bights_xy() -> tuple[np.ndarray, np.ndarray]:
    """Two interlocked bights in the plane: strand 1's bend at +x, strand 2's at -x.

    Strand 1's legs run at y = +-a(x), a from 1 (x <= -3) to 2 (x >= 3); strand 2's at
    y = +-b(x), b from 2 (x <= -3) to 1 (x >= 3); the bends are half circles of radius
    2 centred at (+-3, 0). Six projected crossings: each bend over the other's legs,
    the legs over each other at x = 0.
    """

    def a(x: np.ndarray) -> np.ndarray:
        return np.clip(1.5 + x / 6.0, 1.0, 2.0)

    def b(x: np.ndarray) -> np.ndarray:
        return np.clip(1.5 - x / 6.0, 1.0, 2.0)

    s1 = np.vstack(
        [
            _leg(-20, 3, a, 90),
            _arc(3, 0, 2, math.pi / 2, -math.pi / 2)[1:-1],
            _leg(3, -12, lambda x: -a(x), 60),
        ]
    )
    s2 = np.vstack(
        [
            _leg(12, -3, lambda x: -b(x), 60),
            _arc(-3, 0, 2, -math.pi / 2, -3 * math.pi / 2)[1:-1],
            _leg(-3, 20, b, 90),
        ]
    )
    return s1, s2


def _projected_crossings(p: np.ndarray, q: np.ndarray) -> list[tuple[float, float]]:
    """Fractional indices (along p, along q) where the xy projections of p and q cross."""
    d1 = (p[1:] - p[:-1])[:, None, :]  # (n, 1, 2)
    d2 = (q[1:] - q[:-1])[None, :, :]  # (1, m, 2)
    r = q[:-1][None, :, :] - p[:-1][:, None, :]  # (n, m, 2)

    def cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    den = cross(d1, d2)
    ok = np.abs(den) > 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(ok, cross(r, d2) / den, -1.0)
        t = np.where(ok, cross(r, d1) / den, -1.0)
    hit = (s >= 0) & (s < 1) & (t >= 0) & (t < 1)
    return [(i + s[i, j], j + t[i, j]) for i, j in zip(*np.nonzero(hit), strict=True)]


def _lift(p: np.ndarray, q: np.ndarray, over: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Heights: at the k-th crossing along p, p at +over[k] D/2 and q at -over[k] D/2."""
    crossings = _projected_crossings(p, q)
    assert len(crossings) == len(over)

    def heights(n: int, knots: list[tuple[float, float]]) -> np.ndarray:
        knots = sorted(knots)
        u = [0.0, *(k for k, _ in knots), n - 1.0]
        return np.interp(np.arange(n), u, [0.0, *(z for _, z in knots), 0.0])

    zp = heights(len(p), [(s, o * DIA / 2) for (s, _), o in zip(crossings, over, strict=True)])
    zq = heights(len(q), [(t, -o * DIA / 2) for (_, t), o in zip(crossings, over, strict=True)])
    return np.column_stack([p, zp]), np.column_stack([q, zq])


def _stitch_loop(end1: np.ndarray, start2: np.ndarray) -> np.ndarray:
    """The thread through the tissue, well below and beside the knot, from end1's side."""
    loop = np.array([(-14.0, -6.0, -4.0), (0.0, -8.0, -6.0), (14.0, -6.0, -4.0)])
    assert end1[0] * start2[0] < 0
    return loop if end1[0] < 0 else loop[::-1]


def _join(s1: np.ndarray, s2: np.ndarray) -> np.ndarray:
    return np.vstack([s1, _stitch_loop(s1[-1], s2[0]), s2])


SQUARE_OVER = (1, -1, 1, 1, -1, 1)
GRANNY_OVER = (1, -1, 1, -1, 1, -1)


def square_lay(over: tuple[int, ...] = SQUARE_OVER) -> np.ndarray:
    """Square knot laid flat: two interlocked bights (the reef knot's drawing) [mm]."""
    return _join(*_lift(*_bights_xy(), over))


def half_hitches_lay(turns: float = 2.0, pitch: float = 2.5) -> np.ndarray:
    """Strand 1 a straight post along x; strand 2 wound ``turns`` times round it [mm].

    The winding is a helix of radius D about the post's axis (touching it), entered from
    below-left and left towards the needle end at the right.
    """
    post = _leg(-20, 10, lambda x: 0.0 * x, 120)
    post = np.column_stack([post, np.zeros(len(post))])
    x0 = -pitch * turns / 2
    t = np.linspace(0.0, 1.0, int(60 * turns) + 1)
    helix = np.column_stack(
        [
            x0 + pitch * turns * t,
            -DIA * np.cos(2 * math.pi * turns * t),
            DIA * np.sin(2 * math.pi * turns * t),
        ]
    )
    approach = np.array([(-10.0, -6.0, -1.0), (x0 - 2.0, -3.0, 0.0)])
    leave = np.array([(helix[-1, 0] + 3.0, -4.0, 0.0), (20.0, -8.0, 0.0)])
    return np.vstack([post, _stitch_loop(post[-1], approach[0]), approach, helix, leave])


def test_hand_built_lays_have_the_intended_topology() -> None:
    """The test curves are what they claim: the classifier (closure far away) agrees."""
    from suture_engine.suture.topology import classify_knot

    assert classify_knot(square_lay() * 1e-3).type == "square"
    assert classify_knot(square_lay(GRANNY_OVER) * 1e-3).type == "granny"


@pytest.mark.parametrize("over", [SQUARE_OVER, GRANNY_OVER])
def test_square_lay_keeps_both_strands_bent(over: tuple[int, ...]) -> None:
    lay = knot_lay(square_lay(over) * 1e-3, diameter=DIA * 1e-3)
    assert lay.lay == "square"
    assert lay.post_straight is True
    assert post_straight(square_lay(over) * 1e-3, diameter=DIA * 1e-3) is True
    assert lay.straight_strand is None
    # each bight: chord = the leg spacing at its far crossing (2 mm), arc ~ 20 mm
    assert max(lay.straightness) < 0.3
    (_, a1), (b0, _) = lay.zones
    assert a1 < b0  # strand 1's zone ends before strand 2's begins


@pytest.mark.parametrize("turns", [1.0, 2.0, 3.0])
def test_half_hitches_straighten_one_strand(turns: float) -> None:
    pts = half_hitches_lay(turns) * 1e-3
    lay = knot_lay(pts, diameter=DIA * 1e-3)
    assert lay.lay == "half-hitches"
    assert lay.post_straight is False
    assert post_straight(pts, diameter=DIA * 1e-3) is False
    assert lay.straight_strand == 1
    assert lay.straightness[0] > 0.99
    # the wound strand's zone is the helix: chord / arc = pitch / sqrt((2 pi D)^2 + pitch^2)
    assert lay.straightness[1] == pytest.approx(2.5 / math.hypot(2 * math.pi * DIA, 2.5), abs=0.01)


def test_lay_is_invariant_under_rigid_motion_scale_and_reversal() -> None:
    from scipy.spatial.transform import Rotation

    rot = Rotation.from_euler("xyz", [0.3, -1.1, 2.0]).as_matrix()
    for pts, expected in ((square_lay(), "square"), (half_hitches_lay(), "half-hitches")):
        moved = 7.0 * pts @ rot.T + np.array([0.1, -2.0, 5.0])
        lay = knot_lay(moved, diameter=7.0 * DIA)
        ref = knot_lay(pts, diameter=DIA)
        assert lay.lay == expected
        np.testing.assert_allclose(lay.straightness, ref.straightness, rtol=1e-9)
        back = knot_lay(pts[::-1], diameter=DIA)
        assert back.lay == expected
        np.testing.assert_allclose(back.straightness, ref.straightness[::-1], rtol=1e-9)
        if expected == "half-hitches":
            assert back.straight_strand == 2


def test_lay_does_not_depend_on_the_sampling() -> None:
    """Twice as many points on the same curve: same lay, close straightness.

    A zone ends at closest points, which move a little with the sampling of a curve.
    """
    for pts in (square_lay(), half_hitches_lay()):
        fine = np.empty((2 * len(pts) - 1, 3))
        fine[0::2] = pts
        fine[1::2] = 0.5 * (pts[1:] + pts[:-1])
        a, b = knot_lay(pts, diameter=DIA), knot_lay(fine, diameter=DIA)
        assert a.lay == b.lay
        np.testing.assert_allclose(a.straightness, b.straightness, atol=0.01)


def test_strands_that_do_not_touch_are_no_knot() -> None:
    s1, s2 = _bights_xy()
    far = np.column_stack([s2, np.full(len(s2), 5.0)])  # 5 mm above strand 1
    pts = _join(np.column_stack([s1, np.zeros(len(s1))]), far)
    lay = knot_lay(pts, diameter=DIA)
    assert lay.lay == "no-knot" and lay.post_straight is None
    assert post_straight(pts, diameter=DIA) is None


def test_strands_side_by_side_are_undetermined() -> None:
    """Two straight strands touching along a stretch: no knot shape to judge."""
    s1 = np.column_stack([np.linspace(-20, 10, 60), np.zeros(60), np.zeros(60)])
    s2 = np.column_stack([np.linspace(8, -10, 60), np.full(60, DIA), np.zeros(60)])
    loop = np.array([(14.0, -6.0, -4.0), (12.0, 6.0, 6.0), (8.0, DIA, 0.0)])
    lay = knot_lay(np.vstack([s1, loop, s2]), diameter=DIA)
    assert lay.lay == "undetermined"
    assert lay.post_straight is None
    assert min(lay.straightness) > 0.99


def test_tight_bend_alone_is_not_a_contact() -> None:
    """A single hairpin of radius D touches nothing but itself near the bend."""
    hairpin = np.vstack(
        [
            _leg(-20, 0, lambda x: 0.0 * x + DIA, 40),
            _arc(0, 0, DIA, math.pi / 2, -math.pi / 2, 20)[1:-1],
            _leg(0, -20, lambda x: 0.0 * x - DIA, 40),
        ]
    )
    pts = np.column_stack([hairpin, np.zeros(len(hairpin))])
    # legs 2 D apart: not touching at 1.5 D contact distance
    assert knot_lay(pts, diameter=DIA).lay == "no-knot"


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(min_value=-1.0, max_value=1.0), min_size=12, max_size=12))
def test_segment_distance_matches_dense_sampling(c: list[float]) -> None:
    from suture_engine.suture.knot import _segment_distances

    p0, p1, q0, q1 = (np.array(c[3 * k : 3 * k + 3]) for k in range(4))
    got = float(_segment_distances(p0, p1, q0, q1))
    s = np.linspace(0.0, 1.0, 201)
    ps = p0 + s[:, None] * (p1 - p0)
    qs = q0 + s[:, None] * (q1 - q0)
    brute = float(np.min(np.linalg.norm(ps[:, None, :] - qs[None, :, :], axis=-1)))
    length = float(np.linalg.norm(p1 - p0) + np.linalg.norm(q1 - q0))
    assert got <= brute + 1e-9
    assert got >= brute - length / 200 - 1e-9  # the grid's resolution


def test_knot_lay_bad_arguments() -> None:
    with pytest.raises(ValueError):
        knot_lay(np.zeros((1, 3)), diameter=1e-3)
    with pytest.raises(ValueError):
        knot_lay(square_lay(), diameter=0.0)
    with pytest.raises(ValueError):
        knot_lay(np.full((4, 3), np.nan), diameter=1e-3)
