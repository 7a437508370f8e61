"""Reachability: the numpy-free closed-form IK against rotation matrices built by scipy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from suture_engine.validation.reach import base_to_world, check_reach, ik, world_to_base

LIMITS = ((-1.2, 1.2), (-1.2, 1.2), (-math.pi, math.pi), (0.02, 0.3))


def _tip(q: tuple[float, float, float, float]) -> np.ndarray:
    """Tool tip = Rx(q1) Ry(q2) Rz(q3) [0, 0, q4]: yaw about x, pitch about y, roll about z."""
    rot = Rotation.from_euler("XYZ", [q[0], q[1], q[2]])  # intrinsic: Rx * Ry * Rz
    return rot.apply([0.0, 0.0, q[3]])


@given(
    st.floats(-1.4, 1.4),
    st.floats(-1.4, 1.4),
    st.floats(-3.0, 3.0),
    st.floats(0.01, 0.3),
)
def test_ik_inverts_the_rotation_chain(q1: float, q2: float, q3: float, q4: float) -> None:
    q = ik(_tip((q1, q2, q3, q4)), q3)
    assert q == pytest.approx((q1, q2, q3, q4), abs=1e-9)


def test_ik_agrees_with_the_robot_package() -> None:
    kin = pytest.importorskip("suture_engine.robot.kinematics")
    rng = np.random.default_rng(0)
    for _ in range(50):
        p = rng.uniform([-0.1, -0.1, 0.02], [0.1, 0.1, 0.2])
        assert ik(p, 0.3) == pytest.approx(tuple(kin.inverse_kinematics(p, 0.3)), abs=1e-12)


@given(
    st.tuples(*[st.floats(-0.2, 0.2)] * 3),
    st.tuples(*[st.floats(-math.pi, math.pi)] * 3),
    st.tuples(*[st.floats(-0.2, 0.2)] * 3),
)
def test_base_frame_matches_scipy(origin: tuple, rpy: tuple, point: tuple) -> None:
    rot = Rotation.from_euler("xyz", rpy)  # extrinsic x, y, z: Rz * Ry * Rx
    expected = rot.inv().apply(np.subtract(point, origin))
    assert world_to_base(point, origin, rpy) == pytest.approx(tuple(expected), abs=1e-12)
    assert base_to_world(world_to_base(point, origin, rpy), origin, rpy) == pytest.approx(
        point, abs=1e-12
    )


def test_reachable_target() -> None:
    assert check_reach((0.05, -0.03, 0.12), LIMITS).problem == ""


def test_outside_the_joint_limits() -> None:
    reach = check_reach((0.0, -0.2, 0.05), LIMITS)  # yaw atan2(0.2, 0.05) = 76 deg > 69 deg
    assert reach.problem == "unreachable" and "yaw" in reach.reason


def test_too_far_or_too_close_is_an_insertion_problem() -> None:
    assert "insertion" in check_reach((0.0, 0.0, 0.5), LIMITS).reason
    assert "insertion" in check_reach((0.0, 0.0, 0.01), LIMITS).reason


def test_singularities_3_23() -> None:
    wide = ((-3.0, 3.0), (-3.0, 3.0), (-math.pi, math.pi), (0.0, 0.3))
    assert check_reach((0.0, 0.0, 0.0), wide).problem == "singularity"  # q4 = 0
    near = check_reach((0.1, 0.0, 0.001), wide)  # q2 = 89.4 deg
    assert near.problem == "singularity" and "q2" in near.reason
    assert check_reach((0.1, 0.0, 0.02), wide, margin=math.radians(5)).problem == ""  # 78.7 deg
