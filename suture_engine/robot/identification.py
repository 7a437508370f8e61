"""Identification of the EndoBot's dynamic parameters, one joint at a time (3.5).

Each joint is excited alone while the others are held at their synchronisation
positions, so it behaves as the one-link manipulator (3.73)
``I q'' + ml g s(q) + Fc sgn(q') + Fv q' = tau`` where ``s(q)`` is the joint's
gravity shape (``sin q`` for yaw and pitch, none for roll, a constant for the
insertion stage, whose ``ml`` column then carries its weight).

The procedure follows the thesis:

1. friction first, from a constant-velocity loop (Fig. 3.17, 3.5.3.1):
   :func:`fit_friction` regresses the steady torques on ``[g s(q), sgn v, v]``;
2. inertia and gravity moment by least squares (3.52) with either the
   differential model (3.60-3.64, 3.74) -- :func:`differential_regressor`,
   accelerations from zero-phase filtered positions -- or the energy model
   (3.65-3.75) -- :func:`energy_regressor`, no accelerations, with the friction
   found in step 1 subtracted, because its Coulomb and viscous columns are
   nearly collinear (Table 3.2, :func:`column_correlation`);
3. validation (3.5.4): the residual of (3.80) and its cross-correlation with
   the input (3.77), :func:`validate`.

The functions here work on recorded arrays; the experiments on the simulated
robot are in :mod:`suture_engine.robot.identification_experiment`.
"""

from __future__ import annotations

import enum
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from suture_engine.errors import SutureError

__all__ = [
    "FrictionEstimate",
    "GravityShape",
    "IdentificationError",
    "JointEstimate",
    "Validation",
    "column_correlation",
    "differential_regressor",
    "differential_rows",
    "energy_regressor",
    "estimate_motion",
    "fit_differential",
    "fit_energy",
    "fit_friction",
    "least_squares",
    "validate",
]

FloatArray = NDArray[np.float64]
GRAVITY = 9.81
"""Standard gravity [m/s^2]."""


class IdentificationError(SutureError):
    """The data cannot identify the parameters (too short, not exciting, rank deficient).

    Attributes:
        reason: what is wrong.
        condition: condition number of the regressor, when it was computed.
    """

    code = "identification"

    def __init__(self, reason: str, condition: float | None = None) -> None:
        super().__init__(f"identification failed: {reason}")
        self.reason = reason
        self.condition = condition


class GravityShape(str, enum.Enum):
    """How gravity enters a single-joint model: ``G = ml g s(q)``."""

    SINE = "sine"
    """Revolute joint swinging about the hanging pose: ``s(q) = sin q`` (yaw, pitch)."""
    NONE = "none"
    """No gravity torque (roll about the tool axis)."""
    CONSTANT = "constant"
    """Constant force, ``s(q) = -1`` (insertion along a vertical tool; ``ml`` is the mass)."""

    def shape(self, q: FloatArray) -> FloatArray:
        """``s(q)`` [-]."""
        if self is GravityShape.SINE:
            return np.sin(q)
        if self is GravityShape.CONSTANT:
            return -np.ones_like(q)
        return np.zeros_like(q)

    def potential(self, q: FloatArray) -> FloatArray:
        """``P_s(q)`` with ``dP_s/dq = s(q)``, so that the potential energy is ``ml g P_s``."""
        if self is GravityShape.SINE:
            return -np.cos(q)
        if self is GravityShape.CONSTANT:
            return -np.asarray(q, dtype=float)
        return np.zeros_like(q)


class FrictionEstimate(NamedTuple):
    """Friction from the constant-velocity experiment (Fig. 3.17, Table 3.3).

    Attributes:
        coulomb: ``Fc`` [N m or N].
        viscous: ``Fv`` [N m s/rad or N s/m].
        gravity_moment: ``ml`` fitted alongside [kg m or kg] (nan without gravity).
    """

    coulomb: float
    viscous: float
    gravity_moment: float


class JointEstimate(NamedTuple):
    """The identified parameters of one joint (3.75, Table 3.4).

    Attributes:
        inertia: ``I`` [kg m^2] (insertion: [kg]).
        gravity_moment: ``ml`` [kg m] (insertion: the weight's mass [kg]; nan for roll).
        coulomb: ``Fc`` [N m or N].
        viscous: ``Fv`` [N m s/rad or N s/m].
        condition: condition number of the regressor used (3.54) [-].
    """

    inertia: float
    gravity_moment: float
    coulomb: float
    viscous: float
    condition: float


class Validation(NamedTuple):
    """Residual analysis (3.77, 3.80).

    Attributes:
        residual_rms: RMS of ``tau - phi^T theta`` [N m].
        relative_residual: ``residual_rms`` over the RMS of the measured torque [-].
        input_correlation: coefficient of cross-correlation of residual and input (3.77).
    """

    residual_rms: float
    relative_residual: float
    input_correlation: float


def least_squares(phi: ArrayLike, y: ArrayLike) -> tuple[FloatArray, float]:
    """``theta = (phi^T phi)^-1 phi^T y`` (3.52, 3.64, 3.72), computed by SVD.

    Args:
        phi: regression matrix, ``(m, p)``.
        y: measurements, ``(m,)``.

    Returns:
        The estimate and the regressor's condition number (3.54).

    Raises:
        IdentificationError: fewer rows than parameters or a rank-deficient regressor.
    """
    a = np.asarray(phi, dtype=float)
    b = np.asarray(y, dtype=float)
    if a.shape[0] < a.shape[1]:
        raise IdentificationError(f"{a.shape[0]} samples for {a.shape[1]} parameters")
    s = np.linalg.svd(a, compute_uv=False)
    cond = float("inf") if s[-1] <= s[0] * 1e-13 else float(s[0] / s[-1])
    if not np.isfinite(cond):
        raise IdentificationError("regressor is rank deficient (not persistently exciting)", cond)
    theta, *_ = np.linalg.lstsq(a, b, rcond=None)
    return theta, cond


def estimate_motion(
    q: ArrayLike, dt: float, cutoff_hz: float | None = 10.0
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Velocities and accelerations aligned with the torque samples (offline).

    Sample ``k`` of a record pairs the position ``q[k]`` at the start of control
    period ``k`` with the torque ``tau[k]`` held during it. Over that period the
    robot goes from ``q[k]`` to ``q[k+1]``, so the period's velocity is
    ``v[k] = (q[k+1] - q[k]) / dt`` (the velocity at its end) and its
    acceleration ``a[k] = (q[k+1] - 2 q[k] + q[k-1]) / dt^2``. Positions are
    first low-passed forwards and backwards (4th-order Butterworth, no lag);
    the same filter should be applied to the torque (:func:`lowpass`) so both
    sides of (3.60) see the same filtering. The first and last samples have no
    neighbours and are NaN.

    Args:
        q: measured positions [rad or m], shape ``(m,)``.
        dt: sampling time [s].
        cutoff_hz: low-pass corner [Hz]; ``None`` for no filtering (clean data).

    Returns:
        ``(q_f, v, a)`` [rad, rad/s, rad/s^2].
    """
    qf = np.asarray(q, dtype=float) if cutoff_hz is None else lowpass(q, dt, cutoff_hz)
    v = np.full_like(qf, np.nan)
    a = np.full_like(qf, np.nan)
    v[:-1] = np.diff(qf) / dt
    a[1:-1] = np.diff(qf, 2) / (dt * dt)
    return qf, v, a


def lowpass(x: ArrayLike, dt: float, cutoff_hz: float | None) -> FloatArray:
    """Zero-phase 4th-order Butterworth low-pass (``scipy.signal.filtfilt``); ``None``: identity."""
    if cutoff_hz is None:
        return np.asarray(x, dtype=np.float64).copy()
    from scipy import signal

    b, a = signal.butter(4, cutoff_hz * 2.0 * dt)
    return np.asarray(signal.filtfilt(b, a, np.asarray(x, dtype=float)), dtype=np.float64)


def _sgn(v: FloatArray, deadband: float) -> FloatArray:
    if deadband > 0.0:
        return np.asarray(np.clip(v / deadband, -1.0, 1.0), dtype=np.float64)
    return np.sign(v)


def differential_regressor(
    q: FloatArray,
    qd: FloatArray,
    qdd: FloatArray,
    shape: GravityShape,
    *,
    g: float = GRAVITY,
    deadband: float = 0.0,
) -> FloatArray:
    """Rows ``[q'', g s(q), sgn q', q']`` of the one-link differential model (3.74).

    Args:
        q: positions [rad or m].
        qd: velocities.
        qdd: accelerations.
        shape: the joint's gravity shape.
        g: gravity [m/s^2].
        deadband: speed below which ``sgn`` ramps linearly.

    Returns:
        ``(m, 4)`` regressor; the gravity column is zero for :attr:`GravityShape.NONE`.
    """
    return np.column_stack([qdd, g * shape.shape(q), _sgn(qd, deadband), qd])


def energy_regressor(
    q: FloatArray,
    qd: FloatArray,
    tau: FloatArray,
    dt: float,
    shape: GravityShape,
    *,
    window: int,
    g: float = GRAVITY,
) -> tuple[FloatArray, FloatArray]:
    """Energy model over consecutive windows ``[ta, tb]`` (3.65-3.75).

    ``int tau q' dt = [ (q'b^2 - q'a^2)/2,  g (P_s(qb) - P_s(qa)),  int |q'| dt,  int q'^2 dt ]
    [I, ml, Fc, Fv]^T``.

    Args:
        q: positions [rad or m].
        qd: velocity over each period [rad/s or m/s] (no accelerations needed).
        tau: applied torques [N m or N].
        dt: sampling time [s].
        shape: the joint's gravity shape.
        window: samples per window.
        g: gravity [m/s^2].

    Returns:
        ``(Delta E, Delta W)``: the ``(k, 4)`` regressor and the ``(k,)`` works [J].
    """
    m = q.size
    if window < 2 or window >= m:
        raise IdentificationError(f"window of {window} samples for {m} samples")

    # Running integrals by the rectangle rule: period k contributes f[k] dt, with
    # qd[k] the velocity over period k (see :func:`estimate_motion`).
    def running(f: FloatArray) -> FloatArray:
        return np.concatenate([[0.0], np.cumsum(f * dt)])

    power = running(tau * qd)
    absv = running(np.abs(qd))
    sq = running(qd * qd)
    edges = np.arange(0, m, window)
    a, b = edges[:-1], edges[1:]
    pot = shape.potential(q)
    # Energy at an edge: the velocity entering it (period before) and its position.
    v_in = np.concatenate([[qd[0]], qd[:-1]])
    rows = np.column_stack(
        [
            0.5 * (v_in[b] ** 2 - v_in[a] ** 2),
            g * (pot[b] - pot[a]),
            absv[b] - absv[a],
            sq[b] - sq[a],
        ]
    )
    return rows, power[b] - power[a]


def column_correlation(regressor: ArrayLike) -> FloatArray:
    """Coefficients of cross-correlation between regressor columns (3.77, Table 3.2)."""
    x = np.asarray(regressor, dtype=float)
    keep = np.std(x, axis=0) > 0
    r = np.full((x.shape[1], x.shape[1]), np.nan)
    r[np.ix_(keep, keep)] = np.corrcoef(x[:, keep], rowvar=False)
    return r


def _active(shape: GravityShape) -> list[int]:
    return [0, 2, 3] if shape is GravityShape.NONE else [0, 1, 2, 3]


def differential_rows(
    q: ArrayLike,
    tau: ArrayLike,
    dt: float,
    shape: GravityShape,
    *,
    cutoff_hz: float | None = 10.0,
    trim: float = 0.5,
    deadband: float = 0.0,
) -> tuple[FloatArray, FloatArray]:
    """The differential model's regression rows and torques from a record (3.62-3.63, 3.74).

    Positions are low-passed and differenced (:func:`estimate_motion`); the torque
    and the nonlinear columns get the same low-pass (parallel filtering);
    ``trim`` seconds are dropped at both ends.

    Args:
        q: measured positions [rad or m].
        tau: applied torques [N m or N].
        dt: sampling time [s].
        shape: the joint's gravity shape.
        cutoff_hz: low-pass corner [Hz]; ``None`` for clean data.
        trim: seconds dropped at each end [s].
        deadband: speed below which ``sgn`` ramps [rad/s].

    Returns:
        ``(D, tau)``: the ``(m, 4)`` rows ``[q'', g s(q), sgn q', q']`` and the torques.
    """
    qf, qd, qdd = estimate_motion(q, dt, cutoff_hz)
    qd = np.nan_to_num(qd)  # end samples, trimmed below
    qdd = np.nan_to_num(qdd)
    tf = lowpass(tau, dt, cutoff_hz)
    phi = differential_regressor(qf, qd, qdd, shape, deadband=deadband)
    # Parallel filtering: the nonlinear columns get the filter the torque got, since
    # low-pass(sgn(v)) differs from sgn(low-pass(v)) around velocity reversals.
    for c in (1, 2):
        if np.any(phi[:, c]):
            phi[:, c] = lowpass(phi[:, c], dt, cutoff_hz)
    k = max(2, int(trim / dt))
    sl = slice(k, qf.size - k)
    return phi[sl], tf[sl]


def fit_differential(
    q: ArrayLike,
    tau: ArrayLike,
    dt: float,
    shape: GravityShape,
    *,
    cutoff_hz: float | None = 10.0,
    friction: FrictionEstimate | None = None,
    trim: float = 0.5,
    deadband: float = 0.0,
) -> JointEstimate:
    """Least squares on the differential model (3.60-3.64, 3.74).

    Args:
        q: measured positions [rad or m].
        tau: applied torques [N m or N].
        dt: sampling time [s].
        shape: the joint's gravity shape.
        cutoff_hz: low-pass corner applied to both positions and torques [Hz];
            ``None`` for clean data.
        friction: if given, subtract this friction and fit only ``I`` and ``ml``.
        trim: seconds dropped at each end (filter edge effects) [s].
        deadband: speed below which ``sgn`` ramps [rad/s].

    Returns:
        The estimate.
    """
    phi, y = differential_rows(q, tau, dt, shape, cutoff_hz=cutoff_hz, trim=trim,
                               deadband=deadband)  # fmt: skip
    return _solve(phi, y, shape, friction)


def _solve(
    rows: np.ndarray, rhs: np.ndarray, shape: GravityShape, friction: FrictionEstimate | None
) -> JointEstimate:
    """Least squares of a differential or energy model for one joint.

    Columns are (I, ml, Fc, Fv); friction identified first (3.5.3.1) is moved to the
    right-hand side and only I and ml are fitted.
    """
    cols = _active(shape)
    if friction is not None:
        rhs = rhs - friction.coulomb * rows[:, 2] - friction.viscous * rows[:, 3]
        cols = [c for c in cols if c < 2]
    theta, cond = least_squares(rows[:, cols], rhs)
    full = dict(zip(cols, theta, strict=True))
    return JointEstimate(
        inertia=float(full[0]),
        gravity_moment=float(full.get(1, np.nan)),
        coulomb=float(full.get(2, friction.coulomb if friction else np.nan)),
        viscous=float(full.get(3, friction.viscous if friction else np.nan)),
        condition=cond,
    )


def fit_energy(
    q: ArrayLike,
    tau: ArrayLike,
    dt: float,
    shape: GravityShape,
    *,
    qd: ArrayLike | None = None,
    cutoff_hz: float | None = None,
    window: int = 100,
    friction: FrictionEstimate | None = None,
) -> JointEstimate:
    """Least squares on the energy model (3.65-3.72, 3.75).

    Args:
        q: measured positions [rad or m].
        tau: applied torques [N m or N].
        dt: sampling time [s].
        shape: the joint's gravity shape.
        qd: velocity over each period [rad/s or m/s] (e.g. a washout filter's);
            by default differenced from (optionally low-passed) positions.
        cutoff_hz: low-pass corner for positions and torques [Hz]; ``None``: none.
        window: samples per energy window.
        friction: friction identified first (3.5.3.1); if ``None`` all four
            parameters are fitted together (ill-conditioned, Table 3.2).

    Returns:
        The estimate.
    """
    q_ = np.asarray(q, dtype=float)
    if qd is None:
        q_, v, _ = estimate_motion(q_, dt, cutoff_hz)
    else:
        v = np.asarray(qd, dtype=float)
    tau_ = lowpass(tau, dt, cutoff_hz)
    sl = slice(1, q_.size - 1)
    rows, work = energy_regressor(q_[sl], v[sl], tau_[sl], dt, shape, window=window)
    return _solve(rows, work, shape, friction)


def fit_friction(
    q: ArrayLike,
    qd: ArrayLike,
    tau: ArrayLike,
    shape: GravityShape,
    *,
    g: float = GRAVITY,
) -> FrictionEstimate:
    """Coulomb and viscous friction from constant-velocity segments (Fig. 3.17, Table 3.3).

    At constant velocity ``q'' = 0`` and ``tau = ml g s(q) + Fc sgn(q') + Fv q'``;
    the samples must cover both directions and several speeds.

    Args:
        q: positions during the steady segments [rad or m].
        qd: velocities during the steady segments [rad/s or m/s].
        tau: torques during the steady segments [N m or N].
        shape: the joint's gravity shape.
        g: gravity [m/s^2].

    Returns:
        The friction estimate (and the gravity moment seen in passing).
    """
    q_, v, t = (np.asarray(x, dtype=float) for x in (q, qd, tau))
    phi = np.column_stack([g * shape.shape(q_), np.sign(v), v])
    cols = [1, 2] if shape is GravityShape.NONE else [0, 1, 2]
    theta, _ = least_squares(phi[:, cols], t)
    full = dict(zip(cols, theta, strict=True))
    return FrictionEstimate(
        coulomb=float(full[1]), viscous=float(full[2]), gravity_moment=float(full.get(0, np.nan))
    )


def validate(phi: ArrayLike, theta: ArrayLike, y: ArrayLike, u: ArrayLike) -> Validation:
    """Residual ``eps = y - phi theta`` (3.80) and its correlation with the input ``u`` (3.77).

    Args:
        phi: regressor rows.
        theta: estimate.
        y: measured outputs (torques).
        u: the excitation input.

    Returns:
        The residual statistics.
    """
    y_ = np.asarray(y, dtype=float)
    eps = y_ - np.asarray(phi, dtype=float) @ np.asarray(theta, dtype=float)
    rms = float(np.sqrt(np.mean(eps**2)))
    u_ = np.asarray(u, dtype=float)
    corr = float(np.corrcoef(eps, u_)[0, 1]) if np.std(eps) > 0 and np.std(u_) > 0 else 0.0
    return Validation(rms, rms / float(np.sqrt(np.mean(y_**2))), corr)
