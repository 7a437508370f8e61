"""Friction models a-d (3.42-3.45) against hand-evaluated curves."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from suture_engine.robot import endobot
from suture_engine.robot.friction import FrictionModel, friction_levels, joint_friction
from suture_engine.robot.params import E1, FrictionParams, InvalidParameters

P = FrictionParams(coulomb=0.1, viscous=0.05, static=0.15, stribeck_velocity=0.02)


@given(st.floats(-5.0, 5.0).filter(lambda v: v != 0.0))
def test_models_in_motion(v: float) -> None:
    s = math.copysign(1.0, v)
    assert joint_friction(v, P, FrictionModel.COULOMB) == pytest.approx(0.1 * s)
    assert joint_friction(v, P, FrictionModel.COULOMB_VISCOUS) == pytest.approx(0.1 * s + 0.05 * v)
    assert joint_friction(v, P, FrictionModel.STATIC) == pytest.approx(0.1 * s + 0.05 * v)
    stribeck = 0.1 * s + 0.05 * math.exp(-((abs(v) / 0.02) ** 2)) * s + 0.05 * v
    assert joint_friction(v, P, FrictionModel.STRIBECK) == pytest.approx(stribeck)


def test_static_friction_at_rest_balances_up_to_fs() -> None:
    for model in (FrictionModel.STATIC, FrictionModel.STRIBECK):
        assert joint_friction(0.0, P, model, tau_applied=0.12) == pytest.approx(0.12)
        assert joint_friction(0.0, P, model, tau_applied=-0.3) == pytest.approx(-0.15)
    assert joint_friction(0.0, P, FrictionModel.COULOMB_VISCOUS, tau_applied=0.12) == 0.0


def test_stribeck_curve_shape() -> None:
    """Break-away Fs at 0+, falls to Fc + Fv v well above q̇s (Fig. 3.10 d)."""
    assert joint_friction(1e-9, P, FrictionModel.STRIBECK) == pytest.approx(0.15, abs=1e-9)
    assert joint_friction(0.2, P, FrictionModel.STRIBECK) == pytest.approx(0.1 + 0.01, abs=1e-9)
    vs = np.linspace(1e-4, 0.03, 50)
    coulomb_part = [joint_friction(v, P, FrictionModel.STRIBECK) - 0.05 * v for v in vs]
    assert np.all(np.diff(coulomb_part) < 0.0)


def test_vector_api_uses_table_3_3_and_letters() -> None:
    qd = np.array([0.5, -0.5, 2.0, -0.1])
    expected = [
        0.127 + 0.044 * 0.5,
        -(0.120 + 0.067 * 0.5),
        0.029 + 0.847 * 2.0,
        -(0.069 + 0.742 * 0.1),
    ]
    np.testing.assert_allclose(endobot.friction_torque(qd), expected)
    np.testing.assert_allclose(endobot.friction_torque(qd, E1, "a"), [0.127, -0.120, 0.029, -0.069])
    with pytest.raises(ValueError):
        endobot.friction_torque(qd, E1, "z")


def test_invalid_friction_parameters_are_typed_errors() -> None:
    with pytest.raises(InvalidParameters) as err:
        FrictionParams(coulomb=0.2, viscous=0.1, static=0.1)
    assert err.value.name == "static"
    with pytest.raises(InvalidParameters):
        FrictionParams(coulomb=-0.1, viscous=0.1, static=0.1)


@pytest.mark.parametrize("model", list(FrictionModel))
def test_friction_levels_agree_with_the_single_joint_models(model: FrictionModel) -> None:
    """In motion a joint feels slide sgn(q̇) + Fv q̇; at rest it holds up to brk."""
    joints = [j.friction for j in E1.joints] + [P]
    velocities = [0.3, -0.004, 0.0, 5e-8, -2e-3]
    slide, brk = friction_levels(
        velocities,
        [f.coulomb for f in joints],
        [f.static for f in joints],
        [f.stribeck_velocity for f in joints],
        [f.stribeck_exponent for f in joints],
        model,
        1e-7,
    )
    for v, f, sl, br in zip(velocities, joints, slide, brk, strict=True):
        viscous = 0.0 if model is FrictionModel.COULOMB else f.viscous
        if abs(v) > 1e-7:
            expected = joint_friction(v, f, model)
            assert sl * math.copysign(1.0, v) + viscous * v == pytest.approx(expected, abs=1e-15)
            assert br == sl
        else:
            assert sl == f.coulomb
            static = model in (FrictionModel.STATIC, FrictionModel.STRIBECK)
            assert br == (joint_friction(0.0, f, model, tau_applied=1e3) if static else sl)
