"""Suture length tracked from the needle position only (thesis 4.2-4.3).

The suture runs from the exit point P_o to the needle held at the tool tip P.
With ``xi = P - P_o`` the suture is in tension, and its length L grows, only
while the needle moves away from the exit point (``xi . dP/dt > 0``) and
``|xi| >= L``; then ``dL/dt = xi . dP/dt / |xi|``, otherwise ``dL/dt = 0``
(4.1). Integrated, the length is the running maximum of the extension
``l(t) = max(l_0, max_{s <= t} |xi(s)|)`` (4.3), whose rate is the
extension rate (4.4). The simulator's suture state is never read.

Pulling with tension ``f = F_s sgn(l') + F_v l'`` (4.5) stays under f_max when
``l' <= l'_max = (f_max - F_s) / F_v`` (4.10-4.11).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.errors import SutureError

__all__ = [
    "DEFAULT_STATIC_DRAG",
    "DEFAULT_VISCOUS_DRAG",
    "LengthSample",
    "SutureLengthEstimator",
    "TensionBoundTooLow",
    "max_extension_rate",
]

DEFAULT_STATIC_DRAG = 0.2
"""F_s, static suture-tissue drag [N] (assumed; the thesis gives no value)."""
DEFAULT_VISCOUS_DRAG = 50.0
"""F_v, viscous suture-tissue drag [N*s/m] (assumed; the thesis gives no value)."""


class TensionBoundTooLow(SutureError):
    """f_max is not above the static drag F_s, so no pulling speed keeps f <= f_max (4.11).

    Attributes:
        f_max: the tension bound [N].
        static: the static drag F_s [N].
    """

    code = "tension-bound-too-low"

    def __init__(self, f_max: float, static: float) -> None:
        super().__init__(
            f"tension bound {f_max:g} N is not above the static drag {static:g} N: "
            "the suture cannot be pulled (4.11)"
        )
        self.f_max = f_max
        self.static = static


def max_extension_rate(
    f_max: float, static: float = DEFAULT_STATIC_DRAG, viscous: float = DEFAULT_VISCOUS_DRAG
) -> float:
    """Largest suture extension rate l'_max = (f_max - F_s) / F_v [m/s] (4.10-4.11).

    Args:
        f_max: tension bound [N].
        static: static drag F_s [N], >= 0.
        viscous: viscous drag F_v [N*s/m], > 0.

    Raises:
        TensionBoundTooLow: f_max <= F_s.
        ValueError: negative F_s or non-positive F_v.
    """
    if static < 0.0 or viscous <= 0.0:
        raise ValueError(f"need F_s >= 0 and F_v > 0, got {static!r}, {viscous!r}")
    if f_max <= static:
        raise TensionBoundTooLow(f_max, static)
    return (f_max - static) / viscous


class LengthSample(NamedTuple):
    """One update of the estimator.

    Attributes:
        length: estimated suture length from the exit point to the needle L [m] (4.3).
        rate: extension rate l' over the last update [m/s] (4.4); 0 when slack.
        taut: whether the suture was in tension during the update (4.1).
    """

    length: float
    rate: float
    taut: bool


class SutureLengthEstimator:
    """Track the suture length from the needle (tool-tip) position only (4.1, 4.3-4.4).

    Args:
        exit_point: the stitch's exit point P_o in the world frame [m].
        initial_length: L at the start [m]; at least ``|P(0) - P_o|`` once the first
            position is given.
    """

    def __init__(
        self, exit_point: Sequence[float] | NDArray[np.float64], initial_length: float = 0.0
    ):
        if initial_length < 0.0:
            raise ValueError("initial_length must be >= 0")
        self.exit_point = np.array(exit_point, dtype=np.float64).reshape(3)
        self.length = float(initial_length)
        self.peak_rate = 0.0
        self._last_t: float | None = None

    def extension(self, needle: Sequence[float] | NDArray[np.float64]) -> float:
        """|xi| = |P - P_o| [m]."""
        d = np.asarray(needle, dtype=np.float64) - self.exit_point
        return math.sqrt(float(d @ d))

    def update(self, t: float, needle: Sequence[float] | NDArray[np.float64]) -> LengthSample:
        """Advance to time ``t`` [s] with the measured needle position [m] (4.1, 4.3).

        Args:
            t: time [s], non-decreasing.
            needle: needle (tool-tip) position in the world frame [m].

        Returns:
            the :class:`LengthSample` after the update.
        """
        ext = self.extension(needle)
        dt = 0.0 if self._last_t is None else t - self._last_t
        if dt < 0.0:
            raise ValueError("time went backwards")
        self._last_t = t
        if ext > self.length:
            grown = ext - self.length
            self.length = ext
            rate = grown / dt if dt > 0.0 else 0.0
            self.peak_rate = max(self.peak_rate, rate)
            return LengthSample(self.length, rate, True)
        return LengthSample(self.length, 0.0, False)
