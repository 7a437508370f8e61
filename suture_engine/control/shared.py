"""Shared control for Manual mode: virtual springs and dampers normal to a fixture (chapter 6).

Two controllers, both leaving the motion along the fixture to the operator:

* task space (6.7, 6.24): ``tau = -J^T Jc^T (Kp C(x) + Kv Jc xdot) + G(q)``: a spring
  ``Kp`` [N/m] and a damper ``Kv`` [N*s/m] act only in the constrained directions;
* joint space via the diffeomorphism ``d = [c; f]`` (6.33-6.37): the set point is the
  fixture point with the operator's current free coordinates, ``x_d = d^-1([0; f(k(q))])``
  (6.35), ``xdot_d = [Jc; Jf]^-1 [0; Jf xdot]`` (6.36), tracked by a joint PD with gravity
  and friction compensation (6.37).

And the metrics of the chapter 6 experiments: the constraint force recovered from the
joint torques (6.52-6.53) and the effective constraint stiffness ``max|Fc| / max|e|``
(6.54, Tables 6.2-6.4).

Kinematics come from :mod:`suture_engine.robot.endobot` (3.13-3.21).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.control.fixtures import EqualityFixture, Fixture
from suture_engine.errors import SutureError
from suture_engine.robot import endobot

__all__ = [
    "JointSetpoint",
    "SharedControlError",
    "StiffnessReport",
    "TaskSpaceGains",
    "TaskSpaceOutput",
    "constraint_force",
    "effective_stiffness",
    "joint_space_setpoint",
    "joint_space_shared_control",
    "task_space_shared_control",
    "task_vector",
]

Array = NDArray[np.float64]


class SharedControlError(SutureError):
    """Shared control was given values it cannot use.

    Attributes:
        field: the offending field name.
        value: the offending value.
    """

    code = "bad-shared-control"

    def __init__(self, field: str, value: object, reason: str) -> None:
        super().__init__(f"{field}={value!r}: {reason}")
        self.field = field
        self.value = value


@dataclass(frozen=True, eq=False)
class TaskSpaceGains:
    """The virtual spring and damper of task-space shared control (6.7).

    Attributes:
        stiffness: Kp per constraint row [N/m] (a scalar applies to every row).
        damping: Kv per constraint row [N*s/m].
    """

    stiffness: float | Sequence[float] = 1000.0
    damping: float | Sequence[float] = 20.0

    def matrices(self, rows: int) -> tuple[Array, Array]:
        """Diagonal Kp, Kv for ``rows`` constraint rows."""
        kp = np.broadcast_to(np.asarray(self.stiffness, dtype=float), (rows,))
        kv = np.broadcast_to(np.asarray(self.damping, dtype=float), (rows,))
        if np.any(kp < 0) or np.any(kv < 0) or not np.all(np.isfinite(kp + kv)):
            raise SharedControlError("stiffness", self.stiffness, "gains must be finite, >= 0")
        return np.diag(kp), np.diag(kv)


class TaskSpaceOutput(NamedTuple):
    """One tick of task-space shared control.

    Attributes:
        tau: joint torques [N*m, N*m, N*m, N] (6.24), gravity included when given.
        constraint_force: Fc = -(Kp C + Kv Jc xdot) per constraint row [N] (6.20).
        deviation: C(x), the constraint error [m] (6.14-6.15).
    """

    tau: Array
    constraint_force: Array
    deviation: Array


class JointSetpoint(NamedTuple):
    """The set point of joint-space shared control (6.35-6.36).

    Attributes:
        q: joint set point k^-1(x_d) [rad, rad, rad, m].
        qd: joint velocity set point J^-1(q) xdot_d [rad/s, rad/s, rad/s, m/s].
        x: task set point x_d (6.35) [m, m, m, rad].
        xd: task velocity set point xdot_d (6.36) [m/s, m/s, m/s, rad/s].
    """

    q: Array
    qd: Array
    x: Array
    xd: Array


class StiffnessReport(NamedTuple):
    """Tables 6.2-6.4: per constraint row, the peaks and their ratio (6.54).

    Attributes:
        max_deviation: max |e| over the run [m].
        max_force: max |Fc| over the run [N].
        stiffness: max |Fc| / max |e| [N/m].
    """

    max_deviation: Array
    max_force: Array
    stiffness: Array


def task_vector(q: Array) -> Array:
    """x = k(q) = (x, y, z, phi) of (3.13) [m, m, m, rad]."""
    pose = endobot.forward_kinematics(q)
    return np.array([pose.position[0], pose.position[1], pose.position[2], pose.roll])


def task_space_shared_control(
    fixture: Fixture,
    q: Array,
    qd: Array,
    gains: TaskSpaceGains,
    gravity: Array | None = None,
) -> TaskSpaceOutput:
    """Task-space shared control, ``tau = -J^T Jc^T (Kp C(x) + Kv Jc J qd) + G(q)`` (6.24).

    For an inequality fixture (cone) the spring and damper act only while g(x) > 0.

    Args:
        fixture: the virtual fixture.
        q: joint positions [rad, rad, rad, m].
        qd: joint velocities (estimated) [rad/s, rad/s, rad/s, m/s].
        gains: Kp [N/m] and Kv [N*s/m].
        gravity: G(q) [N*m, N*m, N*m, N] to add (None: no compensation).

    Returns:
        Torques, constraint force and deviation.
    """
    q = np.asarray(q, dtype=float)
    J = endobot.jacobian(q)
    x = task_vector(q)
    kp, kv = gains.matrices(fixture.rows)
    c = fixture.value(x)
    jc = fixture.jacobian(x)
    cdot = jc @ (J @ np.asarray(qd, dtype=float))
    fc = -(kp @ c + kv @ cdot)
    if fixture.kind == "ineq":
        fc = np.where(c > 0.0, np.minimum(fc, 0.0), 0.0)
    tau = J.T @ (jc.T @ fc)
    if gravity is not None:
        tau = tau + np.asarray(gravity, dtype=float)
    return TaskSpaceOutput(tau, fc, c)


def joint_space_setpoint(fixture: EqualityFixture, q: Array, qd: Array) -> JointSetpoint:
    """The joint-space shared-control set point (6.35-6.36).

    ``x_d = d^-1([0; f(k(q))])`` keeps the operator's free coordinates and zeroes the
    constrained ones; ``xdot_d = [Jc; Jf]^-1 [0; Jf xdot]`` (both Jacobians at x_d,
    except ``Jf xdot``, the operator's current free-coordinate rate, at x).

    Args:
        fixture: an equality fixture (line, circle, plane).
        q: joint positions [rad, rad, rad, m].
        qd: joint velocities [rad/s, rad/s, rad/s, m/s].

    Returns:
        The joint and task set points.
    """
    q = np.asarray(q, dtype=float)
    J = endobot.jacobian(q)
    x = task_vector(q)
    x_d = fixture.project(x)
    free_rate = fixture.free_jacobian(x) @ (J @ np.asarray(qd, dtype=float))
    d_jac = np.vstack([fixture.jacobian(x_d), fixture.free_jacobian(x_d)])
    xd_d = np.linalg.solve(d_jac, np.concatenate([np.zeros(fixture.rows), free_rate]))
    q_d = endobot.inverse_kinematics(x_d[:3], float(x_d[3]))
    qd_d = np.linalg.solve(J, xd_d)
    return JointSetpoint(np.asarray(q_d, dtype=float), np.asarray(qd_d, dtype=float), x_d, xd_d)


def joint_space_shared_control(
    fixture: EqualityFixture,
    q: Array,
    qd: Array,
    kp: Array,
    kd: Array,
    gravity: Array | None = None,
    friction: Array | None = None,
) -> tuple[Array, JointSetpoint]:
    """Joint-space shared control (6.37).

    ``tau = -Kp (q - k^-1(x_d)) - Kd (qd - J^-1 xdot_d) + G(q) + N(qd)``.

    Args:
        fixture: an equality fixture.
        q: joint positions [rad, rad, rad, m].
        qd: joint velocities [rad/s, rad/s, rad/s, m/s].
        kp: joint stiffness, diagonal [N*m/rad, N*m/rad, N*m/rad, N/m] (4,) or (4, 4).
        kd: joint damping, diagonal [N*m*s/rad, ..., N*s/m] (4,) or (4, 4).
        gravity: G(q) to add (None: no compensation).
        friction: friction compensation N(qd) to add (None: none).

    Returns:
        The torques [N*m, N*m, N*m, N] and the set point used.
    """
    sp = joint_space_setpoint(fixture, q, qd)
    kp_m = np.diag(kp) if np.ndim(kp) == 1 else np.asarray(kp, dtype=float)
    kd_m = np.diag(kd) if np.ndim(kd) == 1 else np.asarray(kd, dtype=float)
    tau = -kp_m @ (np.asarray(q, dtype=float) - sp.q) - kd_m @ (np.asarray(qd, dtype=float) - sp.qd)
    if gravity is not None:
        tau = tau + np.asarray(gravity, dtype=float)
    if friction is not None:
        tau = tau + np.asarray(friction, dtype=float)
    return tau, sp


def constraint_force(fixture: Fixture, q: Array, tau: Array) -> Array:
    """The constraint force recovered from joint torques, ``Fc = (Jc^T)^+ J^-T tau`` (6.53).

    Args:
        fixture: the virtual fixture.
        q: joint positions [rad, rad, rad, m].
        tau: the shared controller's joint torques without gravity [N*m, ..., N].

    Returns:
        Fc per constraint row [N].
    """
    q = np.asarray(q, dtype=float)
    J = endobot.jacobian(q)
    jc = fixture.jacobian(task_vector(q))
    task_force = np.linalg.solve(J.T, np.asarray(tau, dtype=float))
    return np.asarray(np.linalg.pinv(jc.T) @ task_force)


def effective_stiffness(deviation: Array, force: Array) -> StiffnessReport:
    """Effective constraint stiffness ``max|Fc| / max|e|`` per row (6.54, Tables 6.2-6.4).

    Args:
        deviation: e over time, shape (T, m) [m].
        force: Fc over time, shape (T, m) [N].

    Returns:
        Peaks and their ratio per row; the ratio is nan for a row that never deviated.
    """
    e = np.atleast_2d(np.asarray(deviation, dtype=float))
    f = np.atleast_2d(np.asarray(force, dtype=float))
    if e.shape != f.shape or e.size == 0:
        raise SharedControlError("deviation", e.shape, f"must match force shape {f.shape}")
    max_e = np.max(np.abs(e), axis=0)
    max_f = np.max(np.abs(f), axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(max_e > 0, max_f / np.where(max_e > 0, max_e, 1.0), np.nan)
    return StiffnessReport(max_e, max_f, k)
