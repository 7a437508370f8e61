"""URDF of an EndoBot generated from its parameter set.

The kinematic tree reproduces :mod:`suture_engine.robot.kinematics` and the
inertial tags reproduce the rigid bodies of
:attr:`suture_engine.robot.params.EndoBotParams.bodies`, so that PyBullet's
dynamics equal :mod:`suture_engine.robot.dynamics` (load it with
``URDF_USE_INERTIA_FROM_FILE``, or PyBullet recomputes inertias from shapes):

    mount --(fixed, base F/T sensor)--> base_link (the static frame, at the RCM)
      --yaw (revolute, x)--> yaw_link --pitch (revolute, y)--> pitch_link
      --roll (revolute, z)--> roll_link --insertion (prismatic, z)--> insertion_link
      [--tool_tip (fixed)--> tool_link]

All joint origins are at the RCM; the insertion link frame is at the tool tip
(q4 along the tool axis). With a tool link, the insertion body is split into
a shaft and a tool tip whose combined mass, centre of mass and inertia equal
the model's insertion body exactly.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

from suture_engine.robot.params import EndoBotParams, RigidBody

__all__ = [
    "BASE_LINK",
    "FT_JOINT",
    "JOINT_NAMES",
    "TOOL_LINK",
    "endobot_urdf",
    "write_endobot_urdf",
]

JOINT_NAMES = ("yaw", "pitch", "roll", "insertion")
"""Names of the four actuated joints, in order."""
FT_JOINT = "base_ft"
"""Fixed joint that carries the base force/torque sensor (chapter 7)."""
BASE_LINK = "base_link"
TOOL_LINK = "tool_link"

BASE_MASS = 0.5
"""Mass of the static frame between the sensor and the yaw joint [kg] (a choice)."""


class _Inertial(NamedTuple):
    mass: float
    com_z: float
    ixx: float
    iyy: float
    izz: float


def _inertial(b: _Inertial) -> str:
    return (
        f'    <inertial>\n      <origin xyz="0 0 {b.com_z!r}" rpy="0 0 0"/>\n'
        f'      <mass value="{b.mass!r}"/>\n'
        f'      <inertia ixx="{b.ixx!r}" ixy="0" ixz="0"'
        f' iyy="{b.iyy!r}" iyz="0" izz="{b.izz!r}"/>\n'
        "    </inertial>\n"
    )


def _from_body(b: RigidBody) -> _Inertial:
    return _Inertial(b.mass, b.com_z, *b.inertia)


def _split_tool(body: RigidBody, fraction: float) -> tuple[_Inertial, _Inertial]:
    """Split the insertion body into shaft + tool tip with the same mass properties."""
    m = body.mass
    mt = fraction * m
    ms = m - mt
    ixx, _, izz = body.inertia
    l4 = body.com_z
    zs = m * l4 / ms  # shaft COM so that the combined COM stays at l4 (tip COM at 0)
    it = 1e-7  # tiny inertia of the tip about its own COM [kg*m^2]
    is_xy = ixx - it - ms * (zs - l4) ** 2 - mt * l4 * l4
    is_z = izz - it
    if is_xy <= 0.0 or is_z <= 0.0:
        raise ValueError(f"tool fraction {fraction} too large for the insertion body")
    return _Inertial(ms, zs, is_xy, is_xy, is_z), _Inertial(mt, 0.0, it, it, it)


def _cyl(
    radius: float, length: float, z: float, rgba: str, collision: bool, bare: float = 0.0
) -> str:
    """A cylinder along z centred at ``z``; its collision shape leaves out the ``bare`` [m]
    at its +z end."""
    geo = f'<geometry><cylinder radius="{radius}" length="{length}"/></geometry>'
    org = f'<origin xyz="0 0 {z}" rpy="0 0 0"/>'
    out = f'    <visual>{org}{geo}<material name="m{rgba.replace(" ", "_")}">'
    out += f'<color rgba="{rgba}"/></material></visual>\n'
    if collision:
        cgeo = f'<geometry><cylinder radius="{radius}" length="{length - bare}"/></geometry>'
        corg = f'<origin xyz="0 0 {z - bare / 2}" rpy="0 0 0"/>'
        out += f"    <collision>{corg}{cgeo}</collision>\n"
    return out


def _link(name: str, inertial: _Inertial | None, geometry: str = "") -> str:
    body = _inertial(inertial) if inertial is not None else ""
    return f'  <link name="{name}">\n{body}{geometry}  </link>\n'


def _joint(
    name: str,
    kind: str,
    parent: str,
    child: str,
    axis: str = "0 0 1",
    limits: tuple[float, float, float, float] | None = None,
) -> str:
    out = f'  <joint name="{name}" type="{kind}">\n'
    out += f'    <parent link="{parent}"/>\n    <child link="{child}"/>\n'
    out += '    <origin xyz="0 0 0" rpy="0 0 0"/>\n'
    if kind != "fixed":
        out += f'    <axis xyz="{axis}"/>\n'
        out += '    <dynamics damping="0" friction="0"/>\n'
    if limits is not None:
        lo, hi, effort, vel = limits
        out += (
            f'    <limit lower="{lo!r}" upper="{hi!r}" effort="{effort!r}" velocity="{vel!r}"/>\n'
        )
    return out + "  </joint>\n"


def endobot_urdf(
    params: EndoBotParams,
    include_tool: bool = True,
    tool_fraction: float = 0.1,
    shaft_length: float = 0.35,
    shaft_radius: float = 0.0025,
    jaw_length: float = 0.006,
) -> str:
    """The URDF text of one EndoBot.

    Args:
        params: robot parameters (bodies and joint limits).
        include_tool: add a fixed ``tool_link`` at the tool tip.
        tool_fraction: share of the insertion mass placed at the tip when
            ``include_tool`` [-]; the totals are unchanged.
        shaft_length: length of the shaft's visual/collision cylinder behind the tip [m].
        shaft_radius: shaft radius [m] (5 mm laparoscopic tools: 0.0025).
        jaw_length: length of the jaws behind the tip that the shaft's collision shape
            leaves out [m]: the jaws are thinner than the shaft and hold by constraint.

    Returns:
        URDF XML text.
    """
    b1, b2, b3, b4 = params.bodies
    lim = [
        (j.limits.lower, j.limits.upper, j.motor.max_torque, j.limits.velocity)
        for j in params.joints
    ]
    name = f"endobot_{params.name.lower()}"
    out = f'<?xml version="1.0"?>\n<robot name="{name}">\n'
    out += _link("mount", _Inertial(1.0, 0.0, 1e-3, 1e-3, 1e-3))
    out += _joint(FT_JOINT, "fixed", "mount", BASE_LINK)
    arch = _cyl(0.01, 0.04, -0.25, "0.3 0.3 0.35 1", False)
    out += _link(BASE_LINK, _Inertial(BASE_MASS, -0.25, 1e-3, 1e-3, 1e-3), arch)
    out += _joint(JOINT_NAMES[0], "revolute", BASE_LINK, b1.name, "1 0 0", lim[0])
    out += _link(b1.name, _from_body(b1), _cyl(0.006, 0.02, -0.2, "0.6 0.6 0.65 1", False))
    out += _joint(JOINT_NAMES[1], "revolute", b1.name, b2.name, "0 1 0", lim[1])
    out += _link(b2.name, _from_body(b2), _cyl(0.008, 0.03, -0.15, "0.5 0.5 0.7 1", False))
    out += _joint(JOINT_NAMES[2], "revolute", b2.name, b3.name, "0 0 1", lim[2])
    out += _link(b3.name, _from_body(b3), _cyl(0.006, 0.04, -0.08, "0.7 0.7 0.7 1", False))
    out += _joint(JOINT_NAMES[3], "prismatic", b3.name, b4.name, "0 0 1", lim[3])
    shaft = _cyl(shaft_radius, shaft_length, -0.5 * shaft_length, "0.8 0.8 0.8 1", True, jaw_length)
    if include_tool:
        shaft_in, tip_in = _split_tool(b4, tool_fraction)
        out += _link(b4.name, shaft_in, shaft)
        out += _joint("tool_tip", "fixed", b4.name, TOOL_LINK)
        out += _link(TOOL_LINK, tip_in)
    else:
        out += _link(b4.name, _from_body(b4), shaft)
    return out + "</robot>\n"


def write_endobot_urdf(path: str | Path, params: EndoBotParams, **kwargs: float | bool) -> Path:
    """Write :func:`endobot_urdf` to ``path``.

    Args:
        path: output file.
        params: robot parameters.
        **kwargs: passed to :func:`endobot_urdf`.

    Returns:
        The path written.
    """
    p = Path(path)
    p.write_text(endobot_urdf(params, **kwargs))  # type: ignore[arg-type]
    return p
