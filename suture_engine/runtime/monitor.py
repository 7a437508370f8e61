"""The safety monitor: a step's invariant Inv(s_i) checked every tick (4.43).

x(t) must stay in Inv(s) while the step's activity runs (4.43); when it
leaves, the interpreter raises an unpredictable event (thesis 4.6.1.2). The
invariants checked here are the ones a procedure declares:

- a tension bound: the tension estimated from the base force/torque sensor
  stays below ``max_tension_N`` [N] on every robot, not only the ones the step
  drives (the suture is one thread);
- a force bound: the magnitude of the tared base force below ``max_force_N`` [N];
- a workspace box (4.45): joint positions inside ``[q_min, q_max]``
  [rad, rad, rad, m], and the tool tip (world frame) inside
  ``[workspace_min, workspace_max]`` [m];
- a singularity margin (3.22-3.23): |q2| stays ``margin`` [rad] away from
  90 deg and the insertion q4 stays above ``insertion_margin_m`` [m];
- QP failures: at most ``max_qp_failures`` consecutive failed solves.

Independently of the steps' invariants, in every mode, :meth:`Monitor.emergency`
locks the robots (an unpredictable event, issue #8's third tension layer) when
the estimated tension reaches a margin below the scene's derived limit, when a
measurement is not finite, and when a sensor stays stale longer than a bound
(:class:`SafetyLimits`). The tension is the thesis' base-sensor estimate
(7.6)-(7.9), :class:`BaseSensorTension`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from suture_engine.runtime.observation import Measurement, Observation, RobotObservation

if TYPE_CHECKING:
    from suture_engine.robot.params import EndoBotParams

__all__ = [
    "EMERGENCIES",
    "BaseSensorTension",
    "Invariant",
    "Monitor",
    "SafetyLimits",
    "Violation",
]


@dataclass(frozen=True)
class Invariant:
    """A step's invariant Inv(s_i) (4.43); ``None`` disables a check.

    Attributes:
        max_tension_N: bound on the estimated suture tension [N].
        q_min: lower joint bounds of the workspace box [rad, rad, rad, m] (4.45).
        q_max: upper joint bounds of the workspace box [rad, rad, rad, m] (4.45).
        singularity_margin_rad: least distance of q2 from +-90 deg [rad] (3.22).
        insertion_margin_m: least insertion q4 [m] (q4 = 0 is singular, 3.23).
        max_qp_failures: consecutive failed QP solves tolerated.
        max_force_N: bound on the tared base-force magnitude [N].
        workspace_min: lower corner of the tool-tip box, world frame [m] (4.45).
        workspace_max: upper corner of the tool-tip box, world frame [m] (4.45).
    """

    max_tension_N: float | None = None
    q_min: tuple[float, float, float, float] | None = None
    q_max: tuple[float, float, float, float] | None = None
    singularity_margin_rad: float | None = None
    insertion_margin_m: float | None = None
    max_qp_failures: int | None = None
    max_force_N: float | None = None
    workspace_min: tuple[float, float, float] | None = None
    workspace_max: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Violation:
    """One invariant violation, for the trace and the summary.

    Attributes:
        t: simulation time [s].
        tick: tick index.
        state: the automaton state.
        robot: the robot concerned ("" when none).
        invariant: which check ("tension", "force", "workspace", "singularity", "qp"; the
            emergencies "tension-limit", "non-finite", "sensor-stale").
        value: the offending value (tension [N], joint value, count).
        bound: the bound it crossed.
    """

    t: float
    tick: int
    state: str
    robot: str
    invariant: str
    value: float
    bound: float

    @property
    def reason(self) -> str:
        """Short text for the automaton's event reason."""
        who = f"{self.robot}:" if self.robot else ""
        if self.invariant in EMERGENCIES:
            return f"emergency:{self.invariant}:{who}{self.value:.6g}>={self.bound:.6g}"
        return f"invariant:{self.invariant}:{who}{self.value:.6g}>{self.bound:.6g}"


EMERGENCIES = ("tension-limit", "non-finite", "sensor-stale")
"""The monitor's own checks, independent of the steps' invariants: each locks the robots."""


@dataclass(frozen=True)
class SafetyLimits:
    """Bounds of the monitor's emergency lock (issue #8, the third tension layer).

    Independently of the running step's invariant, the monitor locks every robot
    when the estimated tension reaches ``(1 - margin) * tension_limit_N``, when a
    measurement is not finite (NaN or inf in the encoders or the base wrench: a
    physics blow-up or a sensor fault) and when a sensor reports dropped (stale)
    readings for longer than ``max_stale_s``. Shorter dropouts are absorbed (the
    backend holds the last reading). The tension lock leaves robots the operator's
    hand moves (Manual, shared control) to the surgeon: the base sensor cannot tell
    the hand's force from the thread's.

    Attributes:
        tension_limit_N: the scene's derived tension limit [N] (Tables 7.1-7.2 times
            the safety factor); None: no tension lock.
        margin: fraction of the limit kept in reserve [-] (0.1: lock at 90 %).
        max_stale_s: longest tolerated run of stale sensor readings [s].
    """

    tension_limit_N: float | None = None
    margin: float = 0.1
    max_stale_s: float = 0.01

    def __post_init__(self) -> None:
        if not 0.0 <= self.margin < 1.0:
            raise ValueError(f"margin must be in [0, 1), not {self.margin!r}")
        if not self.max_stale_s >= 0.0:
            raise ValueError(f"max_stale_s must be >= 0, not {self.max_stale_s!r}")

    @property
    def lock_tension_N(self) -> float | None:
        """The tension at which the monitor locks [N] (None: no tension lock)."""
        if self.tension_limit_N is None:
            return None
        return (1.0 - self.margin) * self.tension_limit_N


class BaseSensorTension:
    """Tension at each robot's tool tip from its base force/torque sensor (7.6)-(7.9).

    As :mod:`suture_engine.suture.tension` derives it: the gravity wrench
    ``F_g(q)`` of the robot's model (link masses and centres of mass, gravity in
    the robot's base frame) is compensated (7.7), the motion wrench ``F_m`` is
    neglected (low speed, 7.2.2), and the environment's load
    ``-F_b = F_g + o - F_s`` is moved from the remote centre of motion O to the
    tool tip ``p(q)`` (3.12) by the adjoint transform (7.8)-(7.9): force ``f`` and
    moment ``m_tip = m_O - p x f`` (:meth:`tip_wrench`). The monitor knows no
    pulling direction, so its tension is ``|f|`` [N] (the thread's tension when
    the thread is the only load at the tip), low-pass filtered (first order,
    ``cutoff_hz``).

    The tare ``o = F_s - F_g(q)``, taken at rest with the thread slack, absorbs
    the static frame above the sensor, unmodelled mounted tools' weight and the
    sensor's bias. The force part of ``F_g`` is ``-sum_i m_i g`` at every pose: a
    robot's pose changes the gravity *moment* at the sensor, never its force, and
    the adjoint transform only rotates the force. So ``|f|`` is free of the
    robot's pose-dependent load once tared and needs no trigonometry per tick;
    what it still sees of the robot itself is its motion wrench. The
    arithmetic is on plain floats; :meth:`tip_wrench` equals
    :func:`suture_engine.suture.tension.tip_wrench` (tested).

    Args:
        params: per robot, the robot's model with gravity in its base frame;
            robots missing here use E1 (base z axis pointing down).
        dt: control period [s].
        cutoff_hz: low-pass cut-off [Hz]; ``math.inf`` disables filtering.
    """

    def __init__(
        self,
        params: Mapping[str, EndoBotParams] | None = None,
        dt: float = 1e-3,
        cutoff_hz: float = 30.0,
    ) -> None:
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"dt must be finite and > 0, not {dt!r}")
        if not cutoff_hz > 0.0:
            raise ValueError(f"cutoff_hz must be > 0, not {cutoff_hz!r}")
        self.params = dict(params or {})
        self.dt = dt
        self.cutoff_hz = cutoff_hz
        tau = 0.0 if math.isinf(cutoff_hz) else 1.0 / (2.0 * math.pi * cutoff_hz)
        self._alpha = dt / (tau + dt)
        self._model: dict[str, tuple[float, ...]] = {}
        self._offset: dict[str, tuple[float, ...]] = {}
        self._state: dict[str, tuple[float, float, float]] = {}
        self._const: dict[str, tuple[float, float, float]] = {}

    def _coefficients(self, name: str) -> tuple[float, ...]:
        """(g, M g, m1 c1, m2 c2 + m3 c3 + m4 c4, m4) of the robot's model (7.6)."""
        model = self._model.get(name)
        if model is None:
            from suture_engine.robot.params import E1

            prm = self.params.get(name, E1)
            b1, b2, b3, b4 = prm.bodies
            gx, gy, gz = (float(v) for v in prm.gravity)
            mass = b1.mass + b2.mass + b3.mass + b4.mass
            a1 = b1.mass * b1.com_z
            a2 = b2.mass * b2.com_z + b3.mass * b3.com_z + b4.mass * b4.com_z
            model = (gx, gy, gz, mass * gx, mass * gy, mass * gz, a1, a2, b4.mass)
            self._model[name] = model
        return model

    def _load(self, name: str, q: Sequence[float], w: Sequence[float]) -> list[float]:
        """``F_g(q) - F_s`` about O (force [N], moment [N*m]), without the tare."""
        gx, gy, gz, mgx, mgy, mgz, a1, a2, m4 = self._coefficients(name)
        q1, q2, q4 = q[0], q[1], q[3]
        c1, s1 = math.cos(q1), math.sin(q1)
        c2, s2 = math.cos(q2), math.sin(q2)
        k = a2 + m4 * q4
        # first mass moment h = sum_i m_i c_i(q) (z1 = Rx(q1) e_z, z2 = Rx(q1) Ry(q2) e_z)
        hx, hy, hz = k * s2, -(a1 + k * c2) * s1, (a1 + k * c2) * c1
        # F_g = -(M g, h x g)
        return [
            -mgx - w[0],
            -mgy - w[1],
            -mgz - w[2],
            -(hy * gz - hz * gy) - w[3],
            -(hz * gx - hx * gz) - w[4],
            -(hx * gy - hy * gx) - w[5],
        ]

    def tare(self, measurement: Measurement) -> None:
        """Zero every robot's estimate on this measurement (at rest, thread slack)."""
        for name, robot in measurement.robots.items():
            load = self._load(name, robot.q.tolist(), robot.base_wrench.tolist())
            self._offset[name] = tuple(-v for v in load)
            self._state.pop(name, None)
            self._const.pop(name, None)

    def estimate(self, obs: Observation) -> dict[str, float]:
        """Estimated tension ``|f|`` [N] per robot, low-pass filtered.

        Per tick only the force of (7.7) is computed: the force part of ``F_g`` is
        ``-M g`` at every pose and the adjoint transform (7.9) only rotates the force
        (``|R^T f| = |f|``), so ``|f|`` needs neither the encoders nor trigonometry.
        :meth:`tip_wrench` gives the whole wrench at the tip, moment included.
        """
        out: dict[str, float] = {}
        alpha = self._alpha
        for name, robot in obs.robots.items():
            const = self._const.get(name)
            if const is None:
                const = self._constants(name)
            sx, sy, sz, _tx, _ty, _tz = robot.base_wrench.tolist()
            fx, fy, fz = const[0] - sx, const[1] - sy, const[2] - sz  # -F_b (7.7)
            st = self._state.get(name)
            if st is not None:
                fx = st[0] + alpha * (fx - st[0])
                fy = st[1] + alpha * (fy - st[1])
                fz = st[2] + alpha * (fz - st[2])
            self._state[name] = (fx, fy, fz)
            out[name] = math.sqrt(fx * fx + fy * fy + fz * fz)
        return out

    def _constants(self, name: str) -> tuple[float, float, float]:
        """The tared force part of ``F_g`` [N]: ``-M g`` plus the tare's force."""
        _gx, _gy, _gz, mgx, mgy, mgz, _a1, _a2, _m4 = self._coefficients(name)
        o = self._offset.get(name, (0.0,) * 6)
        const = (o[0] - mgx, o[1] - mgy, o[2] - mgz)
        self._const[name] = const
        return const

    def tip_wrench(self, name: str, robot: RobotObservation) -> tuple[float, ...]:
        """The environment's wrench on the tool at its tip, base frame, unfiltered (7.7-7.9).

        Args:
            name: the robot.
            robot: its observation (encoders and base wrench).

        Returns:
            ``(fx, fy, fz [N], mx, my, mz [N*m])``: force and moment about the tool tip
            ``p(q)`` (3.12); the moment is ~0 when a thread is the only load.
        """
        q = robot.q.tolist()
        load = self._load(name, q, robot.base_wrench.tolist())
        o = self._offset.get(name, (0.0,) * 6)
        fx, fy, fz, mx, my, mz = (load[i] + o[i] for i in range(6))
        q1, q2, q4 = q[0], q[1], q[3]
        c2q4 = math.cos(q2) * q4
        px, py, pz = math.sin(q2) * q4, -math.sin(q1) * c2q4, math.cos(q1) * c2q4
        return (
            fx,
            fy,
            fz,
            mx - (py * fz - pz * fy),
            my - (pz * fx - px * fz),
            mz - (px * fy - py * fx),
        )


class Monitor:
    """Checks invariants and counts violations over a run."""

    def __init__(self) -> None:
        self.violations: list[Violation] = []
        self.max_tension_N = 0.0
        self._stale: dict[str, int] = {}
        self._stale_any = False
        self._active: set[tuple[str, str]] = set()

    def quiet(
        self,
        limits: SafetyLimits,
        tension: Mapping[str, float],
        stale: Mapping[str, bool],
        non_finite: Mapping[str, str],
    ) -> bool:
        """Whether :meth:`emergency` has nothing to do this tick: no sensor stale or
        non-finite, none of them was on the last tick, and every tension [N] below the
        lock bound. It then returns None and changes nothing; with fewer robots' tensions
        (a subset of ``tension``) too.
        """
        if stale or non_finite or self._active or self._stale_any:
            return False
        bound = limits.lock_tension_N
        return bound is None or not tension or max(tension.values()) < bound

    def emergency(
        self,
        limits: SafetyLimits,
        obs: Observation,
        state: str,
        tension: Mapping[str, float],
        stale: Mapping[str, bool],
        non_finite: Mapping[str, str],
        dt: float,
        locked: bool,
    ) -> Violation | None:
        """The monitor's emergency check for this tick (see :class:`SafetyLimits`).

        Args:
            limits: the emergency bounds.
            obs: this tick's observation (state, time).
            state: the automaton state (for the record).
            tension: estimated tension per robot [N].
            stale: per robot, whether a sensor reported a dropped (held) reading.
            non_finite: per robot, the signal that was not finite ("q", "base_wrench").
            dt: control period [s].
            locked: whether every robot already holds its pose (Lock law): a
                condition that lasts is then recorded once, when it arises.

        Returns:
            The first emergency that must lock the robots now (also recorded), or
            None. A condition arising while ``locked`` is recorded, not returned.
        """
        if self.quiet(limits, tension, stale, non_finite):
            return None  # the common, quiet tick
        found: list[Violation] = []
        for name in obs.robots:
            signal = non_finite.get(name)
            if signal:
                found.append(Violation(obs.t, obs.tick, state, name, "non-finite", 1.0, 0.0))
            run = self._stale.get(name, 0) + 1 if stale.get(name, False) else 0
            self._stale[name] = run
            if run and run * dt > limits.max_stale_s + 0.5 * dt:
                found.append(
                    Violation(
                        obs.t, obs.tick, state, name, "sensor-stale", run * dt, limits.max_stale_s
                    )
                )
            bound = limits.lock_tension_N
            value = tension.get(name, 0.0)
            if bound is not None and value >= bound:
                found.append(Violation(obs.t, obs.tick, state, name, "tension-limit", value, bound))
        self._stale_any = any(self._stale.values())
        keys = {(v.invariant, v.robot) for v in found}
        arising = [v for v in found if (v.invariant, v.robot) not in self._active]
        self._active = keys
        if not found:
            return None
        if locked:
            self.violations.extend(arising)
            return None
        self.violations.append(found[0])
        return found[0]

    def check(
        self,
        invariant: Invariant | None,
        obs: Observation,
        state: str,
        tension: Mapping[str, float],
        qp_failures: Mapping[str, int],
        robots: tuple[str, ...] = (),
        base_poses: Mapping[str, Any] | None = None,
    ) -> Violation | None:
        """Return the first violation of ``invariant`` this tick (also recorded), or None.

        Sensor dropouts, non-finite measurements and the tension limit are not a
        step's invariant: :meth:`emergency` checks them in every mode.

        Args:
            invariant: the active step's invariant (None: nothing to check).
            obs: this tick's observation.
            state: the automaton state (for the record).
            tension: estimated tension per robot [N].
            qp_failures: consecutive QP failures per robot.
            robots: the robots the step drives (empty: all).
            base_poses: robot -> (base position [m], row-major 3x3 rotation) for the
                tool-tip workspace box.
        """
        top = max(tension.values()) if tension else -math.inf
        if tension:
            self.max_tension_N = max(self.max_tension_N, top)
        if invariant is None:
            return None
        names = robots or tuple(obs.robots)
        found: Violation | None = None
        # max() is the largest of the non-NaN values (or NaN if the first is): when it is
        # within the bound no robot's tension exceeds it and the ordered scan is skipped
        if invariant.max_tension_N is not None and not top <= invariant.max_tension_N:
            # the suture's tension is one quantity, whichever robot's sensor reads it: a step
            # that drives the stitcher still must not overload the strand the grasper holds
            for name in sorted(tension, key=lambda n: (n not in names, n)):
                if tension[name] > invariant.max_tension_N:
                    found = Violation(
                        obs.t,
                        obs.tick,
                        state,
                        name,
                        "tension",
                        tension[name],
                        invariant.max_tension_N,
                    )
                    self.violations.append(found)
                    return found
        for name in names:
            found = self._check_robot(invariant, obs, state, name, tension, qp_failures)
            if found is None and invariant.workspace_min is not None:
                found = self._check_tip(invariant, obs, state, name, (base_poses or {}).get(name))
            if found is not None:
                break
        if found is not None:
            self.violations.append(found)
        return found

    @staticmethod
    def _check_tip(
        inv: Invariant, obs: Observation, state: str, name: str, base: Any
    ) -> Violation | None:
        from suture_engine.robot.kinematics import forward_kinematics

        robot = obs.robots.get(name)
        if robot is None or inv.workspace_min is None or inv.workspace_max is None:
            return None
        tip = np.asarray(forward_kinematics(robot.q).position)
        if base is not None:
            tip = np.asarray(base[0]) + np.asarray(base[1]).reshape(3, 3) @ tip
        for i in range(3):
            if tip[i] < inv.workspace_min[i]:
                return Violation(
                    obs.t, obs.tick, state, name, "workspace", tip[i], inv.workspace_min[i]
                )
            if tip[i] > inv.workspace_max[i]:
                return Violation(
                    obs.t, obs.tick, state, name, "workspace", tip[i], inv.workspace_max[i]
                )
        return None

    @staticmethod
    def _check_robot(
        inv: Invariant,
        obs: Observation,
        state: str,
        name: str,
        tension: Mapping[str, float],
        qp_failures: Mapping[str, int],
    ) -> Violation | None:
        robot = obs.robots.get(name)
        if robot is None:
            return None
        # (max_tension is checked over every robot in :meth:`check`, before this)
        if inv.max_force_N is not None and tension.get(name, 0.0) > inv.max_force_N:
            return Violation(obs.t, obs.tick, state, name, "force", tension[name], inv.max_force_N)
        q = robot.q
        if inv.q_min is not None:
            for i in range(q.shape[0]):
                if q[i] < inv.q_min[i]:
                    return Violation(obs.t, obs.tick, state, name, "workspace", q[i], inv.q_min[i])
        if inv.q_max is not None:
            for i in range(q.shape[0]):
                if q[i] > inv.q_max[i]:
                    return Violation(obs.t, obs.tick, state, name, "workspace", q[i], inv.q_max[i])
        if inv.singularity_margin_rad is not None:
            distance = abs(abs(float(q[1])) - math.pi / 2)
            if distance < inv.singularity_margin_rad:
                return Violation(
                    obs.t,
                    obs.tick,
                    state,
                    name,
                    "singularity",
                    distance,
                    inv.singularity_margin_rad,
                )
        if inv.insertion_margin_m is not None and q[3] < inv.insertion_margin_m:
            return Violation(
                obs.t, obs.tick, state, name, "singularity", float(q[3]), inv.insertion_margin_m
            )
        if inv.max_qp_failures is not None and qp_failures.get(name, 0) > inv.max_qp_failures:
            return Violation(
                obs.t,
                obs.tick,
                state,
                name,
                "qp",
                float(qp_failures[name]),
                float(inv.max_qp_failures),
            )
        return None
