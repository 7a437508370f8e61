"""The public EndoBot API: kinematics, dynamics and friction of one robot (chapter 3).

``params=None`` means the thesis' EndoBot 1 (:data:`~suture_engine.robot.params.E1`).
This module imports neither pybullet nor scipy, so the validator can use it.

Example:
    >>> from suture_engine.robot import endobot
    >>> pose = endobot.forward_kinematics([0.1, -0.2, 0.0, 0.12])
    >>> q = endobot.inverse_kinematics(pose.position, pose.roll)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from suture_engine.robot import dynamics as _dyn
from suture_engine.robot.friction import FrictionModel
from suture_engine.robot.friction import friction_torque as _friction_torque
from suture_engine.robot.kinematics import (
    SINGULARITY_MARGIN,
    ToolPose,
    UnreachablePose,
    forward_kinematics,
    geometric_jacobian,
    inverse_kinematics,
    is_singular,
    jacobian_determinant,
    manipulability,
    rotation,
)
from suture_engine.robot.kinematics import analytical_jacobian as jacobian
from suture_engine.robot.params import E1, E2, EndoBotParams

__all__ = [
    "E1",
    "E2",
    "SINGULARITY_MARGIN",
    "EndoBotParams",
    "FrictionModel",
    "ToolPose",
    "UnreachablePose",
    "coriolis_matrix",
    "coriolis_vector",
    "forward_kinematics",
    "friction_torque",
    "geometric_jacobian",
    "gravity_vector",
    "inverse_dynamics",
    "inverse_kinematics",
    "is_singular",
    "jacobian",
    "jacobian_determinant",
    "manipulability",
    "mass_matrix",
    "regressor",
    "rotation",
]

FloatArray = NDArray[np.float64]
Vec = Sequence[float] | FloatArray


def mass_matrix(q: Vec, params: EndoBotParams | None = None) -> FloatArray:
    """Mass-inertia matrix M(q) (3.38), derived.

    Args:
        q: joints [rad, rad, rad, m].
        params: robot parameters (None: E1).

    Returns:
        4x4 symmetric positive definite M(q).
    """
    return _dyn.mass_matrix(q, (params or E1).coefficients)


def coriolis_matrix(q: Vec, qd: Vec, params: EndoBotParams | None = None) -> FloatArray:
    """Coriolis/centrifugal matrix C(q, q̇) (3.40), Christoffel form, Ṁ - 2C skew (3.33).

    Args:
        q: joints [rad, rad, rad, m].
        qd: joint velocities [rad/s, rad/s, rad/s, m/s].
        params: robot parameters (None: E1).

    Returns:
        4x4 C(q, q̇).
    """
    return _dyn.coriolis_matrix(q, qd, (params or E1).coefficients)


def coriolis_vector(q: Vec, qd: Vec, params: EndoBotParams | None = None) -> FloatArray:
    """C(q, q̇) q̇ [N*m, N*m, N*m, N] (3.40).

    Args:
        q: joints [rad, rad, rad, m].
        qd: joint velocities [rad/s, rad/s, rad/s, m/s].
        params: robot parameters (None: E1).

    Returns:
        Shape (4,) torques.
    """
    return _dyn.coriolis_vector(q, qd, (params or E1).coefficients)


def gravity_vector(
    q: Vec, params: EndoBotParams | None = None, out: FloatArray | None = None
) -> FloatArray:
    """Gravity torques G(q) (3.41), derived, in the gravity of ``params.gravity``.

    Args:
        q: joints [rad, rad, rad, m].
        params: robot parameters (None: E1).
        out: optional preallocated (4,) array.

    Returns:
        G(q) [N*m, N*m, N*m, N].
    """
    p = params or E1
    return _dyn.gravity_vector(q, p.coefficients, p.gravity, out)


def inverse_dynamics(q: Vec, qd: Vec, qdd: Vec, params: EndoBotParams | None = None) -> FloatArray:
    """Rigid-body torques M q̈ + C q̇ + G (3.32), friction excluded.

    Args:
        q: joints [rad, rad, rad, m].
        qd: joint velocities [rad/s, rad/s, rad/s, m/s].
        qdd: joint accelerations [rad/s^2, rad/s^2, rad/s^2, m/s^2].
        params: robot parameters (None: E1).

    Returns:
        Shape (4,) torques [N*m, N*m, N*m, N].
    """
    p = params or E1
    return _dyn.inverse_dynamics(q, qd, qdd, p.coefficients, p.gravity)


def regressor(q: Vec, qd: Vec, qdd: Vec, params: EndoBotParams | None = None) -> FloatArray:
    """Regressor Y with Y θ = M q̈ + C q̇ + G (3.34); θ = ``params.coefficients``.

    Args:
        q: joints [rad, rad, rad, m].
        qd: joint velocities [rad/s, rad/s, rad/s, m/s].
        qdd: joint accelerations [rad/s^2, rad/s^2, rad/s^2, m/s^2].
        params: robot parameters (None: E1); only its gravity is used.

    Returns:
        4x8 regressor.
    """
    return _dyn.regressor(q, qd, qdd, (params or E1).gravity)


def friction_torque(
    qd: Vec,
    params: EndoBotParams | None = None,
    model: FrictionModel | str = FrictionModel.COULOMB_VISCOUS,
    tau_applied: Vec | None = None,
) -> FloatArray:
    """Joint friction torques by model a-d (3.42)-(3.45).

    Args:
        qd: joint velocities [rad/s, rad/s, rad/s, m/s].
        params: robot parameters (None: E1).
        model: friction model or its letter; default b (3.43), as identified.
        tau_applied: torques applied at rest, for the static models c and d.

    Returns:
        τ_f [N*m, N*m, N*m, N], with the sign of q̇ (on the left of (3.60)).
    """
    p = params or E1
    return _friction_torque(qd, [j.friction for j in p.joints], model, tau_applied)
