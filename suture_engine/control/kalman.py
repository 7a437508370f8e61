"""Kalman velocity observer (5.51-5.56) and the LQG controller it gives with feedback linearisation.

Only joint positions are measured. Around the feedback-linearised robot
``x' = A x + B u + w``, ``y = C x + v`` (5.51-5.52) with ``x = [q; qd]`` and
``u`` the commanded acceleration, the steady-state Kalman gain is
``L = Sigma C^T Ro^-1`` (5.55) with ``Sigma`` the solution of
``A Sigma + Sigma A^T + Qo - Sigma C^T Ro^-1 C Sigma = 0`` (5.56). The observer
``xh' = A xh + B u + L (y - C xh)`` (5.53) runs at the control rate as its
sampled counterpart: the same noise model sampled exactly at the period gives a
steady-state predictor-corrector gain (computed once), so a tick costs three
small matrix-vector products and uses the newest encoder reading.

:class:`LQGController` puts the observer in front of
:class:`~suture_engine.control.lqr.FeedbackLinearizingLQR` (separation
principle, 5.2.3.4, Fig. 5.7).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from suture_engine.control.lqr import FeedbackLinearizingLQR, LqrDesignError, double_integrator
from suture_engine.control.model import ControlModel, FrictionSign, as_floats

__all__ = ["KalmanDesign", "KalmanVelocityObserver", "LQGController", "kalman_gain"]

FloatArray = NDArray[np.float64]


class KalmanDesign(NamedTuple):
    """A steady-state Kalman observer design (5.55-5.56).

    Attributes:
        gain: ``L = Sigma C^T Ro^-1``, shape ``(n, p)``.
        covariance: ``Sigma``, the estimation-error covariance, shape ``(n, n)``.
        poles: eigenvalues of ``A - L C`` [1/s].
    """

    gain: FloatArray
    covariance: FloatArray
    poles: NDArray[np.complex128]


def kalman_gain(a: ArrayLike, c: ArrayLike, qo: ArrayLike, ro: ArrayLike) -> KalmanDesign:
    """Steady-state continuous Kalman gain, the dual of the LQR (5.55-5.56).

    Args:
        a: state matrix.
        c: output matrix.
        qo: process-noise intensity ``E[w w^T]``.
        ro: measurement-noise intensity ``E[v v^T]``.

    Returns:
        The gain, the error covariance and the observer poles.

    Raises:
        LqrDesignError: the dual Riccati equation has no stabilising solution.
    """
    from scipy.linalg import solve_continuous_are

    a_ = np.atleast_2d(np.asarray(a, dtype=float))
    c_ = np.atleast_2d(np.asarray(c, dtype=float))
    qo_ = np.atleast_2d(np.asarray(qo, dtype=float))
    ro_ = np.atleast_2d(np.asarray(ro, dtype=float))
    try:
        sigma = solve_continuous_are(a_.T, c_.T, qo_, ro_)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise LqrDesignError(str(exc)) from exc
    gain = sigma @ c_.T @ np.linalg.inv(ro_)
    poles = np.linalg.eigvals(a_ - gain @ c_)
    if not np.all(poles.real < 0.0):
        raise LqrDesignError(f"observer not stable, poles {poles}")
    return KalmanDesign(gain=gain, covariance=sigma, poles=poles)


class KalmanVelocityObserver:
    """Steady-state Kalman observer of ``[q; qd]`` for ``n`` decoupled double integrators.

    Args:
        n: number of joints.
        dt: control period [s].
        process_noise: acceleration-disturbance intensity per joint ``Qo`` on the
            velocity states [(rad/s^2)^2 s]; larger trusts the encoders more.
        measurement_noise: encoder-noise intensity ``Ro`` per joint [rad^2 s].
    """

    def __init__(
        self,
        n: int,
        dt: float,
        process_noise: float | FloatArray = 1.0e2,
        measurement_noise: float | FloatArray = 1.0e-9,
    ) -> None:
        from scipy.linalg import expm, solve_discrete_are

        self.n = n
        self.dt = float(dt)
        a, b = double_integrator(n)
        c = np.hstack([np.eye(n), np.zeros((n, n))])
        qo = np.zeros((2 * n, 2 * n))
        qo[n:, n:] = np.diag(np.broadcast_to(np.asarray(process_noise, dtype=float), (n,)))
        ro = np.diag(np.broadcast_to(np.asarray(measurement_noise, dtype=float), (n,)))
        self.a, self.b, self.c, self.qo, self.ro = a, b, c, qo, ro
        self.design = kalman_gain(a, c, qo, ro)
        # The same noise model sampled at dt: x[k+1] = Phi x[k] + Gam u[k] + w[k],
        # y[k] = C x[k] + v[k], with Cov(w) the integral of e^{A s} Qo e^{A^T s} over
        # one period (Van Loan) and Var(v) = Ro / dt. Its steady-state predictor-
        # corrector gain is the sampled counterpart of (5.55).
        phi = expm(a * self.dt)
        van = np.zeros((4 * n, 4 * n))
        van[: 2 * n, : 2 * n] = -a * self.dt
        van[: 2 * n, 2 * n :] = qo * self.dt
        van[2 * n :, 2 * n :] = a.T * self.dt
        ev = expm(van)
        qd = ev[2 * n :, 2 * n :].T @ ev[: 2 * n, 2 * n :]
        qd = 0.5 * (qd + qd.T) + 1e-15 * np.eye(2 * n)
        rd = ro / self.dt
        prior = solve_discrete_are(phi.T, c.T, qd, rd)
        self.discrete_gain = prior @ c.T @ np.linalg.inv(c @ prior @ c.T + rd)
        big = np.zeros((3 * n, 3 * n))
        big[: 2 * n, : 2 * n] = a * self.dt
        big[: 2 * n, 2 * n :] = b * self.dt
        self.transition = np.ascontiguousarray(phi)
        self.input_matrix = np.ascontiguousarray(expm(big)[: 2 * n, 2 * n :])
        # The model is n decoupled double integrators: per joint, two gains.
        lg = self.discrete_gain
        self._l1: list[float] = [float(lg[i, i]) for i in range(n)]
        self._l2: list[float] = [float(lg[n + i, i]) for i in range(n)]
        recon = np.zeros_like(lg)
        for i in range(n):
            recon[i, i], recon[n + i, i] = self._l1[i], self._l2[i]
        if not np.allclose(recon, lg, rtol=0.0, atol=1e-9 * np.abs(lg).max()):
            raise LqrDesignError("diagonal noise intensities gave a coupled observer")
        self._xq: list[float] = [0.0] * n
        self._xv: list[float] = [0.0] * n
        self._x = np.zeros(2 * n)
        self._started = False

    def __repr__(self) -> str:
        return f"KalmanVelocityObserver(n={self.n}, dt={self.dt})"

    def reset(self, q: ArrayLike | None = None) -> None:
        """Restart the estimate at position ``q`` at rest (or at the next measurement)."""
        self._x[:] = 0.0
        self._started = q is not None
        if q is not None:
            self._x[: self.n] = q
        self._xq = self._x[: self.n].tolist()
        self._xv = [0.0] * self.n

    @property
    def position(self) -> FloatArray:
        """Estimated positions [rad or m]."""
        return self._x[: self.n]

    @property
    def velocity(self) -> FloatArray:
        """Estimated velocities [rad/s or m/s]."""
        return self._x[self.n :]

    def update(self, y: FloatArray, u: FloatArray) -> FloatArray:
        """Predict over one period with the held command ``u``, then correct with ``y``.

        Args:
            y: joint positions measured now [rad or m].
            u: acceleration command applied over the last period [rad/s^2 or m/s^2].

        Returns:
            The state estimate ``[q; qd]``; internal storage.
        """
        yl, ul = as_floats(y), as_floats(u)
        n = self.n
        if not self._started:
            self._xq = yl
            self._x[:n] = yl
            self._started = True
            return self._x
        dt, h2 = self.dt, 0.5 * self.dt * self.dt
        xq, xv, l1, l2 = self._xq, self._xv, self._l1, self._l2
        for i in range(n):
            qp = xq[i] + dt * xv[i] + h2 * ul[i]  # predict (exact for q'' = u)
            vp = xv[i] + dt * ul[i]
            r = yl[i] - qp  # correct
            xq[i] = qp + l1[i] * r
            xv[i] = vp + l2[i] * r
        self._x[:n] = xq
        self._x[n:] = xv
        return self._x


class LQGController:
    """LQG: the Kalman velocity observer feeding the feedback-linearising LQR (5.2.3.4).

    Args:
        model: the estimated dynamics.
        dt: control period [s].
        lqr: keyword arguments for :class:`FeedbackLinearizingLQR` (weights, integral, ...).
        process_noise: observer ``Qo`` per joint, see :class:`KalmanVelocityObserver`.
        measurement_noise: observer ``Ro`` per joint.
    """

    def __init__(
        self,
        model: ControlModel,
        dt: float,
        *,
        process_noise: float | FloatArray = 1.0e2,
        measurement_noise: float | FloatArray = 1.0e-9,
        **lqr: object,
    ) -> None:
        lqr.setdefault("friction_sign", FrictionSign.DESIRED)
        self.controller = FeedbackLinearizingLQR(model, dt, **lqr)  # type: ignore[arg-type]
        self.observer = KalmanVelocityObserver(model.n, dt, process_noise, measurement_noise)
        self._u_prev = np.zeros(model.n)

    def __repr__(self) -> str:
        return f"LQGController({self.controller!r}, {self.observer!r})"

    def reset(self, q: ArrayLike | None = None) -> None:
        """Clear the integral state and restart the observer."""
        self.controller.reset()
        self.observer.reset(q)
        self._u_prev[:] = 0.0

    def update(
        self,
        q_measured: FloatArray,
        q_des: FloatArray,
        qd_des: FloatArray,
        qdd_des: FloatArray | None = None,
    ) -> FloatArray:
        """One tick from the encoder positions only.

        Args:
            q_measured: encoder positions [rad, m].
            q_des: reference positions.
            qd_des: reference velocities.
            qdd_des: reference accelerations; ``None`` means zero.

        Returns:
            Joint torques/forces [N m, N]; internal storage.
        """
        x = self.observer.update(q_measured, self._u_prev)
        n = self.controller.n
        tau = self.controller.update(q_measured, x[n:], q_des, qd_des, qdd_des)
        self._u_prev[:] = self.controller.last_acceleration_command
        return tau
