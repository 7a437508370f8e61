"""Excitation signals for identification, and the quality tags of a regressor (3.5.1).

Four off-the-shelf signals, each scaled to respect an amplitude limit
``u_min <= u(k) <= u_max`` (3.55):

* :func:`multisine`: a sum of sines at chosen frequencies, zero phases;
* :func:`chirp`: ``sin(2 pi f(t) t)`` with a linear or logarithmic sweep (3.56);
* :func:`prbs`: a pseudo-random binary sequence from a linear feedback shift
  register (Fig. 3.12), period ``2^n - 1`` for ``n`` registers;
* :func:`schroeder_multisine`: the Schroeder-phased multisine (3.57-3.59),
  whose phases ``phi_i = 2 pi sum_{j<=i} j alpha_j`` keep the crest factor low
  for a given (flat, by default) power spectrum.

:func:`persistence_of_excitation` and :func:`condition_number` give the
quality tags of (3.53) and (3.54) for a regression matrix.
"""

from __future__ import annotations

import enum
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from suture_engine.errors import SutureError

__all__ = [
    "PRBS_TAPS",
    "ExcitationError",
    "ExcitationKind",
    "ExcitationSignal",
    "Persistence",
    "chirp",
    "condition_number",
    "crest_factor",
    "excitation",
    "lfsr_sequence",
    "multisine",
    "persistence_of_excitation",
    "prbs",
    "schroeder_multisine",
]

FloatArray = NDArray[np.float64]

PRBS_TAPS: dict[int, tuple[int, ...]] = {
    2: (2, 1),
    3: (3, 2),
    4: (4, 3),
    5: (5, 3),
    6: (6, 5),
    7: (7, 6),
    8: (8, 6, 5, 4),
    9: (9, 5),
    10: (10, 7),
    11: (11, 9),
    12: (12, 11, 10, 4),
    13: (13, 12, 11, 8),
    14: (14, 13, 12, 2),
    15: (15, 14),
    16: (16, 15, 13, 4),
}
"""Feedback taps (1-based register numbers) of maximal-length shift registers (Fig. 3.12)."""


class ExcitationError(SutureError):
    """An excitation signal was asked for with impossible settings.

    Attributes:
        name: the parameter's name.
        value: the offending value.
        bound: the valid range or names.
    """

    code = "excitation"

    def __init__(self, name: str, value: object, bound: str) -> None:
        super().__init__(f"excitation parameter {name}={value!r}: {bound}")
        self.name = name
        self.value = value
        self.bound = bound


class ExcitationKind(str, enum.Enum):
    """The excitation signals of 3.5.1."""

    MULTISINE = "multisine"
    """Sum of sines, zero phases."""
    CHIRP = "chirp"
    """Swept sine (3.56)."""
    PRBS = "prbs"
    """Pseudo-random binary sequence from a shift register (Fig. 3.12)."""
    SCHROEDER = "schroeder"
    """Schroeder-phased multisine (3.57-3.59)."""


class ExcitationSignal(NamedTuple):
    """A sampled excitation signal.

    Attributes:
        t: sample times [s].
        u: samples, in the unit of the limits (torque [N m] for identification).
        kind: which signal.
    """

    t: FloatArray
    u: FloatArray
    kind: ExcitationKind


class Persistence(NamedTuple):
    """Persistence of excitation of a regression matrix over sliding windows (3.53).

    Attributes:
        alpha1: smallest eigenvalue of the windowed information matrix over all windows.
        alpha2: largest eigenvalue over all windows.
        persistent: ``alpha1 > 0`` relative to ``alpha2`` (above ``tol``).
    """

    alpha1: float
    alpha2: float
    persistent: bool


def _samples(duration: float, dt: float) -> FloatArray:
    if not (np.isfinite(duration) and duration > 0.0):
        raise ExcitationError("duration", duration, "must be positive")
    if not (np.isfinite(dt) and 0.0 < dt < duration):
        raise ExcitationError("dt", dt, "must be positive and below the duration")
    return np.arange(round(duration / dt), dtype=np.float64) * float(dt)


def _fit_to_limits(u: FloatArray, amplitude: float, offset: float) -> FloatArray:
    """Scale a zero-centred shape so that ``offset +- amplitude`` bounds it (3.55)."""
    if not (np.isfinite(amplitude) and amplitude > 0.0):
        raise ExcitationError("amplitude", amplitude, "must be positive")
    peak = float(np.max(np.abs(u)))
    if peak == 0.0:
        return np.full_like(u, offset)
    return offset + u * (amplitude / peak)


def crest_factor(u: ArrayLike) -> float:
    """Peak over RMS of a zero-mean signal [-]."""
    x = np.asarray(u, dtype=float)
    x = x - x.mean()
    return float(np.max(np.abs(x)) / np.sqrt(np.mean(x * x)))


def multisine(
    duration: float,
    dt: float,
    frequencies: ArrayLike,
    amplitude: float,
    *,
    offset: float = 0.0,
    phases: ArrayLike | None = None,
) -> ExcitationSignal:
    """A sum of equal-amplitude sines, scaled into ``offset +- amplitude``.

    Args:
        duration: length [s].
        dt: sampling time [s].
        frequencies: sine frequencies [Hz].
        amplitude: half-range of the signal (3.55).
        offset: centre value.
        phases: phase per sine [rad]; zero phases (the plain multisine) by default.

    Returns:
        The signal.
    """
    t = _samples(duration, dt)
    f = np.atleast_1d(np.asarray(frequencies, dtype=float))
    ph = np.zeros_like(f) if phases is None else np.asarray(phases, dtype=float)
    u = np.sin(2.0 * np.pi * f[None, :] * t[:, None] + ph[None, :]).sum(axis=1)
    return ExcitationSignal(t, _fit_to_limits(u, amplitude, offset), ExcitationKind.MULTISINE)


def chirp(
    duration: float,
    dt: float,
    f_start: float,
    f_end: float,
    amplitude: float,
    *,
    offset: float = 0.0,
    logarithmic: bool = False,
) -> ExcitationSignal:
    """Swept sine ``sin(2 pi f(t) t)`` (3.56), written with its exact phase integral.

    Args:
        duration: sweep time [s].
        dt: sampling time [s].
        f_start: start frequency [Hz].
        f_end: end frequency [Hz].
        amplitude: half-range of the signal (3.55).
        offset: centre value.
        logarithmic: logarithmic instead of linear sweep.

    Returns:
        The signal.
    """
    t = _samples(duration, dt)
    if f_start <= 0.0 or f_end <= 0.0:
        raise ExcitationError("frequency", (f_start, f_end), "must be positive")
    if logarithmic and f_end != f_start:
        k = (f_end / f_start) ** (1.0 / duration)
        phase = 2.0 * np.pi * f_start * (k**t - 1.0) / np.log(k)
    else:
        phase = 2.0 * np.pi * (f_start * t + 0.5 * (f_end - f_start) / duration * t * t)
    return ExcitationSignal(t, offset + amplitude * np.sin(phase), ExcitationKind.CHIRP)


def lfsr_sequence(registers: int, seed: int = 1) -> NDArray[np.int8]:
    """One period of the bit stream of a maximal-length shift register (Fig. 3.12).

    Args:
        registers: number of registers ``n`` (2-16); the period is ``2^n - 1``.
        seed: initial register contents, any non-zero ``n``-bit integer.

    Returns:
        The ``2^n - 1`` output bits (0/1).
    """
    taps = PRBS_TAPS.get(registers)
    if taps is None:
        raise ExcitationError("registers", registers, f"one of {sorted(PRBS_TAPS)}")
    mask = (1 << registers) - 1
    state = seed & mask
    if state == 0:
        raise ExcitationError("seed", seed, "must be non-zero in the low n bits")
    period = (1 << registers) - 1
    out = np.empty(period, dtype=np.int8)
    for k in range(period):
        out[k] = state & 1  # output from the last register
        fb = 0
        for tap in taps:
            fb ^= (state >> (registers - tap)) & 1
        state = (state >> 1) | (fb << (registers - 1))
    return out


def prbs(
    duration: float,
    dt: float,
    switching_time: float,
    amplitude: float,
    *,
    registers: int = 9,
    offset: float = 0.0,
    seed: int = 1,
) -> ExcitationSignal:
    """Pseudo-random binary sequence ``offset +- amplitude`` (Fig. 3.12).

    Args:
        duration: length [s]; the sequence repeats with period ``(2^n - 1) Tsw``.
        dt: sampling time [s].
        switching_time: ``Tsw``, the minimum time between level changes [s].
        amplitude: the two levels are ``offset +- amplitude``.
        registers: number of shift registers ``n``.
        offset: centre value.
        seed: register initial state.

    Returns:
        The signal.
    """
    t = _samples(duration, dt)
    if not (switching_time >= dt):
        raise ExcitationError("switching_time", switching_time, "must be at least dt")
    bits = lfsr_sequence(registers, seed)
    idx = (np.floor(t / switching_time + 1e-9).astype(np.int64)) % bits.size
    u = offset + amplitude * (2.0 * bits[idx].astype(float) - 1.0)
    return ExcitationSignal(t, u, ExcitationKind.PRBS)


def schroeder_multisine(
    duration: float,
    dt: float,
    amplitude: float,
    *,
    period_samples: int = 2000,
    n_sines: int = 20,
    relative_power: ArrayLike | None = None,
    offset: float = 0.0,
) -> ExcitationSignal:
    """Schroeder-phased multisine (3.57-3.59), scaled into ``offset +- amplitude``.

    ``u(k) = lambda sum_i sqrt(2 alpha_i) cos(w_i k T + phi_i)`` with
    ``w_i = 2 pi i / (Ns T)`` and ``phi_i = 2 pi sum_{j<=i} j alpha_j``.

    Args:
        duration: length [s]; periodic with period ``Ns T``.
        dt: sampling time ``T`` [s].
        amplitude: half-range; ``lambda`` is chosen to meet it (3.55).
        period_samples: ``Ns``, samples per period; sets the lowest frequency
            ``1 / (Ns T)`` [Hz].
        n_sines: ``ns`` harmonics (order of persistent excitation), ``ns <= Ns / 2``.
        relative_power: ``alpha_i`` (normalised to sum 1, (3.59)); flat by default.
        offset: centre value.

    Returns:
        The signal.
    """
    t = _samples(duration, dt)
    ns, big_n = int(n_sines), int(period_samples)
    if ns < 1 or 2 * ns > big_n:
        raise ExcitationError("n_sines", n_sines, f"must be in 1..{big_n // 2}")
    alpha = np.ones(ns) if relative_power is None else np.asarray(relative_power, dtype=float)
    if alpha.shape != (ns,) or np.any(alpha <= 0.0):
        raise ExcitationError("relative_power", alpha.tolist(), f"{ns} positive values")
    alpha = alpha / alpha.sum()
    i = np.arange(1, ns + 1)
    phi = 2.0 * np.pi * np.cumsum(i * alpha)
    w = 2.0 * np.pi * i / (big_n * dt)
    k = np.arange(t.size)
    u = (np.sqrt(2.0 * alpha)[None, :] * np.cos(w[None, :] * (k * dt)[:, None] + phi)).sum(axis=1)
    return ExcitationSignal(t, _fit_to_limits(u, amplitude, offset), ExcitationKind.SCHROEDER)


def excitation(
    kind: ExcitationKind | str,
    duration: float,
    dt: float,
    amplitude: float,
    *,
    f_low: float = 0.2,
    f_high: float = 4.0,
    offset: float = 0.0,
    seed: int = 1,
) -> ExcitationSignal:
    """Any of the four signals over the band ``f_low``-``f_high`` [Hz] with common defaults.

    Args:
        kind: which signal.
        duration: length [s].
        dt: sampling time [s].
        amplitude: half-range of the signal.
        f_low: lowest excited frequency [Hz].
        f_high: highest excited frequency [Hz].
        offset: centre value.
        seed: PRBS register seed.

    Returns:
        The signal.
    """
    try:
        k = ExcitationKind(kind)
    except ValueError as exc:
        raise ExcitationError("kind", kind, f"one of {[e.value for e in ExcitationKind]}") from exc
    if not 0.0 < f_low < f_high:
        raise ExcitationError("f_low", (f_low, f_high), "need 0 < f_low < f_high")
    if k is ExcitationKind.MULTISINE:
        freqs = np.geomspace(f_low, f_high, 6)
        return multisine(duration, dt, freqs, amplitude, offset=offset)
    if k is ExcitationKind.CHIRP:
        return chirp(duration, dt, f_low, f_high, amplitude, offset=offset, logarithmic=True)
    if k is ExcitationKind.PRBS:
        tsw = 1.0 / (2.0 * f_high)
        return prbs(duration, dt, max(tsw, dt), amplitude, offset=offset, seed=seed)
    big_n = round(1.0 / (f_low * dt))
    ns = max(1, min(big_n // 2, int(f_high / f_low)))
    return schroeder_multisine(
        duration, dt, amplitude, period_samples=big_n, n_sines=ns, offset=offset
    )


def condition_number(matrix: ArrayLike) -> float:
    """``c(A) = sigma_1 / sigma_n`` (3.54); ``inf`` for a rank-deficient matrix."""
    s = np.linalg.svd(np.asarray(matrix, dtype=float), compute_uv=False)
    return float("inf") if s[-1] == 0.0 else float(s[0] / s[-1])


def persistence_of_excitation(
    regressor: ArrayLike, window: int, *, tol: float = 1e-9
) -> Persistence:
    """Bounds ``alpha1 I <= sum_window phi^T phi <= alpha2 I`` over sliding windows (3.53).

    Args:
        regressor: rows are regressor samples, shape ``(m, p)``.
        window: samples per window (the discrete ``delta``).
        tol: ``alpha1 / alpha2`` below this counts as not persistent.

    Returns:
        The bounds and the verdict.
    """
    phi = np.asarray(regressor, dtype=float)
    m = phi.shape[0]
    if not 0 < window <= m:
        raise ExcitationError("window", window, f"must be in 1..{m}")
    outer = phi[:, :, None] * phi[:, None, :]
    csum = np.concatenate([np.zeros((1, *outer.shape[1:])), np.cumsum(outer, axis=0)])
    step = max(1, window // 4)
    lo, hi = np.inf, 0.0
    for start in range(0, m - window + 1, step):
        eig = np.linalg.eigvalsh(csum[start + window] - csum[start])
        lo = min(lo, float(eig[0]))
        hi = max(hi, float(eig[-1]))
    return Persistence(alpha1=lo, alpha2=hi, persistent=hi > 0.0 and lo / hi > tol)
