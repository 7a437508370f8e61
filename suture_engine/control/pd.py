"""PD control with gravity and Coulomb friction compensation (5.10, 5.19).

``tau = -Kp e - Kd e' + G^(q) + Fc^ sgn(qd)`` with ``e = q - q_d``. With the
Coriolis terms neglected and ``M(q)`` frozen at a constant diagonal ``M``, the
error dynamics ``M e'' + Kd e' + Kp e = 0`` (5.14) are critically damped at
natural frequency ``w`` by ``Kp = w^2 M`` and ``Kd = 2 sqrt(Kp M)`` (5.15-5.16).
The energy-based Lyapunov argument (5.5-5.12) makes the law globally
asymptotically stable for any positive gains.

Against the thesis' 7 Hz gains (5.17-5.18): the printed
``Kp = diag(97, 97, 1.93, 193)`` and ``Kd = diag(4.4, 4.4, 0.088, 8.8)`` follow
from a frozen ``M ~ diag(0.050, 0.050, 0.001, 0.100)``. Table 3.4's E1 values
at the workspace centre (``q4 = 0.10`` m) give ``M = diag(0.0462, 0.0416,
0.0006, 0.2451)``, hence ``Kp = diag(89.5, 80.6, 1.16, 474)`` and
``Kd = diag(4.07, 3.66, 0.053, 21.6)``: yaw and pitch 8 % and 17 % below the
printed gains; roll (0.6x) and insertion (2.45x) follow Table 3.4's roll inertia
and insertion mass, not the values behind (5.17).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from suture_engine.control.model import ControlModel, FrictionSign, as_floats, coulomb_sign
from suture_engine.errors import SutureError

_DESIRED = FrictionSign.DESIRED  # bound once: Enum.X on the class costs ~60 ns (CPython 3.11)

__all__ = [
    "WORKSPACE_CENTRE",
    "GainError",
    "PDController",
    "PDGains",
    "critically_damped_gains",
    "gains_at_workspace_centre",
]

FloatArray = NDArray[np.float64]

if TYPE_CHECKING:
    from suture_engine.robot.params import EndoBotParams

WORKSPACE_CENTRE: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.10)
"""Centre of the joint workspace [rad, rad, rad, m]: arches and roll centred, the
insertion at mid-stroke of its 0-0.20 m travel. The thesis freezes M here for
gain design (5.2.2)."""


class GainError(SutureError):
    """A gain design got a non-physical input.

    Attributes:
        name: the parameter's name.
        value: the offending value.
    """

    code = "gain"

    def __init__(self, name: str, value: object) -> None:
        super().__init__(f"{name}={value!r} must be positive and finite")
        self.name = name
        self.value = value


class PDGains(NamedTuple):
    """Diagonal PD gains.

    Attributes:
        kp: proportional gains [N m/rad, N/m], shape ``(n,)``.
        kd: derivative gains [N m s/rad, N s/m], shape ``(n,)``.
    """

    kp: FloatArray
    kd: FloatArray


def critically_damped_gains(natural_frequency: float, inertia: ArrayLike) -> PDGains:
    """``Kp = w^2 M``, ``Kd = 2 sqrt(Kp M)`` (5.15-5.16).

    Args:
        natural_frequency: closed-loop natural frequency ``w`` [rad/s].
        inertia: diagonal of the frozen inertia matrix ``M`` [kg m^2, kg].

    Returns:
        The gains; the error dynamics (5.14) then have a double pole at ``-w``.

    Raises:
        GainError: non-positive frequency or inertia.
    """
    w = float(natural_frequency)
    m = np.asarray(inertia, dtype=float).ravel()
    if not np.isfinite(w) or w <= 0.0:
        raise GainError("natural_frequency", natural_frequency)
    if not np.all(np.isfinite(m)) or np.any(m <= 0.0):
        raise GainError("inertia", m.tolist())
    kp = w * w * m
    return PDGains(kp=kp, kd=2.0 * np.sqrt(kp * m))


def gains_at_workspace_centre(
    frequency_hz: float = 7.0,
    params: EndoBotParams | None = None,
    q_centre: ArrayLike = WORKSPACE_CENTRE,
) -> PDGains:
    """Critically damped gains with ``M`` taken at the workspace centre (5.2.2, 5.17-5.18).

    Args:
        frequency_hz: natural frequency [Hz]; the thesis uses 7 Hz.
        params: EndoBot parameters; ``None`` means E1.
        q_centre: the configuration at which ``M(q)`` is evaluated [rad, m].

    Returns:
        Gains from the diagonal of ``M(q_centre)``.
    """
    from suture_engine.robot import endobot

    m = np.diag(np.asarray(endobot.mass_matrix(np.asarray(q_centre, dtype=float), params)))
    return critically_damped_gains(2.0 * np.pi * float(frequency_hz), m)


class PDController:
    """PD with gravity and Coulomb friction compensation (5.10, 5.19).

    Args:
        gains: diagonal ``Kp``, ``Kd``.
        model: the estimated dynamics (gravity and Coulomb coefficients are used).
        gravity: add ``G^(q)``.
        friction: add ``Fc^ sgn(v)`` (5.19); ``False`` reproduces the
            "compensation off" rows of Table 5.1.
        friction_sign: which velocity the sign comes from.
        friction_deadband: speed below which the sign ramps linearly [rad/s].
    """

    def __init__(
        self,
        gains: PDGains,
        model: ControlModel,
        *,
        gravity: bool = True,
        friction: bool = True,
        friction_sign: FrictionSign = FrictionSign.DESIRED,
        friction_deadband: float = 0.0,
    ) -> None:
        self.gains = PDGains(np.asarray(gains.kp, dtype=float), np.asarray(gains.kd, dtype=float))
        self.model = model
        self.gravity = gravity
        self.friction = friction
        self.friction_sign = friction_sign
        self.friction_deadband = float(friction_deadband)
        n = model.n
        # Plain floats per joint: for 4 joints this beats numpy's per-call overhead.
        self._kp: list[float] = self.gains.kp.tolist()
        self._kd: list[float] = self.gains.kd.tolist()
        self._fc: list[float] = np.asarray(model.coulomb, dtype=float).tolist()
        self._zeros: list[float] = [0.0] * n
        self._gravity_floats = model.gravity_floats

    def __repr__(self) -> str:
        return (
            f"PDController(kp={self.gains.kp.tolist()}, kd={self.gains.kd.tolist()}, "
            f"gravity={self.gravity}, friction={self.friction})"
        )

    def update(
        self, q: FloatArray, qd: FloatArray, q_des: FloatArray, qd_des: FloatArray
    ) -> FloatArray:
        """One control tick (5.10).

        Args:
            q: joint positions [rad, m].
            qd: joint velocities, measured or estimated [rad/s, m/s].
            q_des: reference positions.
            qd_des: reference velocities.

        Returns:
            Joint torques/forces [N m, N], a fresh array.
        """
        ql, vl, qrl, vrl = as_floats(q), as_floats(qd), as_floats(q_des), as_floats(qd_des)
        if not self.gravity:
            g = self._zeros
        elif self._gravity_floats is not None:
            g = self._gravity_floats(ql)
        else:
            g = self.model.gravity_vector(q).tolist()
        kp, kd = self._kp, self._kd
        out = [g[i] - kp[i] * (ql[i] - qrl[i]) - kd[i] * (vl[i] - vrl[i]) for i in range(len(ql))]
        if self.friction:
            src = vrl if self.friction_sign is _DESIRED else vl
            fc, db = self._fc, self.friction_deadband
            if db > 0.0:
                for i, v in enumerate(src):
                    out[i] += fc[i] * coulomb_sign(v, db)
            else:  # hard sign, inlined: this is the 1 kHz path
                for i, v in enumerate(src):
                    if v > 0.0:
                        out[i] += fc[i]
                    elif v < 0.0:
                        out[i] -= fc[i]
        return np.array(out)
