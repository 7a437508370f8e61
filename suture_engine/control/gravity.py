"""Gravity compensation for Manual mode (5.1-5.2).

In Manual mode the motors are back-drivable and the surgeon moves the tool by
hand; the controller only holds the arm's weight, ``tau = G^(q)`` (5.1), so the
surgeon feels neither the arm's weight nor a drift when letting go.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from suture_engine.control.model import ControlModel

__all__ = ["GravityCompensation"]

FloatArray = NDArray[np.float64]


class GravityCompensation:
    """``tau = G^(q)`` (5.1) with ``G^`` the model's gravity vector (5.2).

    Args:
        model: the estimated dynamics (only ``gravity_vector`` is used).
        scale: fraction of the weight compensated (1 = all) [-].
    """

    def __init__(self, model: ControlModel, scale: float = 1.0) -> None:
        self.model = model
        self.scale = float(scale)
        self._tau = np.zeros(model.n)

    def __repr__(self) -> str:
        return f"GravityCompensation(scale={self.scale})"

    def update(self, q: FloatArray) -> FloatArray:
        """Torques [N m, N] that hold the arm at ``q`` [rad, m]; internal storage."""
        g = self.model.gravity_vector(q)
        if self.scale == 1.0:
            self._tau[:] = g
        else:
            np.multiply(g, self.scale, out=self._tau)
        return self._tau
