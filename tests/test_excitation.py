"""Excitation signals and regressor quality tags (3.53-3.59)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from suture_engine.robot.excitation import (
    PRBS_TAPS,
    ExcitationError,
    ExcitationKind,
    chirp,
    condition_number,
    crest_factor,
    excitation,
    lfsr_sequence,
    multisine,
    persistence_of_excitation,
    prbs,
    schroeder_multisine,
)


def _period(bits: np.ndarray) -> int:
    """Smallest p with bits[k] == bits[k + p] over two concatenated periods."""
    x = np.concatenate([bits, bits])
    n = bits.size
    for p in range(1, n + 1):
        if np.array_equal(x[p : p + n], bits):
            return p
    return -1


@pytest.mark.parametrize("n", sorted(PRBS_TAPS))
def test_shift_register_is_maximal_length(n: int) -> None:
    bits = lfsr_sequence(n)
    assert bits.size == 2**n - 1
    assert _period(bits) == 2**n - 1
    assert int(bits.sum()) == 2 ** (n - 1)  # balance property of m-sequences
    # Two-valued periodic autocorrelation: N at lag 0, -1 elsewhere.
    s = 2.0 * bits - 1.0
    spec = np.fft.fft(s)
    acf = np.real(np.fft.ifft(spec * np.conj(spec)))
    assert acf[0] == pytest.approx(s.size)
    np.testing.assert_allclose(acf[1:], -1.0, atol=1e-6)


def test_prbs_autocorrelation_matches_scipy_mls() -> None:
    ours = 2.0 * lfsr_sequence(10) - 1.0
    ref = 2.0 * signal.max_len_seq(10)[0].astype(float) - 1.0
    acf = [np.real(np.fft.ifft(np.abs(np.fft.fft(x)) ** 2)) for x in (ours, ref)]
    np.testing.assert_allclose(acf[0], acf[1], atol=1e-6)


def test_prbs_signal_levels_and_switching_time() -> None:
    sig = prbs(2.0, 0.001, 0.02, 0.3, registers=7, offset=0.1)
    assert set(np.round(np.unique(sig.u), 12)) == {-0.2, 0.4}
    changes = np.flatnonzero(np.diff(sig.u)) + 1
    assert np.all(np.diff(changes) % 20 == 0)


def test_schroeder_crest_factor_below_plain_multisine() -> None:
    dt, big_n, ns = 0.001, 2000, 20
    sch = schroeder_multisine(4.0, dt, 1.0, period_samples=big_n, n_sines=ns)
    freqs = np.arange(1, ns + 1) / (big_n * dt)
    plain = multisine(4.0, dt, freqs, 1.0, phases=np.full(ns, np.pi / 2))  # cosines, phase 0
    assert crest_factor(sch.u) < 0.5 * crest_factor(plain.u)
    assert crest_factor(sch.u) < 2.0
    # Flat power spectrum: every harmonic carries the same power (3.59 with equal alpha).
    spec = np.abs(np.fft.rfft(sch.u[:big_n])) ** 2
    harmonics = spec[1 : ns + 1]
    np.testing.assert_allclose(harmonics / harmonics.mean(), 1.0, rtol=1e-9)
    assert np.max(spec[ns + 2 :]) < 1e-12 * harmonics.mean()


def test_amplitude_limits_hold_for_every_kind() -> None:
    for kind in ExcitationKind:
        sig = excitation(kind, 5.0, 0.001, 0.25, offset=0.5)
        assert sig.kind is kind
        assert np.max(sig.u) <= 0.75 + 1e-12
        assert np.min(sig.u) >= 0.25 - 1e-12
        assert np.max(sig.u) - np.min(sig.u) > 0.3  # uses the range


def test_chirp_instantaneous_frequency_sweeps() -> None:
    sig = chirp(10.0, 0.001, 0.5, 5.0, 1.0)
    zero_cross = np.flatnonzero(np.diff(np.signbit(sig.u)))
    tc = sig.t[zero_cross]
    measured = 1.0 / (2.0 * np.diff(tc))
    expected = 0.5 + 0.45 * 0.5 * (tc[1:] + tc[:-1])  # linear sweep 0.5 -> 5 Hz over 10 s
    np.testing.assert_allclose(measured[1:], expected[1:], rtol=0.02)


def test_condition_number_and_persistence() -> None:
    rng = np.random.default_rng(0)
    good = rng.normal(size=(1000, 4))
    assert condition_number(good) == pytest.approx(np.linalg.cond(good))
    bad = good.copy()
    bad[:, 3] = bad[:, 0] + bad[:, 1]
    assert condition_number(bad) > 1e10
    assert persistence_of_excitation(good, 100).persistent
    assert not persistence_of_excitation(bad, 100).persistent
    # A single sine excites an order-2 regressor [sin, cos] but not [sin, cos, sin].
    t = np.arange(2000) * 0.001
    two = np.column_stack([np.sin(5 * t), np.cos(5 * t)])
    assert persistence_of_excitation(two, 500).persistent
    assert not persistence_of_excitation(np.column_stack([two, two[:, 0]]), 500).persistent


@pytest.mark.parametrize(
    "call",
    [
        lambda: lfsr_sequence(1),
        lambda: lfsr_sequence(5, seed=0),
        lambda: schroeder_multisine(1.0, 0.001, 1.0, period_samples=10, n_sines=6),
        lambda: excitation("white", 1.0, 0.001, 1.0),
        lambda: multisine(1.0, 0.001, [1.0], -1.0),
        lambda: chirp(-1.0, 0.001, 1.0, 2.0, 1.0),
    ],
)
def test_bad_settings_raise_typed_error(call) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ExcitationError):
        call()
