"""ModeController: the Autonomous position law and the pose it holds afterwards."""

from __future__ import annotations

import numpy as np

from suture_engine.control.model import endobot_control_model
from suture_engine.control.pd import PDController, gains_at_workspace_centre
from suture_engine.robot import endobot
from suture_engine.robot.params import E1
from suture_engine.runtime.automaton import Mode
from suture_engine.runtime.controller import ModeController
from suture_engine.runtime.observation import RobotCommand, RobotObservation, ToolState

ROBOT = "endobot_1"


def _obs(q: np.ndarray, qd: np.ndarray) -> RobotObservation:
    return RobotObservation(q=q, qd=qd, base_wrench=np.zeros(6), tool=ToolState())


def _pd_oracle(q: np.ndarray, qd: np.ndarray, q_des: np.ndarray, qd_des: np.ndarray) -> np.ndarray:
    """(5.10) by hand: G(q) - Kp (q - q_des) - Kd (qd - qd_des) + Fc sign(qd_des)."""
    gains = gains_at_workspace_centre(7.0, E1)
    fc = np.asarray(endobot_control_model(E1).coulomb, dtype=float)
    g = endobot.gravity_vector(q, E1)
    return g - gains.kp * (q - q_des) - gains.kd * (qd - qd_des) + fc * np.sign(qd_des)


def test_position_command_then_no_command_holds_the_commanded_pose() -> None:
    ctl = ModeController((ROBOT,), 1e-3)
    q = np.array([0.1, -0.2, 0.3, 0.1])
    qd = np.array([0.01, 0.0, -0.02, 0.001])
    q_cmd = np.array([0.12, -0.18, 0.25, 0.105])
    v_cmd = np.array([0.1, -0.1, 0.0, 0.01])
    # The first Autonomous tick captures the pose; the command drives the PD law.
    tau = ctl.torque(ROBOT, Mode.AUTONOMOUS, _obs(q, qd), RobotCommand.position(q_cmd, v_cmd))
    np.testing.assert_allclose(tau, _pd_oracle(q, qd, q_cmd, v_cmd), rtol=1e-12, atol=1e-12)
    # A trusted (handed-over) set point: then no command: the last set point is held.
    handed = q_cmd + 0.01
    ctl.torque(ROBOT, Mode.AUTONOMOUS, _obs(q, qd), RobotCommand.trusted_position(handed))
    tau = ctl.torque(ROBOT, Mode.AUTONOMOUS, _obs(q, qd), None)
    np.testing.assert_allclose(tau, _pd_oracle(q, qd, q_cmd + 0.01, np.zeros(4)), atol=1e-12)
    held = ctl.held_pose(ROBOT)
    assert held is not None and np.array_equal(held, q_cmd + 0.01)


def test_a_writable_set_point_is_copied_into_the_hold() -> None:
    """A command whose q is still writable (built without a constructor's freeze) must
    not let its later changes move the held pose."""
    ctl = ModeController((ROBOT,), 1e-3)
    q = np.array([0.1, -0.2, 0.3, 0.1])
    cmd = RobotCommand.position(q + 0.02)
    q_free = np.array(cmd.q)  # a writable array in a command's q
    object.__setattr__(cmd, "q", q_free)
    ctl.torque(ROBOT, Mode.AUTONOMOUS, _obs(q, np.zeros(4)), cmd)
    q_free += 1.0
    held = ctl.held_pose(ROBOT)
    assert held is not None and np.allclose(held, q + 0.02)


def test_pd_controller_agrees_with_the_oracle_for_lock() -> None:
    ctl = ModeController((ROBOT,), 1e-3)
    q0 = np.array([0.0, 0.1, 0.0, 0.12])
    ctl.torque(ROBOT, Mode.LOCK, _obs(q0, np.zeros(4)), None)  # captures q0
    q = q0 + np.array([0.01, -0.01, 0.02, 0.001])
    qd = np.array([0.1, 0.0, 0.0, 0.0])
    tau = ctl.torque(ROBOT, Mode.LOCK, _obs(q, qd), None)
    pd = PDController(gains_at_workspace_centre(7.0, E1), endobot_control_model(E1))
    np.testing.assert_allclose(tau, pd.update(q, qd, q0, np.zeros(4)), atol=1e-12)
    np.testing.assert_allclose(tau, _pd_oracle(q, qd, q0, np.zeros(4)), atol=1e-12)
