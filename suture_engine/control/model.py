"""The robot model a controller compensates with: M^, C^, G^ and the friction estimate.

Controllers of chapter 5 cancel (5.21) or compensate (5.10, 5.19) the robot's
dynamics with an *estimate* of them, which in general differs from the robot
they drive. :class:`ControlModel` bundles that estimate as plain callables plus
the Coulomb and viscous friction coefficients, so the same controller can run on
the thesis' E1 parameters, on identified ones, or on a deliberately wrong model.

:func:`endobot_control_model` builds one from ``suture_engine.robot.endobot``
(imported lazily).
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ControlModel",
    "FrictionSign",
    "as_floats",
    "coulomb_sign",
    "endobot_control_model",
    "friction_compensation",
]

FloatArray = NDArray[np.float64]

if TYPE_CHECKING:
    from suture_engine.robot.params import EndoBotParams


@dataclass(frozen=True)
class ControlModel:
    """The estimated dynamics a controller uses.

    Attributes:
        mass_matrix: ``q -> M^(q)`` [kg m^2 / kg], shape ``(n, n)`` (3.38-3.39).
        coriolis_matrix: ``(q, qd) -> C^(q, qd)``, shape ``(n, n)`` (3.40).
        gravity_vector: ``q -> G^(q)`` [N m / N], shape ``(n,)`` (3.41, 5.2). The
            EndoBot model returns one reused buffer: copy the result to keep it.
        coulomb: estimated Coulomb coefficients ``Fc^`` [N m / N], shape ``(n,)`` (5.19).
        viscous: estimated viscous coefficients ``Fv^`` [N m s / N s], shape ``(n,)``.
        coriolis_vector: optional ``(q, qd) -> C^(q, qd) qd``, cheaper than the matrix
            when only the product is needed.
        gravity_floats: optional ``G^(q)`` on Python floats (joints as a list) [N m / N]:
            the same numbers as ``gravity_vector`` without an array each way (the PD
            law's per-tick path).
    """

    mass_matrix: Callable[[FloatArray], FloatArray]
    coriolis_matrix: Callable[[FloatArray, FloatArray], FloatArray]
    gravity_vector: Callable[[FloatArray], FloatArray]
    coulomb: FloatArray
    viscous: FloatArray
    coriolis_vector: Callable[[FloatArray, FloatArray], FloatArray] | None = None
    gravity_floats: Callable[[list[float]], list[float]] | None = None

    def coriolis_torque(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        """``C^(q, qd) qd`` [N m, N] (3.40).

        Args:
            q: joint positions [rad, m].
            qd: joint velocities [rad/s, m/s].

        Returns:
            The Coriolis and centrifugal torques.
        """
        if self.coriolis_vector is not None:
            return self.coriolis_vector(q, qd)
        return self.coriolis_matrix(q, qd) @ qd

    @property
    def n(self) -> int:
        """Number of joints."""
        return int(self.coulomb.shape[0])


def endobot_control_model(
    params: EndoBotParams | None = None, *, friction_scale: float = 1.0
) -> ControlModel:
    """A :class:`ControlModel` from the EndoBot model of ``suture_engine.robot``.

    Args:
        params: an EndoBot parameter set; ``None`` means the thesis' E1 values.
        friction_scale: multiplies the friction estimate (``0`` switches friction
            compensation off, for the off/on experiments of Table 5.1).

    Returns:
        The model, whose callables close over ``params``.
    """
    from suture_engine.robot import endobot

    p = params if params is not None else endobot.E1
    fc = np.array([j.friction.coulomb for j in p.joints])
    fv = np.array([j.friction.viscous for j in p.joints])
    g_out = np.zeros(4)

    def mass(q: FloatArray) -> FloatArray:
        return np.asarray(endobot.mass_matrix(q, p))

    def coriolis(q: FloatArray, qd: FloatArray) -> FloatArray:
        return np.asarray(endobot.coriolis_matrix(q, qd, p))

    def gravity(q: FloatArray) -> FloatArray:
        return endobot.gravity_vector(q, p, g_out)

    def coriolis_vec(q: FloatArray, qd: FloatArray) -> FloatArray:
        return endobot.coriolis_vector(q, qd, p)

    from suture_engine.robot.dynamics import gravity_floats as _gravity_floats

    theta, g_base = p.coefficients, p.gravity

    def gravity_list(qf: list[float]) -> list[float]:
        return _gravity_floats(qf, theta, g_base)

    return ControlModel(
        mass_matrix=mass,
        coriolis_matrix=coriolis,
        gravity_vector=gravity,
        coulomb=fc * friction_scale,
        viscous=fv * friction_scale,
        coriolis_vector=coriolis_vec,
        gravity_floats=gravity_list,
    )


class FrictionSign(enum.Enum):
    """Which velocity the Coulomb compensation ``Fc^ sgn(.)`` (5.19) takes its sign from."""

    MEASURED = "measured"
    """The measured or estimated joint velocity, as printed in (5.19)."""
    DESIRED = "desired"
    """The reference velocity: immune to velocity-estimate noise around zero speed."""


def as_floats(x: FloatArray | list[float] | tuple[float, ...]) -> list[float]:
    """A vector as a list of Python floats (cheap for the short vectors of one robot)."""
    return x.tolist() if isinstance(x, np.ndarray) else [float(v) for v in x]


def coulomb_sign(v: float, deadband: float = 0.0) -> float:
    """``sgn(v)`` of (5.19), ramping linearly inside ``+-deadband`` when it is positive.

    Args:
        v: velocity [rad/s or m/s].
        deadband: half-width of the linear ramp around zero [rad/s or m/s]; 0 for a hard sign.

    Returns:
        The sign in [-1, 1].
    """
    if deadband > 0.0:
        x = v / deadband
        return 1.0 if x > 1.0 else (-1.0 if x < -1.0 else x)
    return 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)


def friction_compensation(
    model: ControlModel,
    velocity: FloatArray,
    out: FloatArray,
    *,
    deadband: float = 0.0,
    viscous: bool = False,
) -> FloatArray:
    """Write the friction feed-forward ``Fc^ sgn(v) [+ Fv^ v]`` (5.19, 3.43) into ``out``.

    Args:
        model: the friction estimate.
        velocity: the velocity the sign is taken from [rad/s or m/s].
        out: preallocated output [N m or N], shape ``(n,)``.
        deadband: below this speed the sign ramps linearly (0 gives a hard sign) [rad/s].
        viscous: also add the viscous term ``Fv^ v``.

    Returns:
        ``out``.
    """
    if deadband > 0.0:
        np.divide(velocity, deadband, out=out)
        np.clip(out, -1.0, 1.0, out=out)
    else:
        np.sign(velocity, out=out)
    out *= model.coulomb
    if viscous:
        out += model.viscous * velocity
    return out
