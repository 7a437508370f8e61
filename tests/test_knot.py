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
    placement_error,
    placement_trajectory,
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


@settings(max_examples=200, deadline=None)
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
