"""The parameter sets: Table 3.1, 3.3 and 3.4 values, physical bodies, typed errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from suture_engine.robot.params import (
    E1,
    E2,
    BodyDesign,
    EndoBotParams,
    InvalidParameters,
    JointLimits,
    endobot_params,
)


def test_tables_3_3_and_3_4() -> None:
    e1 = [(j.inertia, j.gravity_moment, j.friction.coulomb, j.friction.viscous) for j in E1.joints]
    assert e1 == [
        (0.0487, 0.1273, 0.127, 0.044),
        (0.0441, 0.1122, 0.120, 0.067),
        (0.0006, 0.0, 0.029, 0.847),
        (0.2451, 0.0, 0.069, 0.742),
    ]
    e2 = [(j.inertia, j.gravity_moment, j.friction.coulomb, j.friction.viscous) for j in E2.joints]
    assert e2 == [
        (0.0528, 0.1305, 0.149, 0.029),
        (0.0427, 0.1155, 0.125, 0.054),
        (0.0005, 0.0, 0.019, 0.795),
        (0.2605, 0.0, 0.045, 0.484),
    ]


def test_table_3_1_torque_per_volt() -> None:
    """τ = Ka Kt Kg vc (3.76), evaluated by hand."""
    expected = [
        0.375 * 0.01342 * 134,
        0.375 * 0.01342 * 134,
        0.375 * 0.00652 * 72.88,
        0.375 * 0.00996 * 66,
    ]
    got = [j.motor.torque_per_volt for j in E1.joints]
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    assert E1.joints[0].motor.max_torque == pytest.approx(expected[0] * 10.0)


@pytest.mark.parametrize("params", [E1, E2])
def test_bodies_are_physical_and_reproduce_the_lumped_values(params: EndoBotParams) -> None:
    _, b2, b3, b4 = params.bodies
    for b in params.bodies:
        ixx, iyy, izz = b.inertia
        assert b.mass > 0 and min(b.inertia) > 0
        assert ixx + iyy >= izz and iyy + izz >= ixx and ixx + izz >= iyy
    # lumped inertia of joint 1 about x through the RCM at q = 0 (parallel axis theorem)
    i1 = sum(b.inertia[0] + b.mass * b.com_z**2 for b in params.bodies)
    i2 = sum(b.inertia[1] + b.mass * b.com_z**2 for b in (b2, b3, b4))
    assert i1 == pytest.approx(params.joints[0].inertia, rel=1e-12)
    assert i2 == pytest.approx(params.joints[1].inertia, rel=1e-12)
    assert b3.inertia[2] + b4.inertia[2] == pytest.approx(params.joints[2].inertia, rel=1e-12)
    assert b4.mass == params.joints[3].inertia
    ml1 = sum(b.mass * b.com_z for b in params.bodies)
    ml2 = sum(b.mass * b.com_z for b in (b2, b3, b4))
    assert ml1 == pytest.approx(params.joints[0].gravity_moment, rel=1e-12)
    assert ml2 == pytest.approx(params.joints[1].gravity_moment, rel=1e-12)


def test_parameters_are_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        E1.name = "x"  # type: ignore[misc]


def test_impossible_sets_are_typed_errors() -> None:
    with pytest.raises(InvalidParameters) as err:
        endobot_params(
            "tiny", (0.001, 0.0441, 0.0006, 0.2451), (0.1273, 0.1122), (0.1,) * 4, (0.1,) * 4
        )
    assert err.value.name == "yaw.inertia"
    with pytest.raises(InvalidParameters):
        endobot_params(
            "x",
            (0.0487, 0.0441, 0.0006, 0.2451),
            (0.1273, 0.1122),
            (0.1,) * 4,
            (0.1,) * 4,
            design=BodyDesign(shaft_inertia_z=0.001),
        )
    with pytest.raises(InvalidParameters):
        JointLimits(1.0, -1.0, 1.0)
