"""Minimum-jerk trajectories and frame helpers, against finite differences and PyBullet."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from suture_engine.runtime.trajectory import (
    MinJerk,
    min_jerk_duration,
    rpy_matrix,
    tool_tip_world,
    world_to_base,
)

finite = st.floats(-1.0, 1.0, allow_nan=False)


@given(
    st.lists(finite, min_size=4, max_size=4),
    st.lists(finite, min_size=4, max_size=4),
    st.floats(0.05, 5.0),
)
def test_min_jerk_is_rest_to_rest_and_its_velocity_is_the_derivative(
    q0: list[float], q1: list[float], duration: float
) -> None:
    traj = MinJerk(q0, q1, duration)
    start, end = traj(0.0), traj(duration)
    np.testing.assert_allclose(start.q, q0, atol=1e-12)
    np.testing.assert_allclose(end.q, q1, atol=1e-12)
    np.testing.assert_allclose(start.qd, 0.0, atol=1e-12)
    np.testing.assert_allclose(end.qd, 0.0, atol=1e-12)
    assert end.done and not traj(0.5 * duration).done
    h = 1e-6 * duration
    for frac in (0.1, 0.3, 0.5, 0.8):
        t = frac * duration
        fd = (traj(t + h).q - traj(t - h).q) / (2 * h)
        np.testing.assert_allclose(traj(t).qd, fd, rtol=1e-5, atol=1e-7)
    # peak rate 1.875 / T at the middle
    mid = traj(0.5 * duration).qd
    np.testing.assert_allclose(mid, 1.875 * (np.array(q1) - q0) / duration, atol=1e-9)


def test_duration_gives_the_peak_speed() -> None:
    assert min_jerk_duration(0.1, 0.05) == pytest.approx(1.875 * 0.1 / 0.05)
    assert min_jerk_duration(0.0, 0.05, minimum=0.2) == 0.2
    with pytest.raises(ValueError):
        min_jerk_duration(0.1, 0.0)


def test_tool_tip_world_matches_pybullet() -> None:
    import pybullet as p

    from backends.pybullet.backend import _quaternion
    from backends.pybullet.robot import EndoBotSim

    client = p.connect(p.DIRECT)
    try:
        rpy = (math.pi, 0.1, -0.3)
        pos = (0.02, -0.05, 0.12)
        q = (0.2, -0.3, 0.4, 0.09)
        sim = EndoBotSim(client, base_position=pos, base_orientation=_quaternion(rpy), q0=q)
        truth, _ = sim.true_tool_pose()
        rot = rpy_matrix(rpy)  # what the runtime uses
        np.testing.assert_allclose(rot, p.getMatrixFromQuaternion(_quaternion(rpy)), atol=1e-12)
        np.testing.assert_allclose(
            rot, p.getMatrixFromQuaternion(p.getQuaternionFromEuler(rpy)), atol=1e-12
        )
        np.testing.assert_allclose(tool_tip_world(q, (pos, rot)), truth, atol=1e-9)
        np.testing.assert_allclose(
            world_to_base(truth, (pos, rot)),
            tool_tip_world(q, ((0.0, 0.0, 0.0), (1, 0, 0, 0, 1, 0, 0, 0, 1))),
            atol=1e-9,
        )
    finally:
        p.disconnect(client)
