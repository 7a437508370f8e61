"""The joint-level laws under every mode (thesis chapter 5, 4.6.3).

Per robot and per tick, :class:`ModeController` turns the mode and the skill's
command into joint torques:

- **Lock** regulates the pose captured when the robot entered Lock,
  x1 = x_cp, x2 = 0 (4.44): PD with gravity compensation (5.10) towards it.
- **Manual** applies gravity compensation, tau = G^(q) (5.1); the operator
  moves the back-drivable arm (a force at the tool tip in simulation). When
  the interrupted step offers a shared-control law (its skill's
  ``manual_step``, e.g. a virtual fixture (6.24)), its torques are used instead.
- **Autonomous** follows the skill: a position setpoint (with velocity
  feed-forward) through the PD law (5.10, 5.19), a velocity setpoint
  integrated into a position setpoint, or torques passed through.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from suture_engine.runtime.automaton import Mode
from suture_engine.runtime.observation import N_JOINTS, CommandMode, RobotCommand, RobotObservation

__all__ = ["ModeController"]

FloatArray = NDArray[np.float64]

# Enum members bound once for the per-tick tests: ``Mode.X`` on the class costs ~60 ns
# in CPython 3.11, a module global ~10 ns.
_AUTONOMOUS, _MANUAL = Mode.AUTONOMOUS, Mode.MANUAL
_TORQUE, _VELOCITY = CommandMode.TORQUE, CommandMode.VELOCITY


class ModeController:
    """Lock / Manual / Autonomous joint laws for a set of robots.

    The model is the thesis' E1 parameter set (Tables 3.3-3.4) with gravity
    expressed in each robot's base frame.

    Args:
        robots: robot names.
        dt: control period [s].
        frequency_hz: natural frequency of the critically damped PD (5.15-5.16) [Hz].
        gravity_base: per robot, gravity in its base frame [m/s^2]; missing robots
            take E1's default (base z axis pointing down).
    """

    def __init__(
        self,
        robots: tuple[str, ...],
        dt: float,
        frequency_hz: float = 7.0,
        gravity_base: Mapping[str, tuple[float, float, float]] | None = None,
    ) -> None:
        import dataclasses

        from suture_engine.control.gravity import GravityCompensation
        from suture_engine.control.model import endobot_control_model
        from suture_engine.control.pd import PDController, gains_at_workspace_centre
        from suture_engine.robot.params import E1

        self.dt = dt
        self._pd = {}
        self._gc = {}
        for r in robots:
            g = (gravity_base or {}).get(r)
            params = E1 if g is None else dataclasses.replace(E1, gravity=(g[0], g[1], g[2]))
            model = endobot_control_model(params)
            gains = gains_at_workspace_centre(frequency_hz, params)
            self._pd[r] = PDController(gains, model, friction=True)
            self._gc[r] = GravityCompensation(model)
        self._hold: dict[str, FloatArray] = {}
        self._vel_setpoint: dict[str, FloatArray] = {}
        self._zero = np.zeros(N_JOINTS)
        self._last_mode: dict[str, Mode] = {}

    def capture(self, robot: str, q: FloatArray) -> None:
        """Capture the current pose x_cp [rad, m] that Lock regulates (4.44)."""
        self._hold[robot] = np.array(q, dtype=np.float64)

    def held_pose(self, robot: str) -> FloatArray | None:
        """The pose Lock regulates (None before the first capture)."""
        return self._hold.get(robot)

    def torque(
        self,
        robot: str,
        mode: Mode,
        obs: RobotObservation,
        command: RobotCommand | None,
    ) -> FloatArray:
        """Joint torques [N*m, N*m, N*m, N] for one robot this tick (a fresh array)."""
        last = self._last_mode.get(robot)
        if mode is not last:
            if mode is not Mode.MANUAL:
                self.capture(robot, obs.q)
            self._vel_setpoint.pop(robot, None)
            self._last_mode[robot] = mode
        if mode is _MANUAL:
            if command is not None and command.mode is _TORQUE:
                assert command.tau is not None
                return np.array(command.tau)  # shared control under a fixture (6.24)
            return np.array(self._gc[robot].update(obs.q))
        if mode is _AUTONOMOUS and command is not None:
            if command.mode is _TORQUE:
                assert command.tau is not None
                return np.array(command.tau)
            if command.mode is _VELOCITY:
                assert command.qd is not None
                sp = self._vel_setpoint.get(robot)
                if sp is None:
                    sp = np.array(obs.q)
                sp = sp + command.qd * self.dt
                self._vel_setpoint[robot] = sp
                self._hold[robot] = sp
                return self._pd[robot].update(obs.q, obs.qd, sp, command.qd)  # a fresh array
            assert command.q is not None
            qd_des = command.qd if command.qd is not None else self._zero
            q_cmd = command.q
            # A read-only set point (every RobotCommand constructor freezes it) is kept as
            # it is; anything else is copied.
            self._hold[robot] = q_cmd if not q_cmd.flags.writeable else np.array(q_cmd)
            self._vel_setpoint.pop(robot, None)
            return self._pd[robot].update(obs.q, obs.qd, command.q, qd_des)
        hold = self._hold.get(robot)
        if hold is None:
            hold = self._hold[robot] = np.array(obs.q)
        return self._pd[robot].update(obs.q, obs.qd, hold, self._zero)

    def reset(self, poses: Mapping[str, FloatArray]) -> None:
        """Forget modes and capture ``poses`` as the held poses."""
        self._last_mode.clear()
        self._vel_setpoint.clear()
        for robot, q in poses.items():
            self.capture(robot, q)
