"""Velocity filters: measured frequency response against scipy.signal's oracle."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from suture_engine.control.filters import (
    FilterParameterError,
    NumericalDifferentiator,
    WashoutFilter,
)

DT = 0.001
POLE = 100.0


def _measured_response(filt: WashoutFilter | NumericalDifferentiator, w: float) -> complex:
    """Drive the filter with sin(w t) and fit the steady-state output's complex gain."""
    n_periods = 30
    n = int(np.ceil(n_periods * 2 * np.pi / (w * DT)))
    t = np.arange(n) * DT
    out = np.empty(n)
    for k in range(n):
        out[k] = filt.update(np.array([np.sin(w * t[k])]))[0]
    keep = t > t[-1] / 2  # transient gone (filter time constant 10 ms)
    basis = np.column_stack([np.sin(w * t[keep]), np.cos(w * t[keep])])
    (a, b), *_ = np.linalg.lstsq(basis, out[keep], rcond=None)
    return complex(a, b)  # |H| sin(wt + phase) = Re(H) sin(wt) + Im(H) cos(wt)


@pytest.mark.parametrize("w", [2.0, 20.0, 100.0, 400.0, 1500.0])
def test_washout_matches_scipy_backward_difference_discretisation(w: float) -> None:
    # Oracle: scipy discretises the continuous washout s/(s/p+1) = p s/(s+p) itself.
    numd, dend, _ = signal.cont2discrete(([POLE, 0.0], [1.0, POLE]), DT, method="backward_diff")
    _, h = signal.freqz(np.ravel(numd), np.ravel(dend), worN=[w * DT])
    measured = _measured_response(WashoutFilter(POLE, DT, n=1), w)
    assert measured == pytest.approx(complex(h[0]), rel=2e-3, abs=1e-6)


def test_washout_is_a_differentiator_at_low_frequency_and_flat_above_pole() -> None:
    # Continuous-time oracle: |s/(s/p+1)| ~ w for w << p and ~ p for w >> p (Fig. 5.6).
    low = _measured_response(WashoutFilter(POLE, DT, n=1), 1.0)
    assert low == pytest.approx(1j * 1.0 / (1j * 1.0 / POLE + 1), rel=2e-2)
    _, cont = signal.freqs([POLE, 0.0], [1.0, POLE], worN=[1.0, 1000.0])
    assert abs(low) == pytest.approx(abs(cont[0]), rel=2e-2)
    high = _measured_response(WashoutFilter(POLE, DT, n=1), 1000.0)
    assert abs(high) == pytest.approx(abs(cont[1]), rel=0.1)
    assert abs(high) < 1.05 * POLE


def test_transfer_function_coefficients_match_scipy() -> None:
    tf = WashoutFilter(POLE, DT, n=1).transfer_function()
    numd, dend, _ = signal.cont2discrete(([POLE, 0.0], [1.0, POLE]), DT, method="backward_diff")
    numd = np.ravel(numd)
    dend = np.ravel(dend)
    np.testing.assert_allclose(tf.num, numd[-2:] / dend[0], rtol=1e-12)
    np.testing.assert_allclose(tf.den, dend / dend[0], rtol=1e-12)


@pytest.mark.parametrize("w", [5.0, 300.0, 2000.0])
def test_numerical_differentiator_matches_freqz(w: float) -> None:
    _, h = signal.freqz([1.0 / DT, -1.0 / DT], [1.0], worN=[w * DT])
    measured = _measured_response(NumericalDifferentiator(DT, n=1), w)
    assert measured == pytest.approx(complex(h[0]), rel=1e-6, abs=1e-9)


def test_differentiator_amplifies_noise_more_than_washout() -> None:
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 1e-4, size=(5000, 1))
    wo, nd = WashoutFilter(POLE, DT, n=1), NumericalDifferentiator(DT, n=1)
    v_wo = np.array([wo.update(x)[0] for x in noise])
    v_nd = np.array([nd.update(x)[0] for x in noise])
    assert np.std(v_nd[10:]) > 5 * np.std(v_wo[10:])


def test_vector_of_joints_and_ramp() -> None:
    wo = WashoutFilter(POLE, DT, n=4)
    rates = np.array([0.5, -1.0, 2.0, 0.01])
    for k in range(2000):
        v = wo.update(rates * k * DT)
    np.testing.assert_allclose(v, rates, rtol=1e-9)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan")])
def test_bad_parameters_raise_typed_error(bad: float) -> None:
    with pytest.raises(FilterParameterError) as info:
        WashoutFilter(bad, DT)
    assert info.value.name == "pole"
    with pytest.raises(FilterParameterError):
        NumericalDifferentiator(bad)
