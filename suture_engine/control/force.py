"""Explicit PI force control with active damping (thesis 7.22): stability bounds.

The plant seen by the force loop is a mass-damper-spring
``m x'' + b x' + k x = u`` whose measured force is ``f_m = k x`` (7.23-7.24),
under ``u = Kp (f_r - f_m) + Ki int(f_r - f_m) dt - Kv x'`` (7.22, 7.30).
The closed loop's characteristic polynomial is (7.32)::

    Pi(s) = m s^3 + (b + Kv) s^2 + k (1 + Kp) s + k Ki

and Routh's criterion gives, for m, b, k, Kp > 0 (7.29, 7.33)::

    0 < Ki < (b + Kv) (1 + Kp) / m

A measurement delay T turns f_m into ``k x(t - T)``. With the first-order
expansion ``e^{-sT} ~ 1 - sT`` (7.36) the polynomial becomes (7.39)::

    Pi(s) = m s^3 + (b + Kv - k Kp T) s^2 + k (1 + Kp - Ki T) s + k Ki

and Routh gives (7.40-7.44)::

    Kp < (b + Kv) / (k T),   0 < Ki < (1 + Kp) / (m / (b + Kv - k Kp T) + T)

For m=1, b=1, k=10, Kp=10, T=2 ms this is 8.786; a (1,1) or higher-order
Padé approximant of the delay gives 8.7863 (the exact delayed loop's bound,
to four digits), so the first-order bound is slightly conservative. The thesis
reads 8.82 off its root locus.
"""

from __future__ import annotations

import math

from suture_engine.errors import InvalidValue

__all__ = ["ForceGainError", "integral_gain_bound"]


class ForceGainError(InvalidValue):
    """Invalid plant or gain values given to a stability bound.

    Attributes:
        name: the offending argument.
        value: its value.
    """


def integral_gain_bound(
    m: float, b: float, k: float, kp: float, kv: float = 0.0, delay: float = 0.0
) -> float:
    """The largest stable integral gain Ki of PI force control (7.29, 7.33, 7.41, 7.43).

    The loop is stable for ``0 < Ki < integral_gain_bound(...)``.

    Args:
        m: mass of the force plant [kg], > 0.
        b: damping of the force plant [N*s/m], >= 0.
        k: environment stiffness [N/m], > 0.
        kp: proportional force gain Kp [-], >= 0.
        kv: active damping gain Kv [N*s/m], >= 0 (7.30).
        delay: measurement delay T [s], >= 0 (7.34-7.44).

    Returns:
        The upper bound of Ki [1/s]. It is 0.0 when no Ki is stable, which with a
        delay happens once ``Kp >= (b + Kv) / (k T)`` (7.40 (i)).

    Raises:
        ForceGainError: an argument is out of its domain or not finite.
    """
    for name, value, positive in (
        ("m", m, True),
        ("k", k, True),
        ("b", b, False),
        ("kp", kp, False),
        ("kv", kv, False),
        ("delay", delay, False),
    ):
        if not math.isfinite(value) or value < 0 or (positive and value == 0):
            raise ForceGainError(name, value, "finite and " + ("> 0" if positive else ">= 0"))
    damping = b + kv
    if delay == 0.0:
        return damping * (1.0 + kp) / m
    effective = damping - k * kp * delay
    if effective <= 0.0:
        return 0.0
    return (1.0 + kp) / (m / effective + delay)
