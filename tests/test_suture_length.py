"""The suture length estimator vs hand-computed lengths for known needle trajectories."""

from __future__ import annotations

import math

import numpy as np
import pytest

from suture_engine.suture.length import (
    SutureLengthEstimator,
    TensionBoundTooLow,
    max_extension_rate,
)

DT = 1e-3


def segment(a: tuple[float, ...], b: tuple[float, ...], speed: float) -> np.ndarray:
    """Points from a to b at constant ``speed`` [m/s], sampled every DT."""
    pa, pb = np.array(a), np.array(b)
    n = max(1, math.ceil(np.linalg.norm(pb - pa) / (speed * DT)))
    return pa + np.outer(np.arange(1, n + 1) / n, pb - pa)


def feed(est: SutureLengthEstimator, points: np.ndarray, clock: list[float]) -> list[float]:
    out = []
    for p in points:
        clock[0] += DT
        out.append(est.update(clock[0], p).length)
    return out


def test_out_back_around_and_out_again() -> None:
    """Exit point at the origin; the needle goes out 20 mm, back to 10 mm, around a
    10 mm circle and finally to (30, 0, 10) mm: L = sqrt(30^2 + 10^2) mm by hand."""
    est = SutureLengthEstimator((0.0, 0.0, 0.0))
    est.update(0.0, (0.0, 0.0, 0.0))
    clock = [0.0]
    out = feed(est, segment((0, 0, 0), (0, 0, 0.02), 0.01), clock)
    assert out[-1] == pytest.approx(0.02, abs=1e-12)
    back = feed(est, segment((0, 0, 0.02), (0, 0, 0.01), 0.01), clock)
    assert back == [pytest.approx(0.02, abs=1e-12)] * len(back)  # slack: length kept
    phi = np.linspace(0, 2 * math.pi, 500)
    circle = 0.01 * np.column_stack((np.sin(phi), np.zeros_like(phi), np.cos(phi)))
    assert max(feed(est, circle, clock)) == pytest.approx(0.02, abs=1e-12)  # |xi| = 10 mm < L
    feed(est, segment((0, 0, 0.01), (0.03, 0, 0.01), 0.01), clock)
    assert est.length == pytest.approx(math.hypot(0.03, 0.01), abs=1e-12)


def test_the_rate_is_the_radial_speed_when_taut() -> None:
    est = SutureLengthEstimator((0.01, 0.0, 0.0), initial_length=0.0)
    est.update(0.0, (0.01, 0.0, 0.0))
    direction = np.array((1.0, 2.0, 2.0)) / 3.0
    samples = [
        est.update((i + 1) * DT, np.array((0.01, 0.0, 0.0)) + 0.004 * (i + 1) * DT * direction)
        for i in range(200)
    ]
    assert all(s.taut for s in samples)
    assert [s.rate for s in samples] == [pytest.approx(0.004, rel=1e-9)] * 200
    assert est.peak_rate == pytest.approx(0.004, rel=1e-9)
    # moving sideways at the same distance is slack: no growth, zero rate
    side = est.update(
        1.0, np.array((0.01, 0.0, 0.0)) + 0.0008 * np.array((0.0, 1.0, -1.0)) / math.sqrt(2)
    )
    assert not side.taut and side.rate == 0.0


def test_matches_the_differential_form_4_1() -> None:
    """Integrate dL/dt = xi . P' / |xi| when xi . P' > 0 and |xi| >= L (4.1) on a
    wobbling path and compare with the estimator's running maximum (4.3)."""
    t = np.arange(0.0, 4.0, 1e-4)
    path = np.column_stack(
        (
            0.02 * np.sin(1.3 * t),
            0.01 * np.sin(3.1 * t) * t,
            0.005 + 0.008 * t * (1 + np.cos(5 * t)),
        )
    )
    po = np.zeros(3)
    length = float(np.linalg.norm(path[0] - po))
    est = SutureLengthEstimator(po, initial_length=length)
    est.update(t[0], path[0])
    for k in range(1, len(t)):
        xi = path[k - 1] - po
        dp = path[k] - path[k - 1]
        d = float(np.linalg.norm(xi))
        if xi @ dp > 0 and d >= length - 1e-12:
            length += float(xi @ dp) / d
        est.update(t[k], path[k])
    assert est.length == pytest.approx(length, rel=2e-3)


def test_extension_rate_bound_4_11() -> None:
    assert max_extension_rate(3.0, 0.2, 50.0) == pytest.approx(2.8 / 50.0)
    # the bound keeps the static model's tension (4.5) at f_max exactly
    rate = max_extension_rate(1.7, 0.4, 20.0)
    assert 0.4 * 1.0 + 20.0 * rate == pytest.approx(1.7)
    with pytest.raises(TensionBoundTooLow) as info:
        max_extension_rate(0.2, 0.2, 50.0)
    assert info.value.code == "tension-bound-too-low" and info.value.f_max == 0.2
    with pytest.raises(ValueError):
        max_extension_rate(1.0, 0.2, 0.0)


def test_rejects_time_going_backwards_and_negative_lengths() -> None:
    est = SutureLengthEstimator((0, 0, 0))
    est.update(1.0, (0, 0, 0.01))
    with pytest.raises(ValueError):
        est.update(0.5, (0, 0, 0.02))
    with pytest.raises(ValueError):
        SutureLengthEstimator((0, 0, 0), initial_length=-1.0)
