"""Velocity estimation from encoder positions: washout filter and numerical differentiation.

The EndoBot measures joint positions only (thesis 5.2.3.3), so every controller
that needs a joint velocity estimates it. Two estimators are given here for
comparison:

* :class:`NumericalDifferentiator`, the backward difference
  ``v[k] = (q[k] - q[k-1]) / Ts`` whose continuous-time equivalent is
  ``(1 - exp(-s Ts)) / Ts`` (5.48-5.49). It amplifies high-frequency noise.
* :class:`WashoutFilter`, ``s / (s/p + 1)`` (3.78, 5.50), a differentiator
  and a first-order low-pass with its pole at ``p`` in one proper filter,
  discretised with the backward-difference substitution
  ``s = (z - 1) / (Ts z)`` (3.79). The printed (3.79) has a ``+1`` in its
  denominator; the backward substitution gives ``p (z - 1) / ((p Ts + 1) z - 1)``,
  which is what is implemented (the printed sign would put the pole outside
  the unit circle's positive half and is a transcription error).

Both filters work on a vector of joints at once and allocate nothing per call
once constructed.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from suture_engine.errors import SutureError

__all__ = [
    "DiscreteTransferFunction",
    "FilterParameterError",
    "NumericalDifferentiator",
    "WashoutFilter",
]


class FilterParameterError(SutureError):
    """A filter was constructed with a non-physical parameter.

    Attributes:
        name: the parameter's name.
        value: the offending value.
        bound: a description of the valid range.
    """

    code = "filter-parameter"

    def __init__(self, name: str, value: float, bound: str) -> None:
        super().__init__(f"filter parameter {name}={value!r} must be {bound}")
        self.name = name
        self.value = value
        self.bound = bound


class DiscreteTransferFunction(NamedTuple):
    """A discrete transfer function ``num(z) / den(z)`` in descending powers of ``z``.

    Attributes:
        num: numerator coefficients.
        den: denominator coefficients, ``den[0] == 1``.
        dt: sampling time [s].
    """

    num: tuple[float, ...]
    den: tuple[float, ...]
    dt: float


def _check_positive(name: str, value: float) -> float:
    value = float(value)
    if not np.isfinite(value) or value <= 0.0:
        raise FilterParameterError(name, value, "a positive finite number")
    return value


class WashoutFilter:
    """Washout velocity filter ``s / (s/p + 1)`` discretised by backward difference (3.78-3.79).

    The difference equation is ``(1 + p Ts) v[k] = v[k-1] + p (q[k] - q[k-1])``.
    The first sample initialises the filter at rest (``v = 0``).

    Args:
        pole: roll-off pole ``p`` [rad/s]; the thesis uses 100 for identification
            and suggests 2-3 times the fastest closed-loop pole (5.50).
        dt: sampling time ``Ts`` [s].
        n: number of joints filtered together.
    """

    def __init__(self, pole: float, dt: float, n: int = 4) -> None:
        self.pole = _check_positive("pole", pole)
        self.dt = _check_positive("dt", dt)
        self.n = int(n)
        self._a = 1.0 / (1.0 + self.pole * self.dt)
        self._b = self.pole * self._a
        # Plain floats per joint: for 4 channels this beats numpy's per-call overhead.
        self._q_prev: list[float] = [0.0] * self.n
        self._vl: list[float] = [0.0] * self.n
        self._v = np.zeros(self.n)
        self._started = False

    def __repr__(self) -> str:
        return f"WashoutFilter(pole={self.pole}, dt={self.dt}, n={self.n})"

    def reset(self, q: ArrayLike | None = None) -> None:
        """Forget the history; optionally start from position ``q`` [rad or m] at rest."""
        self._v[:] = 0.0
        self._vl = [0.0] * self.n
        if q is None:
            self._started = False
        else:
            self._q_prev = np.asarray(q, dtype=float).tolist()
            self._started = True

    def update(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Feed one position sample and return the velocity estimate.

        Args:
            q: joint positions [rad or m], shape ``(n,)``.

        Returns:
            The velocity estimate [rad/s or m/s]; a view of internal storage,
            overwritten by the next call (copy it to keep it).
        """
        ql = q.tolist()
        if not self._started:
            self._q_prev = ql
            self._started = True
            return self._v
        a, b, qp, vl = self._a, self._b, self._q_prev, self._vl
        for i in range(self.n):
            vl[i] = a * vl[i] + b * (ql[i] - qp[i])
        self._q_prev = ql
        self._v[:] = vl
        return self._v

    def update_frozen(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`update`, returning the estimate as a fresh read-only array the caller
        may keep (the interpreter's per-tick form: no copy of the internal storage).

        Args:
            q: joint positions [rad or m], shape ``(n,)``.

        Returns:
            The velocity estimate [rad/s or m/s], the same numbers as :meth:`update`.
        """
        ql = q.tolist()
        if not self._started:
            self._q_prev = ql
            self._started = True
            out = self._v.copy()
        else:
            a, b, qp, vl = self._a, self._b, self._q_prev, self._vl
            for i in range(self.n):
                vl[i] = a * vl[i] + b * (ql[i] - qp[i])
            self._q_prev = ql
            out = np.array(vl)  # (update() alone writes its view, self._v)
        out.flags.writeable = False
        return out

    def transfer_function(self) -> DiscreteTransferFunction:
        """One channel's discrete transfer function ``p (z-1) / ((p Ts + 1) z - 1)`` (3.79)."""
        g = 1.0 + self.pole * self.dt
        return DiscreteTransferFunction(
            num=(self.pole / g, -self.pole / g), den=(1.0, -1.0 / g), dt=self.dt
        )


class NumericalDifferentiator:
    """Backward-difference differentiator ``(q[k] - q[k-1]) / Ts`` (5.48).

    Args:
        dt: sampling time ``Ts`` [s].
        n: number of joints differentiated together.
    """

    def __init__(self, dt: float, n: int = 4) -> None:
        self.dt = _check_positive("dt", dt)
        self.n = int(n)
        self._inv_dt = 1.0 / self.dt
        self._q_prev: list[float] = [0.0] * self.n
        self._v = np.zeros(self.n)
        self._started = False

    def __repr__(self) -> str:
        return f"NumericalDifferentiator(dt={self.dt}, n={self.n})"

    def reset(self, q: ArrayLike | None = None) -> None:
        """Forget the history; optionally start from position ``q`` [rad or m] at rest."""
        self._v[:] = 0.0
        if q is None:
            self._started = False
        else:
            self._q_prev = np.asarray(q, dtype=float).tolist()
            self._started = True

    def update(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Feed one position sample and return the velocity estimate.

        Args:
            q: joint positions [rad or m], shape ``(n,)``.

        Returns:
            The velocity estimate [rad/s or m/s]; a view of internal storage,
            overwritten by the next call.
        """
        ql = q.tolist()
        if not self._started:
            self._q_prev = ql
            self._started = True
            return self._v
        k, qp = self._inv_dt, self._q_prev
        self._v[:] = [k * (x - y) for x, y in zip(ql, qp, strict=True)]
        self._q_prev = ql
        return self._v

    def transfer_function(self) -> DiscreteTransferFunction:
        """The discrete transfer function of one channel, ``(z - 1) / (Ts z)`` (5.48)."""
        return DiscreteTransferFunction(
            num=(self._inv_dt, -self._inv_dt), den=(1.0, 0.0), dt=self.dt
        )
