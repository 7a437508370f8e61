"""Test helpers shipped with the engine, so users test their procedures as we test ours.

- :class:`IdealBackend`: two EndoBots as the rigid-body model
  ``M(q) q'' + G(q) = tau + J(q)^T F_ext`` (Coriolis and friction left out),
  integrated by semi-implicit Euler at the control period; the base sensor
  reads the robot's weight plus the external force at the tool tip. No
  physics engine, deterministic, fast: for tests of the runtime, not of the
  robot.
- :class:`ScriptedSkill`: a stub activity that holds its robots and reports
  success or failure after a given time (or never), with a counter of starts.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from suture_engine.runtime.observation import (
    N_JOINTS,
    Command,
    CommandMode,
    Measurement,
    RobotCommand,
    RobotMeasurement,
    SceneGeometry,
    SkillStatus,
    StepResult,
    ToolState,
)

__all__ = ["DEFAULT_Q", "IdealBackend", "ScriptedSkill"]

DEFAULT_Q = (0.0, 0.2, 0.0, 0.12)
"""A comfortable start pose [rad, rad, rad, m]."""

_WEIGHT_N = 20.0


def _angles(bend: Any) -> tuple[float, float]:
    """Two joint angles [rad] as a tuple of floats."""
    return (float(bend[0]), float(bend[1]))


class IdealBackend:
    """A model-only backend (see the module docstring).

    Args:
        robots: robot names.
        q0: start pose per robot (default :data:`DEFAULT_Q`).
        dt: control period [s].
        damping: viscous joint damping [N*m*s/rad, N*s/m].
        tools: tool kind per robot ("bent-tip-grasper", ...); a robot not named reports
            a "grasper". The tools follow their commands at once (jaws, hook, bend).
    """

    name = "ideal"

    def __init__(
        self,
        robots: tuple[str, ...] = ("endobot_1", "endobot_2"),
        q0: Mapping[str, tuple[float, ...]] | None = None,
        dt: float = 1e-3,
        damping: float = 0.05,
        tools: Mapping[str, str] | None = None,
    ) -> None:
        self.robots = robots
        self._kinds = dict(tools or {})
        self._q0 = dict(q0 or {})
        self.dt = dt
        self.damping = damping
        self._closed = False
        self.tick = 0
        self.q: dict[str, np.ndarray] = {}
        self.qd: dict[str, np.ndarray] = {}
        self.tau: dict[str, np.ndarray] = {}
        self.tools: dict[str, ToolState] = {}
        self._forces: list[tuple[str, np.ndarray, int]] = []
        self._hands: list[tuple[str, np.ndarray, float, int]] = []

    def reset(self, scene: Any = None, seed: int = 0) -> Measurement:
        """Put the robots at their start poses; ``scene`` and ``seed`` are not needed."""
        del scene, seed
        self.tick = 0
        self._forces = []
        self._hands = []
        for r in self.robots:
            self.q[r] = np.array(self._q0.get(r, DEFAULT_Q), dtype=np.float64)
            self.qd[r] = np.zeros(N_JOINTS)
            self.tau[r] = np.zeros(N_JOINTS)
            kind = self._kinds.get(r)
            self.tools[r] = ToolState() if kind is None else ToolState(kind=kind)
        return self.observe()

    def _force(self, robot: str) -> np.ndarray:
        f = np.zeros(3)
        for name, force, until in self._forces:
            if name == robot and self.tick < until:
                f += force
        if self._hands:
            f += self._hand_force(robot)
        return f

    def observe(self) -> Measurement:
        """Encoder positions and the base wrench (weight plus the tool-tip force)."""
        robots = {}
        for r in self.robots:
            f = self._force(r)
            wrench = np.array([f[0], f[1], f[2] - _WEIGHT_N, 0.0, 0.0, 0.0])
            robots[r] = RobotMeasurement(self.q[r], wrench, self.tools[r])
        return Measurement(self.tick, self.tick * self.dt, robots)

    def apply(self, command: Command) -> None:
        """Keep the torques of TORQUE commands; apply tool commands at once."""
        for r, rc in command.robots.items():
            if rc.mode is CommandMode.TORQUE and rc.tau is not None:
                self.tau[r] = np.array(rc.tau)
            if rc.tool is not None:
                t = self.tools[r]
                self.tools[r] = ToolState(
                    t.kind,
                    t.jaw_closed if rc.tool.jaw_closed is None else rc.tool.jaw_closed,
                    t.jaw2_closed if rc.tool.jaw2_closed is None else rc.tool.jaw2_closed,
                    t.hook_extension if rc.tool.hook_extension is None else rc.tool.hook_extension,
                    t.bend if rc.tool.bend is None else _angles(rc.tool.bend),
                )

    def apply_external_force(
        self, robot: str, force: tuple[float, float, float], duration: float
    ) -> None:
        """Push the tool tip of ``robot`` with ``force`` [N] for ``duration`` [s]."""
        ticks = max(1, round(duration / self.dt))
        self._forces.append((robot, np.array(force, dtype=np.float64), self.tick + ticks))

    def apply_operator_hand(
        self, robot: str, velocity: tuple[float, float, float], stiffness: float, duration: float
    ) -> None:
        """A hand starting at the tool tip, moving at ``velocity`` [m/s] (base frame), pulling
        the tip through a spring of ``stiffness`` [N/m] for ``duration`` [s]."""
        from suture_engine.robot.kinematics import forward_kinematics

        ticks = max(1, round(duration / self.dt))
        x0 = np.asarray(forward_kinematics(self.q[robot]).position)
        v = np.array(velocity, dtype=np.float64)
        for k in range(ticks):  # the hand's force, precomputed per tick as the tip moves
            self._hands.append((robot, x0 + v * (k * self.dt), stiffness, self.tick + k))

    def _hand_force(self, robot: str) -> np.ndarray:
        from suture_engine.robot.kinematics import forward_kinematics

        f = np.zeros(3)
        for name, x_hand, k, tick in self._hands:
            if name == robot and tick == self.tick:
                f += k * (x_hand - np.asarray(forward_kinematics(self.q[robot]).position))
        return f

    def step(self) -> None:
        """Integrate one period: M q'' = tau - G(q) + J^T F - b q'."""
        from suture_engine.robot import endobot
        from suture_engine.robot.kinematics import analytical_jacobian

        for r in self.robots:
            q, qd = self.q[r], self.qd[r]
            m = np.asarray(endobot.mass_matrix(q))
            g = np.asarray(endobot.gravity_vector(q))
            jac = np.asarray(analytical_jacobian(q))[:3]
            rhs = self.tau[r] - g + jac.T @ self._force(r) - self.damping * qd
            qdd = np.linalg.solve(m, rhs)
            self.qd[r] = qd + qdd * self.dt
            self.q[r] = q + self.qd[r] * self.dt
        self.tick += 1

    def geometry(self) -> SceneGeometry:
        """A default geometry (entry/exit points at the origin)."""
        return SceneGeometry()

    def ground_truth(self) -> Mapping[str, Any]:
        """None: this backend has no suture."""
        return {}

    def close(self) -> None:
        """Nothing to release."""
        self._closed = True


class ScriptedSkill:
    """A stub skill: holds the start pose of ``robots``; succeeds or fails after ``after_s``.

    Args:
        outcome: "success", "failure", "raise" (raises in step) or "never".
        after_s: time after the start at which the outcome happens [s].
        robots: robots it commands (position hold).
        fail_first: for outcome "success", fail instead on the first ``fail_first`` starts.
    """

    starts: ClassVar[dict[str, int]] = {}

    def __init__(
        self,
        name: str,
        outcome: str = "success",
        after_s: float = 0.01,
        robots: tuple[str, ...] = ("endobot_1",),
        fail_first: int = 0,
    ) -> None:
        self.name = name
        self.outcome = outcome
        self.after_s = after_s
        self.robots = robots
        self.fail_first = fail_first
        self._t0 = 0.0
        self._hold: dict[str, np.ndarray] = {}
        self._n = 0

    def start(self, ctx: Any) -> None:
        """Remember the start time and pose."""
        self._t0 = ctx.t0
        self._n = ScriptedSkill.starts.get(self.name, 0) + 1
        ScriptedSkill.starts[self.name] = self._n
        self._hold = {r: np.array(ctx.start.robots[r].q) for r in self.robots}

    def step(self, ctx: Any, obs: Any) -> StepResult:
        """Hold; report the scripted outcome once ``after_s`` has passed."""
        cmd = Command({r: RobotCommand.position(q) for r, q in self._hold.items()})
        if obs.t - self._t0 + 1e-12 < self.after_s or self.outcome == "never":
            return StepResult(cmd)
        if self.outcome == "raise":
            raise RuntimeError(f"{self.name} raised on purpose")
        if self.outcome == "failure" or self._n <= self.fail_first:
            return StepResult(cmd, SkillStatus.FAILURE, f"{self.name} failed on purpose")
        return StepResult(cmd, SkillStatus.SUCCESS)
