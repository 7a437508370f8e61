"""One simulated EndoBot on a PyBullet client: torque control at 1 kHz.

The robot is loaded from the URDF generated from its parameter set, with the
default velocity motors disabled and PyBullet's own damping set to zero, so
its rigid-body dynamics are exactly :mod:`suture_engine.robot.dynamics`.

Joint friction (models a-d, (3.42)-(3.45)) is applied as a joint torque,
since PyBullet joints have no Coulomb friction. To avoid chatter around zero
velocity it is solved per step, time-stepping style: with the velocity each
joint would reach without friction, q̇_free = q̇ + h M⁻¹(τ - C q̇ - G), a joint
that friction can hold (|q̇_free,i| ≤ h (M⁻¹)_ii F_break) is held at rest by
exactly the torque needed; otherwise it slides with Coulomb (and Stribeck)
friction opposing it and viscous friction evaluated implicitly at the end of
the step (stable for any Fv; the roll joint has h Fv / I ≈ 1.4). Joints are
coupled through M⁻¹, so the per-joint solves are repeated (projected
Gauss-Seidel). F_break is Fs at rest for the static models c and d, else Fc.
Forces the model does not know (contacts, pushes on the tool, joint-limit
constraints) enter the prediction as a one-step-delayed estimate,
M (q̇ - q̇_predicted) / h from the previous step, so that a joint held by static
friction stays held under a steady external load instead of creeping.

The base is mounted on a fixed joint that carries PyBullet's joint
force/torque sensor: the base wrench sensor of chapter 7. Measured outputs are
the encoder positions and that wrench, through :mod:`backends.pybullet.sensors`
models. Joint velocity is not measured (ground truth stays available through
:meth:`EndoBotSim.true_state` for evaluation and traces only).

In a scene with several robots on one client: call :meth:`EndoBotSim.apply`
on each, ``p.stepSimulation`` once, then :meth:`EndoBotSim.measure` on each.
:meth:`EndoBotSim.step` does the three for a robot alone on its client.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from backends.pybullet.sensors import Sensor, SensorModel, SensorReading
from backends.pybullet.urdf import FT_JOINT, JOINT_NAMES, TOOL_LINK, endobot_urdf
from suture_engine.errors import SutureError
from suture_engine.robot.friction import FrictionModel, friction_levels
from suture_engine.robot.params import E1, EndoBotParams

__all__ = [
    "CONTROL_PERIOD",
    "EndoBotMeasurement",
    "EndoBotSim",
    "JointState",
    "SimulationError",
]

CONTROL_PERIOD = 1e-3
"""Torque-control period [s] (1 kHz)."""

FloatArray = NDArray[np.float64]
Vec = Sequence[float] | FloatArray

_REST_VELOCITY = 1e-7
"""|q̇| below which a joint counts as at rest for static friction [rad/s or m/s]."""
_PGS_ITERATIONS = 4


def _floats(v: Vec) -> list[float]:
    """Joint values as Python floats (math on them is several times faster than on numpy
    scalars)."""
    if type(v) is np.ndarray and v.dtype == np.float64:
        out: list[float] = v.tolist()
        return out
    return [float(x) for x in v]


def _joint_solve(v_free: float, w: float, brk: float, slide: float, fv: float) -> float:
    """Friction torque of one joint in one Gauss-Seidel sweep [N*m or N].

    Args:
        v_free: the joint's velocity at the end of the step without its own friction
            [rad/s or m/s].
        w: h (M⁻¹)_ii, the velocity change per unit torque over the step [(rad/s)/(N*m)].
        brk: break-away level: friction can hold the joint up to it [N*m or N].
        slide: sliding (Coulomb and Stribeck) level [N*m or N].
        fv: viscous coefficient, taken at the end of the step [N*m*s/rad or N*s/m].
    """
    if abs(v_free) <= w * brk:
        return v_free / w  # held: exactly the torque that stops the joint
    s = 1.0 if v_free > 0.0 else -1.0
    v = (v_free - w * slide * s) / (1.0 + w * fv)
    return slide * s + fv * v


class SimulationError(SutureError):
    """A simulated robot used wrongly (bad command shape, non-finite torque).

    Attributes:
        robot: the robot's name.
        detail: what was wrong.
    """

    code = "simulation-error"

    def __init__(self, robot: str, detail: str) -> None:
        super().__init__(f"robot {robot}: {detail}")
        self.robot = robot
        self.detail = detail


class JointState(NamedTuple):
    """Ground-truth joint state (evaluation and traces only).

    Attributes:
        q: positions [rad, rad, rad, m].
        qd: velocities [rad/s, rad/s, rad/s, m/s].
    """

    q: FloatArray
    qd: FloatArray


class EndoBotMeasurement(NamedTuple):
    """What the real robot could measure at one tick.

    Attributes:
        joints: encoder positions [rad, rad, rad, m].
        base_wrench: base F/T sensor (Fx, Fy, Fz [N], Mx, My, Mz [N*m]): the wrench
            the mount exerts on the robot, in the base frame at the RCM.
    """

    joints: SensorReading
    base_wrench: SensorReading


class EndoBotSim:
    """One EndoBot in a PyBullet world, torque controlled.

    Args:
        client: the PyBullet physics client id (from ``p.connect(p.DIRECT)``).
        params: the robot's (true) parameters; None: E1.
        base_position: position of the RCM in the world [m].
        base_orientation: base quaternion (x, y, z, w) in the world; the default
            turns the base z axis downwards, into the patient.
        q0: initial joints [rad, rad, rad, m]; default (0, 0, 0, 0.05).
        friction_model: which friction model the simulated joints follow.
        friction: False to simulate a frictionless robot.
        encoder: encoder imperfections (None: ideal).
        ft_sensor: base F/T sensor imperfections (None: ideal).
        seed: seed of the sensors' random generator.
        include_tool: add the tool-tip link.
        saturate: clip commanded torques to the motors' limits (Table 3.1, ±10 V).
    """

    def __init__(
        self,
        client: int,
        params: EndoBotParams | None = None,
        base_position: Vec = (0.0, 0.0, 0.3),
        base_orientation: Vec = (1.0, 0.0, 0.0, 0.0),
        q0: Vec | None = None,
        friction_model: FrictionModel | str = FrictionModel.COULOMB_VISCOUS,
        friction: bool = True,
        encoder: SensorModel | None = None,
        ft_sensor: SensorModel | None = None,
        seed: int = 0,
        include_tool: bool = True,
        saturate: bool = True,
    ) -> None:
        import pybullet as p

        self._p: Any = p
        self.client = client
        self.params = params or E1
        self.friction_model = FrictionModel(friction_model)
        self.friction_enabled = friction
        self.saturate = saturate
        self.dt = CONTROL_PERIOD
        p.setTimeStep(self.dt, physicsClientId=client)
        fd, path = tempfile.mkstemp(suffix=".urdf", prefix=f"endobot_{self.params.name}_")
        try:
            with os.fdopen(fd, "w") as fh:
                fh.write(endobot_urdf(self.params, include_tool=include_tool))
            self.body_id: int = p.loadURDF(
                path,
                basePosition=list(base_position),
                baseOrientation=list(base_orientation),
                useFixedBase=True,
                flags=p.URDF_USE_INERTIA_FROM_FILE,
                physicsClientId=client,
            )
        finally:
            os.unlink(path)
        names = {
            p.getJointInfo(self.body_id, j, physicsClientId=client)[1].decode(): j
            for j in range(p.getNumJoints(self.body_id, physicsClientId=client))
        }
        self.joint_indices: list[int] = [names[n] for n in JOINT_NAMES]
        self.ft_joint: int = names[FT_JOINT]
        self.tool_link: int = names["tool_tip"] if include_tool else self.joint_indices[-1]
        self.tool_link_name = TOOL_LINK if include_tool else "insertion_link"
        for link in range(-1, p.getNumJoints(self.body_id, physicsClientId=client)):
            p.changeDynamics(
                self.body_id,
                link,
                linearDamping=0.0,
                angularDamping=0.0,
                jointDamping=0.0,
                physicsClientId=client,
            )
        p.setJointMotorControlArray(
            self.body_id,
            self.joint_indices,
            p.VELOCITY_CONTROL,
            forces=[0.0] * 4,
            physicsClientId=client,
        )
        p.enableJointForceTorqueSensor(self.body_id, self.ft_joint, True, physicsClientId=client)
        com = p.getDynamicsInfo(self.body_id, self.ft_joint, physicsClientId=client)[3]
        self._com: tuple[float, float, float] = (float(com[0]), float(com[1]), float(com[2]))
        self._measured_joints = [*self.joint_indices, self.ft_joint]
        rng = np.random.default_rng(seed)
        self._encoder = Sensor(encoder or SensorModel(), 4, rng)
        self._ft = Sensor(ft_sensor or SensorModel(), 6, rng)
        self._coupled: tuple[Sensor, Sensor] | None = None
        self._limits = [float(j.motor.max_torque) for j in self.params.joints]
        fr = [j.friction for j in self.params.joints]
        self._fc = [f.coulomb for f in fr]
        self._fv = [0.0 if self.friction_model is FrictionModel.COULOMB else f.viscous for f in fr]
        self._fs = [f.static for f in fr]
        self._vs = [f.stribeck_velocity for f in fr]
        self._ds = [f.stribeck_exponent for f in fr]
        self._base_rot = np.array(
            p.getMatrixFromQuaternion(list(base_orientation), physicsClientId=client)
        ).reshape(3, 3)
        self.refresh_gravity()
        self._last_command = [0.0, 0.0, 0.0, 0.0]
        self._last_friction = [0.0, 0.0, 0.0, 0.0]
        self.reset(q0 if q0 is not None else (0.0, 0.0, 0.0, 0.05))

    def __repr__(self) -> str:
        return (
            f"EndoBotSim(robot={self.params.name!r}, body={self.body_id}, "
            f"friction={self.friction_model.value if self.friction_enabled else 'off'})"
        )

    def refresh_gravity(self) -> None:
        """Re-read the world gravity; call after ``p.setGravity`` changes it."""
        info = self._p.getPhysicsEngineParameters(physicsClientId=self.client)
        g_world = np.array(
            (
                info["gravityAccelerationX"],
                info["gravityAccelerationY"],
                info["gravityAccelerationZ"],
            )
        )
        g_base = self._base_rot.T @ g_world
        self.model_params = dataclasses.replace(
            self.params, gravity=(float(g_base[0]), float(g_base[1]), float(g_base[2]))
        )
        th = self._theta = self.model_params.coefficients
        self._gravity = self.model_params.gravity
        # constants of the per-step friction solve, evaluated as the dynamics functions do
        self._two_h4 = 2.0 * th.h4
        self._ml12 = th.ml1 - th.ml2
        self._w33 = self.dt * (1.0 / th.m4)

    def reset(self, q: Vec, qd: Vec | None = None) -> None:
        """Teleport the joints (no dynamics); zero velocity unless given.

        Args:
            q: joints [rad, rad, rad, m].
            qd: velocities [rad/s, rad/s, rad/s, m/s].
        """
        vel = [0.0] * 4 if qd is None else [float(v) for v in qd]
        self._predicted: tuple[float, float, float, float] | None = None  # a teleport voids it
        self._last_state: tuple[list[float], list[float]] = ([], [])
        self._last_mass: tuple[float, float, float, float, float] = (0.0,) * 5
        self._ext = [0.0, 0.0, 0.0, 0.0]
        for k, j in enumerate(self.joint_indices):
            self._p.resetJointState(
                self.body_id, j, float(q[k]), vel[k], physicsClientId=self.client
            )

    @property
    def external_torque(self) -> FloatArray:
        """Estimated unmodelled joint torques of the last step [N*m, ..., N] (contacts,
        pushes, limits), used by the friction solve."""
        return np.array(self._ext)

    @property
    def last_command(self) -> FloatArray:
        """The last commanded motor torques, after saturation [N*m, N*m, N*m, N]."""
        return np.array(self._last_command)

    @property
    def last_friction(self) -> FloatArray:
        """The friction torques of the last applied step [N*m, N*m, N*m, N]."""
        return np.array(self._last_friction)

    def _joint_lists(self) -> tuple[list[float], list[float]]:
        """Ground-truth (q, q̇) as Python floats, one PyBullet call."""
        states = self._p.getJointStates(
            self.body_id, self.joint_indices, physicsClientId=self.client
        )
        return [s[0] for s in states], [s[1] for s in states]

    def true_state(self) -> JointState:
        """Ground-truth joint positions and velocities (for evaluation, not for skills)."""
        q, qd = self._joint_lists()
        return JointState(np.array(q), np.array(qd))

    def _wrench_at_rcm(self, raw: Sequence[float]) -> list[float]:
        """PyBullet's joint reaction (Fx, Fy, Fz, Mx, My, Mz) with the moment moved from
        the child link's centre of mass to the RCM: M + c × F [N, N*m]."""
        fx, fy, fz, mx, my, mz = raw
        cx, cy, cz = self._com
        # c × F in the operation order of np.cross: products, then their difference
        return [
            fx,
            fy,
            fz,
            mx + (cy * fz - cz * fy),
            my + (cz * fx - cx * fz),
            mz + (cx * fy - cy * fx),
        ]

    def true_base_wrench(self) -> FloatArray:
        """Ground-truth base wrench (Fx, Fy, Fz [N], Mx, My, Mz [N*m]) in the base frame."""
        raw = self._p.getJointState(self.body_id, self.ft_joint, physicsClientId=self.client)[2]
        return np.array(self._wrench_at_rcm(raw))

    def true_tool_pose(self) -> tuple[FloatArray, FloatArray]:
        """World position [m] and quaternion (x, y, z, w) of the tool frame (ground truth)."""
        st = self._p.getLinkState(
            self.body_id, self.tool_link, computeForwardKinematics=True, physicsClientId=self.client
        )
        return np.array(st[4]), np.array(st[5])

    def scale_friction(self, factor: float) -> None:
        """Scale every joint's friction (Coulomb, static and viscous) by ``factor`` [-]
        (a perturbation: the controllers' friction model stays the nominal one).

        Raises:
            SimulationError: a negative or non-finite factor.
        """
        if not (math.isfinite(factor) and factor >= 0.0):
            raise SimulationError(self.params.name, f"friction scale {factor!r} must be >= 0")
        self._fc = [f * factor for f in self._fc]
        self._fs = [f * factor for f in self._fs]
        self._fv = [f * factor for f in self._fv]

    def friction_torques(self, q: Vec, qd: Vec, tau: Vec) -> FloatArray:
        """Friction torques [N*m, ..., N] this step, solved as described in the module doc.

        Args:
            q: joints [rad, rad, rad, m].
            qd: velocities [rad/s, rad/s, rad/s, m/s].
            tau: the other joint torques applied this step [N*m, ..., N].

        Returns:
            τ_f, opposing motion (subtracted from the applied torque).

        Note:
            Stateful: it also updates the estimate of unmodelled torques from the
            previous step, so call it once per simulation step (``apply`` does).
        """
        return np.array(self._friction(_floats(q), _floats(qd), _floats(tau)))

    def _friction(self, q: list[float], qd: list[float], tau: list[float]) -> list[float]:
        """:meth:`friction_torques` on Python floats (the 1 kHz path).

        M(q) (3.38), its closed-form inverse, C(q, q̇) q̇ (3.40) and G(q) (3.41) are
        evaluated inline with the operations of :mod:`suture_engine.robot.dynamics`
        in the same order, so the values are those of the dynamics functions to the
        bit. Only joints 1 and 3 couple through M⁻¹, so the sums skip the structural
        zeros (adding a ±0 product never changes a sum that starts at +0) and the
        projected Gauss-Seidel sweeps iterate on joints 1 and 3 alone (joints 2 and 4
        are solved exactly by their first sweep).
        """
        i1, i2, i3, m4, _ml1, ml2, h4, delta = self._theta
        gx, gy, gz = self._gravity
        dt = self.dt
        q1, q2, _, q4 = q
        v1, v2, v3, v4 = qd
        c1, s1 = math.cos(q1), math.sin(q1)
        c2, s2 = math.cos(q2), math.sin(q2)
        a = (self._two_h4 + m4 * q4) * q4
        # C(q, q̇) q̇ from the partials of M (dynamics.coriolis_vector)
        da = 2.0 * (h4 + m4 * q4)
        p12 = -2.0 * (delta + a) * s2 * c2
        p14 = da * c2 * c2
        p32 = i3 * c2
        p24 = da
        # G(q) (dynamics.gravity_vector); G3 = 0
        w1 = c1 * gy + s1 * gz
        w2 = gx * c2 + gy * s1 * s2 - gz * c1 * s2
        w4 = gx * s2 - gy * s1 * c2 + gz * c1 * c2
        k = ml2 + m4 * q4
        r0 = tau[0] - (p12 * v1 * v2 + p14 * v1 * v4 + p32 * v2 * v3) - (self._ml12 + k * c2) * w1
        r1 = tau[1] - (-0.5 * p12 * v1 * v1 - p32 * v1 * v3 + p24 * v2 * v4) - -k * w2
        r2 = tau[2] - p32 * v1 * v2 - 0.0
        r3 = tau[3] - -0.5 * (p14 * v1 * v1 + p24 * v2 * v2) - -m4 * w4
        # M(q) and h M(q)⁻¹ (dynamics.mass_matrix, mass_matrix_inverse)
        m11 = i1 - delta * s2 * s2 + a * c2 * c2
        m13 = i3 * s2
        m22 = i2 + a
        det = m11 * i3 - m13 * m13
        w00 = dt * (i3 / det)
        w02 = dt * (-m13 / det)
        w11 = dt * (1.0 / m22)
        w22 = dt * (m11 / det)
        w33 = self._w33
        ext = self._ext
        predicted = self._predicted
        if predicted is not None and (q, qd) != self._last_state:
            # the last step's unmodelled generalised force: the estimate it already
            # contained plus M (q̇ - q̇_pred) / h (an unchanged state means no step ran)
            n11, n13, n22, n33, n44 = self._last_mass
            d1 = v1 - predicted[0]
            d2 = v2 - predicted[1]
            d3 = v3 - predicted[2]
            d4 = v4 - predicted[3]
            ext = self._ext = [
                ext[0] + (0.0 + n11 * d1 + n13 * d3) / dt,
                ext[1] + (0.0 + n22 * d2) / dt,
                ext[2] + (0.0 + n13 * d1 + n33 * d3) / dt,
                ext[3] + (0.0 + n44 * d4) / dt,
            ]
        self._last_state = (q, qd)
        self._last_mass = (m11, m13, m22, i3, m4)
        r0 += ext[0]
        r1 += ext[1]
        r2 += ext[2]
        r3 += ext[3]
        f0 = v1 + (0.0 + w00 * r0 + w02 * r2)
        f1 = v2 + (0.0 + w11 * r1)
        f2 = v3 + (0.0 + w02 * r0 + w22 * r2)
        f3 = v4 + (0.0 + w33 * r3)
        slide: Sequence[float]
        brk: Sequence[float]
        model = self.friction_model
        if model is FrictionModel.COULOMB_VISCOUS or model is FrictionModel.COULOMB:
            slide = brk = self._fc  # both levels are Fc (friction_levels, models a and b)
        else:
            slide, brk = friction_levels(
                qd, self._fc, self._fs, self._vs, self._ds, model, _REST_VELOCITY
            )
        fv = self._fv
        t1 = _joint_solve(f1, w11, brk[1], slide[1], fv[1])
        t3 = _joint_solve(f3, w33, brk[3], slide[3], fv[3])
        # joints 1 and 3: the sweeps of _joint_solve, inline (the hot loop)
        b0, s0, fv0, b2, s2_, fv2 = brk[0], slide[0], fv[0], brk[2], slide[2], fv[2]
        h0, h2 = w00 * b0, w22 * b2
        k0, k2 = 1.0 + w00 * fv0, 1.0 + w22 * fv2
        t0 = t2 = 0.0
        for _ in range(_PGS_ITERATIONS):
            v = f0 - (0.0 + w02 * t2)
            if abs(v) <= h0:
                t0 = v / w00
            else:
                s = 1.0 if v > 0.0 else -1.0
                t0 = s0 * s + fv0 * ((v - w00 * s0 * s) / k0)
            v = f2 - (0.0 + w02 * t0)
            if abs(v) <= h2:
                t2 = v / w22
            else:
                s = 1.0 if v > 0.0 else -1.0
                t2 = s2_ * s + fv2 * ((v - w22 * s2_ * s) / k2)
        self._predicted = (
            f0 - (0.0 + w00 * t0 + w02 * t2),
            f1 - (0.0 + w11 * t1),
            f2 - (0.0 + w02 * t0 + w22 * t2),
            f3 - (0.0 + w33 * t3),
        )
        return [t0, t1, t2, t3]

    def apply(self, tau: Vec) -> None:
        """Command joint torques for the next step only (friction added here).

        PyBullet clears joint torques after each ``stepSimulation``: call this every tick.

        Args:
            tau: motor torques [N*m, N*m, N*m, N]; clipped to the motor limits when
                ``saturate``.

        Raises:
            SimulationError: on a wrong shape or a non-finite torque.
        """
        if type(tau) is np.ndarray and tau.shape == (4,) and tau.dtype == np.float64:
            cmd: list[float] = tau.tolist()
        else:
            arr = np.asarray(tau, dtype=float)
            if arr.shape != (4,):
                raise SimulationError(self.params.name, f"bad torque command {tau!r}")
            cmd = arr.tolist()
        c0, c1, c2, c3 = cmd
        # a sum of floats is finite only if every term is (an overflow is re-checked)
        if not math.isfinite(c0 + c1 + c2 + c3) and not all(math.isfinite(x) for x in cmd):
            raise SimulationError(self.params.name, f"bad torque command {tau!r}")
        if self.saturate:  # np.clip on floats
            l0, l1, l2, l3 = self._limits
            c0 = -l0 if c0 < -l0 else (l0 if c0 > l0 else c0)
            c1 = -l1 if c1 < -l1 else (l1 if c1 > l1 else c1)
            c2 = -l2 if c2 < -l2 else (l2 if c2 > l2 else c2)
            c3 = -l3 if c3 < -l3 else (l3 if c3 > l3 else c3)
            cmd = [c0, c1, c2, c3]
        self._last_command = cmd
        total = cmd
        if self.friction_enabled:
            q, qd = self._joint_lists()
            tf = self._last_friction = self._friction(q, qd, cmd)
            total = [c0 - tf[0], c1 - tf[1], c2 - tf[2], c3 - tf[3]]
        self._p.setJointMotorControlArray(
            self.body_id,
            self.joint_indices,
            self._p.TORQUE_CONTROL,
            forces=total,
            physicsClientId=self.client,
        )

    def measure(self) -> EndoBotMeasurement:
        """Sample the encoders and the base F/T sensor once (one control tick).

        One PyBullet call reads the four joints and the F/T joint. An ideal sensor skips
        its random draws unless an imperfect sensor shares its generator (then the
        draws keep that sensor's noise on the seeded stream).
        """
        states = self._p.getJointStates(
            self.body_id, self._measured_joints, physicsClientId=self.client
        )
        encoder, ft = self._encoder, self._ft
        coupled = self._coupled
        if coupled is None or coupled[0] is not encoder or coupled[1] is not ft:
            self._couple_sensors(encoder, ft)
        return EndoBotMeasurement(
            encoder.measure([s[0] for s in states[:4]]),
            ft.measure(self._wrench_at_rcm(states[4][2])),
        )

    def _couple_sensors(self, encoder: Sensor, ft: Sensor) -> None:
        """Let an ideal sensor skip its random draws when no imperfect sensor reads the
        same generator after it (the draws then change nothing a run can see)."""
        shared = encoder.rng is ft.rng
        encoder.draw_when_ideal = shared and not ft.model.ideal
        ft.draw_when_ideal = shared and not encoder.model.ideal
        self._coupled = (encoder, ft)

    def step(self, tau: Vec) -> EndoBotMeasurement:
        """Apply torques, advance the client by one 1 ms step, measure.

        Only for a robot alone on its client (it calls ``p.stepSimulation``).

        Args:
            tau: motor torques [N*m, N*m, N*m, N].

        Returns:
            The measurement after the step.
        """
        self.apply(tau)
        self._p.stepSimulation(physicsClientId=self.client)
        return self.measure()
