"""The safety monitor: a step's invariant Inv(s_i) checked every tick (4.43).

x(t) must stay in Inv(s) while the step's activity runs (4.43); when it
leaves, the interpreter raises an unpredictable event (thesis 4.6.1.2). The
invariants checked here are the ones a procedure declares:

- a tension bound: the tension estimated from the base force/torque sensor
  stays below ``max_tension_N`` [N];
- a force bound: the magnitude of the tared base force below ``max_force_N`` [N];
- a workspace box (4.45): joint positions inside ``[q_min, q_max]``
  [rad, rad, rad, m], and the tool tip (world frame) inside
  ``[workspace_min, workspace_max]`` [m];
- a singularity margin (3.22-3.23): |q2| stays ``margin`` [rad] away from
  90 deg and the insertion q4 stays above ``insertion_margin_m`` [m];
- QP failures: at most ``max_qp_failures`` consecutive failed solves;
- sensor faults: a dropout flagged by the backend.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from suture_engine.runtime.observation import Measurement, Observation

__all__ = ["Invariant", "Monitor", "TensionEstimator", "Violation"]


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
        invariant: which check ("tension", "workspace", "singularity", "qp", "sensor").
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
        return f"invariant:{self.invariant}:{who}{self.value:.6g}>{self.bound:.6g}"


class TensionEstimator:
    """Suture tension from the base force/torque sensor, as the magnitude of the
    force change since a tare taken when the robot was at rest (a monitor-grade
    estimate of (7.6-7.10): it also sees inertial forces of fast motions).
    """

    def __init__(self) -> None:
        self._tare: dict[str, np.ndarray] = {}

    def tare(self, measurement: Measurement) -> None:
        """Zero the estimate on the current base force of every robot."""
        for name, robot in measurement.robots.items():
            self._tare[name] = np.array(robot.base_wrench[:3])

    def estimate(self, obs: Observation) -> dict[str, float]:
        """Estimated tension [N] per robot."""
        out: dict[str, float] = {}
        for name, robot in obs.robots.items():
            # Plain floats (the same IEEE operations as on numpy scalars, a fraction of
            # the per-call cost).
            fx, fy, fz = robot.base_wrench[:3].tolist()
            tare = self._tare.get(name)
            if tare is not None:
                tx, ty, tz = tare.tolist()
                fx, fy, fz = fx - tx, fy - ty, fz - tz
            out[name] = math.sqrt(fx * fx + fy * fy + fz * fz)
        return out


class Monitor:
    """Checks invariants and counts violations over a run."""

    def __init__(self) -> None:
        self.violations: list[Violation] = []
        self.max_tension_N = 0.0

    def check(
        self,
        invariant: Invariant | None,
        obs: Observation,
        state: str,
        tension: Mapping[str, float],
        qp_failures: Mapping[str, int],
        sensor_faults: Mapping[str, bool],
        robots: tuple[str, ...] = (),
        base_poses: Mapping[str, Any] | None = None,
    ) -> Violation | None:
        """Return the first violation of ``invariant`` this tick (also recorded), or None.

        Args:
            invariant: the active step's invariant (None: only sensor faults count).
            obs: this tick's observation.
            state: the automaton state (for the record).
            tension: estimated tension per robot [N].
            qp_failures: consecutive QP failures per robot.
            sensor_faults: per robot, whether a sensor dropped out this tick.
            robots: the robots the step drives (empty: all).
            base_poses: robot -> (base position [m], row-major 3x3 rotation) for the
                tool-tip workspace box.
        """
        if tension:
            self.max_tension_N = max(self.max_tension_N, max(tension.values()))
        names = robots or tuple(obs.robots)
        found: Violation | None = None
        for name in names:
            if sensor_faults.get(name, False):
                found = Violation(obs.t, obs.tick, state, name, "sensor", 1.0, 0.0)
                break
            if invariant is None:
                continue
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
        if inv.max_tension_N is not None and tension.get(name, 0.0) > inv.max_tension_N:
            return Violation(
                obs.t, obs.tick, state, name, "tension", tension[name], inv.max_tension_N
            )
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
