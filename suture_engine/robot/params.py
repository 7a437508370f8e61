"""The EndoBot parameter set (thesis Tables 3.1, 3.3, 3.4) as frozen dataclasses.

The thesis identifies, per joint, an inertia ``I`` and a gravity moment ``ml``
(joints 1-2), the roll inertia (joint 3), the mass of the translational stage
(joint 4, listed in the ``I`` column in [kg]) and Coulomb / viscous friction.
Those are *lumped* values: each joint was excited alone, the others held at
their "synchronization positions". This module fixes that reference pose as
``q = 0`` (tool vertical, insertion ``q4 = 0`` with the tool tip at the remote
centre of motion) and builds a four-body rigid model whose lumped values at
the reference pose are exactly the table values, so that the analytic model
(:mod:`suture_engine.robot.dynamics`) and the generated URDF describe the same
robot.

Base frame convention: origin at the remote centre of motion (the incision),
``z`` along the tool when ``q = 0``, pointing into the patient. Gravity is a
vector in that frame; by default ``(0, 0, +9.81)`` [m/s^2], i.e. the tool
hangs down into the abdomen.

Choices not in the thesis (documented here and in the report):

- the free geometry of the four bodies (masses of the arches and sleeve, the
  shaft's centre of mass 0.10 m behind the tool tip, small inertias); only the
  lumped values below are dynamically observable in single-joint experiments;
- Stribeck terms: ``Fs = 1.2 Fc``, ``vs = 0.01`` [rad/s or m/s],
  ``delta_s = 2``; the thesis gives only Fc and Fv;
- joint limits: yaw and pitch +-60 deg, roll +-180 deg, insertion 0-0.20 m;
- a +-10 V command limit for the servo amplifiers of Table 3.1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

from suture_engine.errors import SutureError

__all__ = [
    "E1",
    "E2",
    "BodyDesign",
    "DynamicCoefficients",
    "EndoBotParams",
    "FrictionParams",
    "InvalidParameters",
    "JointLimits",
    "JointParams",
    "MotorParams",
    "RigidBody",
    "endobot_params",
]

GRAVITY = 9.81
"""Standard gravity [m/s^2]."""


class InvalidParameters(SutureError):
    """A parameter set that no physical robot can have.

    Attributes:
        name: the offending quantity.
        value: its value.
        reason: why it is rejected.
    """

    code = "invalid-robot-parameters"

    def __init__(self, name: str, value: float, reason: str) -> None:
        super().__init__(f"robot parameter {name}={value!r}: {reason}")
        self.name = name
        self.value = value
        self.reason = reason


@dataclass(frozen=True)
class MotorParams:
    """DC servo drive of one joint (Table 3.1, torque law (3.76)).

    Attributes:
        amplifier_gain: Ka [A/V].
        torque_constant: Kt [N*m/A].
        gear_ratio: Kg [-].
        voltage_limit: largest control voltage |vc| [V] (a choice; not in the thesis).
    """

    amplifier_gain: float
    torque_constant: float
    gear_ratio: float
    voltage_limit: float = 10.0

    @property
    def torque_per_volt(self) -> float:
        """Ka * Kt * Kg [N*m/V] (or [N/V] for the insertion joint), (3.76)."""
        return self.amplifier_gain * self.torque_constant * self.gear_ratio

    @property
    def max_torque(self) -> float:
        """Joint torque at the voltage limit [N*m] (or [N])."""
        return self.torque_per_volt * self.voltage_limit


@dataclass(frozen=True)
class FrictionParams:
    """Joint friction (Table 3.3; models (3.42)-(3.45)).

    Attributes:
        coulomb: Fc [N*m] (or [N]).
        viscous: Fv [N*m*s/rad] (or [N*s/m]).
        static: Fs, break-away friction [N*m] (or [N]); Fs >= Fc.
        stribeck_velocity: q̇s of (3.45) [rad/s] (or [m/s]).
        stribeck_exponent: delta_s of (3.45) [-].
    """

    coulomb: float
    viscous: float
    static: float
    stribeck_velocity: float = 0.01
    stribeck_exponent: float = 2.0

    def __post_init__(self) -> None:
        for name in ("coulomb", "viscous", "static"):
            if getattr(self, name) < 0.0:
                raise InvalidParameters(name, getattr(self, name), "must be >= 0")
        if self.static < self.coulomb:
            raise InvalidParameters("static", self.static, "static friction below Coulomb")
        if self.stribeck_velocity <= 0.0:
            raise InvalidParameters("stribeck_velocity", self.stribeck_velocity, "must be > 0")


@dataclass(frozen=True)
class JointLimits:
    """Travel and speed limits of one joint.

    Attributes:
        lower: lower position limit [rad] (or [m]).
        upper: upper position limit [rad] (or [m]).
        velocity: speed limit [rad/s] (or [m/s]).
    """

    lower: float
    upper: float
    velocity: float

    def __post_init__(self) -> None:
        if not self.lower < self.upper:
            raise InvalidParameters("lower", self.lower, f"not below upper={self.upper}")


@dataclass(frozen=True)
class JointParams:
    """One joint as the thesis identified it (Tables 3.3-3.4).

    Attributes:
        name: joint name (yaw, pitch, roll, insertion).
        inertia: lumped inertia I at the reference pose [kg*m^2]; for the
            insertion joint the moving mass [kg].
        gravity_moment: lumped ml at the reference pose [kg*m] (0 where the
            thesis has none).
        friction: friction parameters.
        motor: servo drive data.
        limits: joint limits.
    """

    name: str
    inertia: float
    gravity_moment: float
    friction: FrictionParams
    motor: MotorParams
    limits: JointLimits


class DynamicCoefficients(NamedTuple):
    """The base dynamic parameters θ of the rigid model, linear in τ = Y θ (3.34).

    The first six are the thesis' lumped Table 3.4 values at the reference pose
    ``q = 0``; the last two are needed by the full 4-DOF model but are not
    observable in single-joint experiments.

    Attributes:
        i1: yaw inertia at q2 = 0, q4 = 0 [kg*m^2].
        i2: pitch inertia at q4 = 0 [kg*m^2].
        i3: roll inertia (tool axis) [kg*m^2].
        m4: mass moved by the insertion joint [kg].
        ml1: yaw gravity moment at q2 = 0, q4 = 0 [kg*m].
        ml2: pitch gravity moment at q4 = 0 [kg*m].
        h4: first mass moment of the insertion body about its frame, m4*l4 [kg*m].
        delta: inertia anisotropy of the pitch body and tool, J2x + A0 - J2z - I3 [kg*m^2].
    """

    i1: float
    i2: float
    i3: float
    m4: float
    ml1: float
    ml2: float
    h4: float
    delta: float


@dataclass(frozen=True)
class RigidBody:
    """One rigid link of the model, with its centre of mass on the link's z axis.

    Attributes:
        name: link name.
        mass: mass [kg].
        com_z: centre of mass along the link frame's z axis [m].
        inertia: principal moments (Ixx, Iyy, Izz) about the centre of mass,
            aligned with the link frame [kg*m^2].
    """

    name: str
    mass: float
    com_z: float
    inertia: tuple[float, float, float]

    def __post_init__(self) -> None:
        if self.mass <= 0.0:
            raise InvalidParameters(f"{self.name}.mass", self.mass, "must be > 0")
        ixx, iyy, izz = self.inertia
        if min(ixx, iyy, izz) <= 0.0:
            raise InvalidParameters(f"{self.name}.inertia", min(ixx, iyy, izz), "must be > 0")
        tol = 1e-12
        if ixx + iyy < izz - tol or iyy + izz < ixx - tol or ixx + izz < iyy - tol:
            raise InvalidParameters(f"{self.name}.inertia", ixx, "violates triangle inequality")


@dataclass(frozen=True)
class BodyDesign:
    """The free geometric choices that turn lumped values into four rigid bodies.

    None of these are in the thesis. Defaults are physically sensible for a
    tabletop arch robot with a ~0.35 m laparoscopic tool.

    Attributes:
        yaw_mass: mass of the yaw arch [kg].
        pitch_mass: mass of the pitch arch [kg].
        sleeve_mass: mass of the roll sleeve [kg].
        sleeve_com_z: sleeve centre of mass along the tool axis [m].
        sleeve_inertia_xy: sleeve transverse inertia about its COM [kg*m^2].
        shaft_com_z: centre of mass of the insertion body relative to the tool tip [m].
        shaft_inertia_xy: insertion body transverse inertia about its COM [kg*m^2].
        shaft_inertia_z: insertion body axial inertia [kg*m^2].
        pitch_axial_ratio: pitch arch Izz / Ixx [-].
    """

    yaw_mass: float = 0.6
    pitch_mass: float = 1.0
    sleeve_mass: float = 0.1
    sleeve_com_z: float = 0.0
    sleeve_inertia_xy: float = 5e-4
    shaft_com_z: float = -0.10
    shaft_inertia_xy: float = 2.5e-3
    shaft_inertia_z: float = 1e-4
    pitch_axial_ratio: float = 0.5


@dataclass(frozen=True)
class EndoBotParams:
    """A full EndoBot parameter set.

    Attributes:
        name: "E1" or "E2" (or a user name).
        joints: the four joints (yaw, pitch, roll, insertion).
        design: free geometric choices of the rigid bodies.
        gravity: gravity acceleration in the base frame [m/s^2].
    """

    name: str
    joints: tuple[JointParams, JointParams, JointParams, JointParams]
    design: BodyDesign = field(default_factory=BodyDesign)
    gravity: tuple[float, float, float] = (0.0, 0.0, GRAVITY)

    def __post_init__(self) -> None:
        if len(self.joints) != 4:
            raise InvalidParameters("joints", float(len(self.joints)), "need exactly 4")
        _ = self.bodies  # validate early: raises InvalidParameters if unbuildable

    @cached_property
    def bodies(self) -> tuple[RigidBody, RigidBody, RigidBody, RigidBody]:
        """The four rigid bodies (yaw arch, pitch arch, roll sleeve, insertion body).

        Solved so that the lumped quantities at ``q = 0`` equal the joint table:
        ml1 - ml2 = m1 l1; ml2 = m2 l2 + m3 l3 + m4 l4; I3 = I3z + I4z;
        I2 = I2y + m2 l2^2 + A0; I1 = I1x + m1 l1^2 + I2x + m2 l2^2 + A0 with
        A0 = I3x + m3 l3^2 + I4x + m4 l4^2 and a symmetric pitch arch I2x = I2y.
        """
        d = self.design
        yaw, pitch, roll, ins = self.joints
        m4 = ins.inertia
        l4 = d.shaft_com_z
        m3, l3 = d.sleeve_mass, d.sleeve_com_z
        l1 = (yaw.gravity_moment - pitch.gravity_moment) / d.yaw_mass
        l2 = (pitch.gravity_moment - m3 * l3 - m4 * l4) / d.pitch_mass
        i4z = d.shaft_inertia_z
        i3z = roll.inertia - i4z
        if i3z <= 0.0:
            raise InvalidParameters("roll.inertia", roll.inertia, "below the shaft's own inertia")
        a0 = d.sleeve_inertia_xy + m3 * l3 * l3 + d.shaft_inertia_xy + m4 * l4 * l4
        i2xy = pitch.inertia - d.pitch_mass * l2 * l2 - a0
        if i2xy <= 0.0:
            raise InvalidParameters("pitch.inertia", pitch.inertia, "too small for the design")
        i1x = yaw.inertia - d.yaw_mass * l1 * l1 - i2xy - d.pitch_mass * l2 * l2 - a0
        if i1x <= 0.0:
            raise InvalidParameters("yaw.inertia", yaw.inertia, "too small for the design")
        # Yaw arch: only Ixx matters dynamically; a sphere-like tensor satisfies the
        # triangle inequality. Sleeve: made symmetric about the tool axis.
        i3xy = max(d.sleeve_inertia_xy, 0.5 * i3z)
        return (
            RigidBody("yaw_link", d.yaw_mass, l1, (i1x, i1x, i1x)),
            RigidBody("pitch_link", d.pitch_mass, l2, (i2xy, i2xy, d.pitch_axial_ratio * i2xy)),
            RigidBody("roll_link", m3, l3, (i3xy, i3xy, i3z)),
            RigidBody("insertion_link", m4, l4, (d.shaft_inertia_xy, d.shaft_inertia_xy, i4z)),
        )

    @cached_property
    def coefficients(self) -> DynamicCoefficients:
        """The base dynamic parameters θ (3.34) implied by the rigid bodies."""
        b1, b2, b3, b4 = self.bodies
        j1 = b1.inertia[0] + b1.mass * b1.com_z**2
        j2x = b2.inertia[0] + b2.mass * b2.com_z**2
        j2y = b2.inertia[1] + b2.mass * b2.com_z**2
        j2z = b2.inertia[2]
        a0 = b3.inertia[0] + b3.mass * b3.com_z**2 + b4.inertia[0] + b4.mass * b4.com_z**2
        cz = b3.inertia[2] + b4.inertia[2]
        ml2 = b2.mass * b2.com_z + b3.mass * b3.com_z + b4.mass * b4.com_z
        return DynamicCoefficients(
            i1=j1 + j2x + a0,
            i2=j2y + a0,
            i3=cz,
            m4=b4.mass,
            ml1=b1.mass * b1.com_z + ml2,
            ml2=ml2,
            h4=b4.mass * b4.com_z,
            delta=j2x + a0 - j2z - cz,
        )

    @property
    def total_mass(self) -> float:
        """Mass of all moving bodies [kg]."""
        return sum(b.mass for b in self.bodies)


_DEG = math.pi / 180.0
_LIMITS = (
    JointLimits(-60.0 * _DEG, 60.0 * _DEG, 2.0),
    JointLimits(-60.0 * _DEG, 60.0 * _DEG, 2.0),
    JointLimits(-math.pi, math.pi, 6.0),
    JointLimits(0.0, 0.20, 0.2),
)
# Table 3.1 (same drives on both robots).
_MOTORS = (
    MotorParams(0.375, 0.01342, 134.0),
    MotorParams(0.375, 0.01342, 134.0),
    MotorParams(0.375, 0.00652, 72.88),
    MotorParams(0.375, 0.00996, 66.0),
)
_NAMES = ("yaw", "pitch", "roll", "insertion")


def _friction(fc: float, fv: float) -> FrictionParams:
    # Fs = 1.2 Fc is a choice: the thesis identified Fc and Fv only.
    return FrictionParams(coulomb=fc, viscous=fv, static=1.2 * fc)


def endobot_params(
    name: str,
    inertia: tuple[float, float, float, float],
    gravity_moment: tuple[float, float],
    coulomb: tuple[float, float, float, float],
    viscous: tuple[float, float, float, float],
    design: BodyDesign | None = None,
) -> EndoBotParams:
    """Build a parameter set from Table 3.4-style columns.

    Args:
        name: robot name.
        inertia: I of joints 1-3 [kg*m^2] and the insertion mass [kg].
        gravity_moment: ml of joints 1-2 [kg*m].
        coulomb: Fc per joint [N*m] (joint 4 [N]).
        viscous: Fv per joint [N*m*s/rad] (joint 4 [N*s/m]).
        design: free body geometry (defaults to :class:`BodyDesign`).

    Returns:
        The parameter set, with Table 3.1 motors and the default limits.
    """
    ml = (gravity_moment[0], gravity_moment[1], 0.0, 0.0)
    joints = tuple(
        JointParams(
            _NAMES[i], inertia[i], ml[i], _friction(coulomb[i], viscous[i]), _MOTORS[i], _LIMITS[i]
        )
        for i in range(4)
    )
    return EndoBotParams(name, joints, design or BodyDesign())  # type: ignore[arg-type]


E1 = endobot_params(
    "E1",
    inertia=(0.0487, 0.0441, 0.0006, 0.2451),
    gravity_moment=(0.1273, 0.1122),
    coulomb=(0.127, 0.120, 0.029, 0.069),
    viscous=(0.044, 0.067, 0.847, 0.742),
)
"""EndoBot 1 (Tables 3.3-3.4, rows E11-E14)."""

E2 = endobot_params(
    "E2",
    inertia=(0.0528, 0.0427, 0.0005, 0.2605),
    gravity_moment=(0.1305, 0.1155),
    coulomb=(0.149, 0.125, 0.019, 0.045),
    viscous=(0.029, 0.054, 0.795, 0.484),
)
"""EndoBot 2 (Tables 3.3-3.4, rows E21-E24)."""
