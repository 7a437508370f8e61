"""Feedback linearisation (5.21) with an LQR outer loop (5.44-5.45) and integral action (5.60-5.62).

The inner loop ``tau = M^(q) u + C^(q, qd) qd + G^(q) + N^(qd)`` (5.21) turns the
robot into ``n`` decoupled double integrators ``x' = A x + B u`` (5.24-5.27).
The outer loop is the infinite-horizon LQR ``u = -K x`` with ``K = R^-1 B^T P``
and ``P`` the solution of the algebraic Riccati equation (5.44-5.45), acting on
the tracking error ``x~ = x - x_d`` (5.57) augmented with the integral of the
position error (5.60-5.62). The reference acceleration is fed forward, so the
law tracks moving references, not only set-points.

Gains are computed once, at construction, with
:func:`scipy.linalg.solve_continuous_are`; :meth:`FeedbackLinearizingLQR.update`
only does matrix-vector products.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from suture_engine.control.model import ControlModel, FrictionSign, as_floats, coulomb_sign
from suture_engine.errors import SutureError

__all__ = [
    "FeedbackLinearizingLQR",
    "LqrDesign",
    "LqrDesignError",
    "LqrWeights",
    "double_integrator",
    "integral_augmented",
    "lqr_gain",
]

FloatArray = NDArray[np.float64]


class LqrDesignError(SutureError):
    """The Riccati equation has no stabilising solution for the given weights.

    Attributes:
        reason: what scipy or the checks reported.
    """

    code = "lqr-design"

    def __init__(self, reason: str) -> None:
        super().__init__(f"LQR design failed: {reason}")
        self.reason = reason


class LqrDesign(NamedTuple):
    """An LQR design (5.44-5.45).

    Attributes:
        gain: ``K = R^-1 B^T P``, shape ``(m, n)``.
        riccati: ``P``, the stabilising ARE solution, shape ``(n, n)``.
        poles: eigenvalues of ``A - B K`` [1/s].
    """

    gain: FloatArray
    riccati: FloatArray
    poles: NDArray[np.complex128]


class LqrWeights(NamedTuple):
    """Diagonal LQR weights for one joint's augmented error state (5.43, 5.61).

    Scalars apply to every joint; arrays give one value per joint. The defaults
    put each joint's error poles near ``-31 +- 31j`` and ``-5`` [1/s], a
    bandwidth comparable with the 7 Hz PD of (5.17).

    Attributes:
        position: weight on the position error ``q - q_d`` [1/rad^2].
        velocity: weight on the velocity error [s^2/rad^2].
        integral: weight on the integrated position error [1/(rad^2 s^2)]; 0 with
            ``integral=False`` controllers.
        effort: ``rho`` in ``R = rho I`` on the commanded acceleration [s^4/rad^2].
    """

    position: float | FloatArray = 4.0e6
    velocity: float | FloatArray = 1.0e2
    integral: float | FloatArray = 1.0e8
    effort: float | FloatArray = 1.0


def double_integrator(n: int) -> tuple[FloatArray, FloatArray]:
    """``A = [[0, I], [0, 0]]``, ``B = [[0], [I]]`` of the linearised robot (5.26).

    Args:
        n: number of joints.

    Returns:
        ``(A, B)`` with state ``[q; qd]`` (5.24), shapes ``(2n, 2n)`` and ``(2n, n)``.
    """
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    b = np.zeros((2 * n, n))
    b[n:, :] = np.eye(n)
    return a, b


def integral_augmented(
    a: FloatArray, b: FloatArray, c: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Augment ``(A, B)`` with the integral ``x_i' = C x~`` of the output error (5.60-5.61).

    Args:
        a: state matrix, ``(n, n)``.
        b: input matrix, ``(n, m)``.
        c: output matrix, ``(p, n)``.

    Returns:
        ``(A_bar, B_bar)`` with state ``[x~; x_i]``.
    """
    n, m = b.shape
    p = c.shape[0]
    a_bar = np.zeros((n + p, n + p))
    a_bar[:n, :n] = a
    a_bar[n:, :n] = c
    b_bar = np.zeros((n + p, m))
    b_bar[:n, :] = b
    return a_bar, b_bar


def lqr_gain(a: ArrayLike, b: ArrayLike, q: ArrayLike, r: ArrayLike) -> LqrDesign:
    """Infinite-horizon continuous LQR gain (5.43-5.45).

    Args:
        a: state matrix.
        b: input matrix.
        q: state weight, symmetric positive semidefinite.
        r: input weight, symmetric positive definite.

    Returns:
        The gain, the Riccati solution and the closed-loop poles.

    Raises:
        LqrDesignError: no stabilising solution (uncontrollable or undetectable pair).
    """
    from scipy.linalg import solve_continuous_are

    a_ = np.atleast_2d(np.asarray(a, dtype=float))
    b_ = np.atleast_2d(np.asarray(b, dtype=float))
    q_ = np.atleast_2d(np.asarray(q, dtype=float))
    r_ = np.atleast_2d(np.asarray(r, dtype=float))
    try:
        p = solve_continuous_are(a_, b_, q_, r_)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise LqrDesignError(str(exc)) from exc
    k = np.linalg.solve(r_, b_.T @ p)
    poles = np.linalg.eigvals(a_ - b_ @ k)
    if not np.all(poles.real < 0.0):
        raise LqrDesignError(f"closed loop not stable, poles {poles}")
    return LqrDesign(gain=k, riccati=p, poles=poles)


def _per_joint(value: float | FloatArray, n: int) -> FloatArray:
    arr = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
    return arr


class FeedbackLinearizingLQR:
    """Computed-torque control (5.21) with an LQR / LQR+integral outer loop (5.44, 5.62).

    ``tau = M^(q) u + C^(q, qd) qd + G^(q) + N^(qd)`` with
    ``u = qdd_d - K [q - q_d; qd - qd_d; integral(q - q_d)]``.

    Args:
        model: the estimated dynamics ``M^, C^, G^, N^``.
        dt: control period [s], used to integrate the position error.
        weights: LQR weights per joint.
        integral: augment with the integral of the position error (5.60-5.62).
        integral_limit: anti-windup bound on each integral state [rad s].
        friction_sign: where the Coulomb compensation takes its sign from.
        friction_deadband: speed below which the Coulomb sign ramps [rad/s].
        coriolis: include ``C^ qd`` (the thesis drops it at low speed).
    """

    def __init__(
        self,
        model: ControlModel,
        dt: float,
        weights: LqrWeights | None = None,
        *,
        integral: bool = True,
        integral_limit: float = 0.05,
        friction_sign: FrictionSign = FrictionSign.DESIRED,
        friction_deadband: float = 0.0,
        coriolis: bool = True,
    ) -> None:
        self.model = model
        self.n = n = model.n
        self.dt = float(dt)
        self.weights = weights if weights is not None else LqrWeights()
        self.integral = integral
        self.integral_limit = float(integral_limit)
        self.friction_sign = friction_sign
        self.friction_deadband = float(friction_deadband)
        self.coriolis = coriolis
        a, b = double_integrator(n)
        w = self.weights
        diag = [_per_joint(w.position, n), _per_joint(w.velocity, n)]
        if integral:
            c = np.hstack([np.eye(n), np.zeros((n, n))])
            a, b = integral_augmented(a, b, c)
            diag.append(_per_joint(w.integral, n))
        q_w = np.diag(np.concatenate(diag))
        self.design = lqr_gain(a, b, q_w, np.diag(_per_joint(w.effort, n)))
        self.gain = self.design.gain
        # Diagonal weights give a joint-decoupled gain: u_i = -(kp e_i + kv e'_i + ki x_i).
        blocks = [np.diag(self.gain[:, k * n : (k + 1) * n]) for k in range(len(diag))]
        self._kp: list[float] = blocks[0].tolist()
        self._kv: list[float] = blocks[1].tolist()
        self._ki: list[float] = blocks[2].tolist() if integral else [0.0] * n
        recon = np.hstack([np.diag(b) for b in blocks])
        if not np.allclose(recon, self.gain, rtol=0.0, atol=1e-9 * np.abs(self.gain).max()):
            raise LqrDesignError("diagonal weights gave a coupled gain")
        self._xi: list[float] = [0.0] * n
        self._fc: list[float] = np.asarray(model.coulomb, dtype=float).tolist()
        self._fv: list[float] = np.asarray(model.viscous, dtype=float).tolist()
        self._u = np.zeros(n)
        self._tau = np.zeros(n)

    def __repr__(self) -> str:
        return (
            f"FeedbackLinearizingLQR(n={self.n}, dt={self.dt}, weights={self.weights}, "
            f"integral={self.integral})"
        )

    def reset(self) -> None:
        """Clear the integral state (call on entering the controlling state)."""
        self._xi = [0.0] * self.n

    @property
    def integral_state(self) -> FloatArray:
        """The integrated position errors [rad s, m s]."""
        return np.array(self._xi)

    @property
    def last_acceleration_command(self) -> FloatArray:
        """The outer loop's last ``u`` [rad/s^2], the linearised plant's input (5.27)."""
        return self._u

    def update(
        self,
        q: FloatArray,
        qd: FloatArray,
        q_des: FloatArray,
        qd_des: FloatArray,
        qdd_des: FloatArray | None = None,
    ) -> FloatArray:
        """One control tick.

        Args:
            q: joint positions [rad, rad, rad, m].
            qd: joint velocities, measured or estimated [rad/s, m/s].
            q_des: reference positions.
            qd_des: reference velocities.
            qdd_des: reference accelerations (feed-forward); ``None`` means zero.

        Returns:
            Joint torques/forces [N m, N]; internal storage overwritten next call.
        """
        ql, vl = as_floats(q), as_floats(qd)
        qrl, vrl = as_floats(q_des), as_floats(qd_des)
        al = as_floats(qdd_des) if qdd_des is not None else [0.0] * self.n
        kp, kv, ki, xi = self._kp, self._kv, self._ki, self._xi
        lim, dt = self.integral_limit, self.dt
        ul = []
        for i in range(self.n):
            e = ql[i] - qrl[i]
            if self.integral:
                x = xi[i] + e * dt
                xi[i] = lim if x > lim else (-lim if x < -lim else x)
            ul.append(al[i] - kp[i] * e - kv[i] * (vl[i] - vrl[i]) - ki[i] * xi[i])
        u = self._u
        u[:] = ul
        tau = self._tau
        np.dot(self.model.mass_matrix(q), u, out=tau)
        if self.coriolis:
            tau += self.model.coriolis_torque(q, qd)
        tau += self.model.gravity_vector(q)
        src = vrl if self.friction_sign is FrictionSign.DESIRED else vl
        fc, fv, db = self._fc, self._fv, self.friction_deadband
        tau += [fc[i] * coulomb_sign(v, db) + fv[i] * v for i, v in enumerate(src)]
        return tau
