"""Joint friction models a-d (thesis 3.42-3.45).

The friction torque τ_f is the term N(q̇) on the left of (3.60):
M q̈ + C q̇ + G + τ_f = τ, so it has the sign of the velocity.

- a) Coulomb: τ_f = Fc sgn(q̇)                                     (3.42)
- b) Coulomb + viscous: τ_f = Fc sgn(q̇) + Fv q̇                    (3.43)
- c) static + Coulomb + viscous: at rest τ_f balances the applied
  torque up to Fs, else as b)                                     (3.44)
- d) Stribeck: Fc sgn(q̇) + (Fs - Fc) e^{-|q̇/q̇s|^δs} sgn(q̇) + Fv q̇,
  static as c) at rest                                            (3.45)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from suture_engine.robot.params import FrictionParams

__all__ = ["FrictionModel", "friction_levels", "friction_torque", "joint_friction"]

FloatArray = NDArray[np.float64]


class FrictionModel(str, Enum):
    """The classical friction models of Fig. 3.10."""

    COULOMB = "a"
    """(3.42) Coulomb only."""
    COULOMB_VISCOUS = "b"
    """(3.43) Coulomb plus viscous; the model the thesis identifies."""
    STATIC = "c"
    """(3.44) static friction at rest, Coulomb plus viscous in motion."""
    STRIBECK = "d"
    """(3.45) static, Stribeck, Coulomb and viscous."""


def _sgn(x: float) -> float:
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


def joint_friction(
    qd: float,
    p: FrictionParams,
    model: FrictionModel = FrictionModel.COULOMB_VISCOUS,
    tau_applied: float = 0.0,
) -> float:
    """Friction torque of one joint.

    Args:
        qd: joint velocity [rad/s] (or [m/s]).
        p: friction parameters of the joint.
        model: which of the models a-d.
        tau_applied: for models c and d at q̇ = 0, the torque [N*m] the rest of
            the system applies; static friction balances it up to Fs.

    Returns:
        τ_f [N*m] (or [N]), the friction term on the left of (3.60).
    """
    if model is FrictionModel.COULOMB:
        return p.coulomb * _sgn(qd)
    if model is FrictionModel.COULOMB_VISCOUS:
        return p.coulomb * _sgn(qd) + p.viscous * qd
    if qd == 0.0:
        return max(-p.static, min(p.static, tau_applied))
    if model is FrictionModel.STATIC:
        return p.coulomb * _sgn(qd) + p.viscous * qd
    stribeck = (p.static - p.coulomb) * math.exp(
        -(abs(qd / p.stribeck_velocity) ** p.stribeck_exponent)
    )
    return (p.coulomb + stribeck) * _sgn(qd) + p.viscous * qd


def friction_levels(
    qd: Sequence[float],
    coulomb: Sequence[float],
    static: Sequence[float],
    stribeck_velocity: Sequence[float],
    stribeck_exponent: Sequence[float],
    model: FrictionModel,
    rest_velocity: float,
) -> tuple[Sequence[float], Sequence[float]]:
    """Sliding and break-away friction levels of all joints at once, (3.42)-(3.45).

    The two magnitudes a time-stepping friction solve needs (the simulated
    robot's): a joint in motion feels the sliding level opposing it (plus its
    viscous term, not included here); a joint at rest stays at rest while the
    torque on it is within the break-away level.

    Args:
        qd: joint velocities [rad/s, ..., m/s] as Python floats.
        coulomb: Fc per joint [N*m, ..., N].
        static: Fs per joint [N*m, ..., N].
        stribeck_velocity: q̇s per joint [rad/s, ..., m/s].
        stribeck_exponent: δs per joint [-].
        model: which of the models a-d.
        rest_velocity: |q̇| at or below which a joint counts as at rest [rad/s or m/s].

    Returns:
        (slide, brk): slide_i = Fc, plus (Fs - Fc) e^{-|q̇/q̇s|^δs} (3.45) for a
        moving joint under model d; brk_i = Fs at rest under models c and d (3.44),
        else slide_i. For models a and b both are ``coulomb`` itself (not a copy).
    """
    if model is FrictionModel.COULOMB or model is FrictionModel.COULOMB_VISCOUS:
        return coulomb, coulomb
    slide: list[float] = []
    brk: list[float] = []
    stribeck = model is FrictionModel.STRIBECK
    for v, fc, fs, vs, ds in zip(
        qd, coulomb, static, stribeck_velocity, stribeck_exponent, strict=True
    ):
        if abs(v) <= rest_velocity:
            slide.append(fc)
            brk.append(fs)
        else:
            if stribeck:
                fc += (fs - fc) * math.exp(-(abs(v / vs) ** ds))
            slide.append(fc)
            brk.append(fc)
    return slide, brk


def friction_torque(
    qd: Sequence[float] | FloatArray,
    params: Sequence[FrictionParams],
    model: FrictionModel | str = FrictionModel.COULOMB_VISCOUS,
    tau_applied: Sequence[float] | FloatArray | None = None,
) -> FloatArray:
    """Friction torques of all joints, (3.42)-(3.45).

    Args:
        qd: joint velocities [rad/s, ..., m/s].
        params: friction parameters per joint.
        model: a model or its letter ("a"-"d").
        tau_applied: torques applied at rest, for the static models c and d.

    Returns:
        τ_f per joint [N*m, ..., N].
    """
    m = FrictionModel(model)
    n = len(params)
    applied = [0.0] * n if tau_applied is None else [float(t) for t in tau_applied]
    return np.array([joint_friction(float(qd[i]), params[i], m, applied[i]) for i in range(n)])
