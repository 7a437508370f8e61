"""Circle tracking on the simulated EndoBot: friction compensation (Table 5.1) and LQG."""

from __future__ import annotations

import numpy as np
import pytest

from suture_engine.control.tracking import circle_trajectory, run_circle_tracking
from suture_engine.robot import endobot


def test_circle_reference_is_consistent_with_kinematics() -> None:
    traj = circle_trajectory(0.005, 0.5, 2.0)
    # FK of the IK gives back the circle; the joint velocity maps to the tip velocity
    # by central differences of the tip path (an oracle independent of the Jacobian).
    tips = np.array([endobot.forward_kinematics(q).position for q in traj.q])
    np.testing.assert_allclose(tips, traj.position, atol=1e-12)
    k = 700
    dq = (traj.q[k + 1] - traj.q[k - 1]) / (2 * 1e-3)
    np.testing.assert_allclose(dq, traj.qd[k], rtol=1e-4, atol=1e-9)
    radius = np.linalg.norm(traj.position[:, :2], axis=1)
    np.testing.assert_allclose(radius, 0.005)


def test_friction_compensation_cuts_pd_error_short_run() -> None:
    off = run_circle_tracking(0.005, 0.5, friction_compensation=False, periods=1.5)
    on = run_circle_tracking(0.005, 0.5, friction_compensation=True, periods=1.5)
    assert off.mean_cartesian_error_mm > 0.05  # friction is felt without compensation
    assert on.mean_cartesian_error_mm < 0.5 * off.mean_cartesian_error_mm


@pytest.mark.slow
@pytest.mark.parametrize("controller", ["pd", "lqg"])
def test_friction_compensation_halves_circle_error_with_stiction_and_model_mismatch(
    controller: str,
) -> None:
    from suture_engine.robot.params import E2

    # Robot E1 with static + Stribeck friction, controller built on E2's parameters.
    kw = {"controller": controller, "friction_model": "d", "model_params": E2}
    off = run_circle_tracking(0.010, 0.25, friction_compensation=False, **kw)  # type: ignore[arg-type]
    on = run_circle_tracking(0.010, 0.25, friction_compensation=True, **kw)  # type: ignore[arg-type]
    assert on.mean_cartesian_error_mm < 0.5 * off.mean_cartesian_error_mm
    assert max(on.mean_joint_error_deg) < max(off.mean_joint_error_deg)
