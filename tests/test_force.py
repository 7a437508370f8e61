"""The Routh bound of PI force control (7.29, 7.33, 7.41, 7.43) against independent oracles."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.interpolate import pade

from suture_engine.control.force import ForceGainError, integral_gain_bound


def _max_real_part_no_delay(m: float, b: float, k: float, kp: float, kv: float, ki: float) -> float:
    """Closed-loop poles of m s^3 + (b+Kv) s^2 + k(1+Kp) s + k Ki (7.32), by numpy.roots."""
    return float(np.max(np.roots([m, b + kv, k * (1 + kp), k * ki]).real))


def _max_real_part_pade(
    m: float, b: float, k: float, kp: float, kv: float, ki: float, delay: float, order: int
) -> float:
    """Poles of the loop with the delay e^{-sT} replaced by a Padé (order, order) approximant.

    Characteristic equation: (m s^3 + (b+Kv) s^2 + k s) Q(s) + k (Kp s + Ki) P(s) = 0,
    with e^{-sT} ~ P(s)/Q(s). Independent of the closed form under test.
    """
    taylor = [(-delay) ** i / math.factorial(i) for i in range(2 * order + 1)]
    p, q = pade(taylor, order)
    plant = np.polymul([m, b + kv, k, 0.0], q.coeffs)
    control = np.polymul([k * kp, k * ki], p.coeffs)
    return float(np.max(np.roots(np.polyadd(plant, control)).real))


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({"kp": 1.0}, 2.0),  # thesis Fig. 7.13: Ki < 2
        ({"kp": 10.0}, 11.0),  # Fig. 7.14
        ({"kp": 1.0, "kv": 1000.0}, 2002.0),  # Fig. 7.16
    ],
)
def test_bound_without_delay_matches_the_thesis(kwargs: dict[str, float], expected: float) -> None:
    assert integral_gain_bound(1.0, 1.0, 10.0, **kwargs) == pytest.approx(expected, rel=1e-12)


def test_bound_with_a_2ms_delay_is_about_8_79() -> None:
    bound = integral_gain_bound(1.0, 1.0, 10.0, 10.0, delay=0.002)
    assert bound == pytest.approx(8.79, abs=0.01)
    # the thesis reads 8.82 off its root locus (Fig. 7.18)
    assert abs(bound - 8.82) < 0.05


@pytest.mark.parametrize(
    ("m", "b", "k", "kp", "kv"),
    [
        (1, 1, 10, 1, 0),
        (1, 1, 10, 10, 0),
        (1, 1, 10, 1, 1000),
        (0.5, 3, 200, 0.2, 2000),
        (2, 0, 5, 4, 7),
    ],
)
def test_roots_cross_the_imaginary_axis_at_the_bound(
    m: float, b: float, k: float, kp: float, kv: float
) -> None:
    bound = integral_gain_bound(m, b, k, kp, kv)
    assert _max_real_part_no_delay(m, b, k, kp, kv, 0.99 * bound) < 0
    assert _max_real_part_no_delay(m, b, k, kp, kv, 1.01 * bound) > 0


@pytest.mark.filterwarnings("ignore::scipy.linalg.LinAlgWarning")
@pytest.mark.parametrize("order", [1, 2, 3])
def test_delayed_bound_agrees_with_pade_approximants(order: int) -> None:
    m, b, k, kp, delay = 1.0, 1.0, 10.0, 10.0, 0.002
    bound = integral_gain_bound(m, b, k, kp, delay=delay)
    # bisect the Padé loop's own stability limit
    lo, hi = 1.0, 11.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if _max_real_part_pade(m, b, k, kp, 0.0, mid, delay, order) < 0:
            lo = mid
        else:
            hi = mid
    # the first-order closed form (7.41) is within 1e-4 of the Padé limit and not above it
    assert bound == pytest.approx(lo, rel=1e-4)
    assert bound <= lo + 1e-9


@pytest.mark.filterwarnings("ignore::scipy.linalg.LinAlgWarning")
def test_delayed_bound_with_active_damping_against_pade() -> None:
    m, b, k, kp, kv, delay = 1.0, 1.0, 10.0, 10.0, 1000.0, 0.002
    bound = integral_gain_bound(m, b, k, kp, kv, delay)
    assert _max_real_part_pade(m, b, k, kp, kv, 0.98 * bound, delay, 3) < 0
    assert _max_real_part_pade(m, b, k, kp, kv, 1.05 * bound, delay, 3) > 0


def test_no_stable_ki_when_the_delay_eats_the_damping() -> None:
    # (7.40 i): Kp < (b + Kv) / (k T); here (1 + 0) / (10 * 0.002) = 50
    assert integral_gain_bound(1.0, 1.0, 10.0, 60.0, delay=0.002) == 0.0


@pytest.mark.parametrize(
    "args",
    [(0.0, 1, 10, 1), (1, -1, 10, 1), (1, 1, 0, 1), (1, 1, 10, -1), (1, 1, 10, float("nan"))],
)
def test_bad_arguments_raise_a_typed_error(args: tuple[float, ...]) -> None:
    with pytest.raises(ForceGainError) as info:
        integral_gain_bound(*args)
    assert info.value.code == "bad-value"
