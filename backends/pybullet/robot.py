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
from suture_engine.robot import dynamics
from suture_engine.robot.friction import FrictionModel
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
        self._base_com = np.array(
            p.getDynamicsInfo(self.body_id, self.ft_joint, physicsClientId=client)[3]
        )
        rng = np.random.default_rng(seed)
        self._encoder = Sensor(encoder or SensorModel(), 4, rng)
        self._ft = Sensor(ft_sensor or SensorModel(), 6, rng)
        self._limits = np.array([j.motor.max_torque for j in self.params.joints])
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
        self.last_command = np.zeros(4)
        self.last_friction = np.zeros(4)
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
        self._theta = self.model_params.coefficients

    def reset(self, q: Vec, qd: Vec | None = None) -> None:
        """Teleport the joints (no dynamics); zero velocity unless given.

        Args:
            q: joints [rad, rad, rad, m].
            qd: velocities [rad/s, rad/s, rad/s, m/s].
        """
        vel = [0.0] * 4 if qd is None else [float(v) for v in qd]
        self._predicted: list[float] | None = None  # a teleport voids the prediction
        self._last_state: tuple[list[float], list[float]] = ([], [])
        self._last_mass: list[list[float]] = []
        self.external_torque = np.zeros(4)
        """Estimated unmodelled joint torques of the last step [N*m, ..., N] (contacts,
        pushes, limits), used by the friction solve."""
        for k, j in enumerate(self.joint_indices):
            self._p.resetJointState(
                self.body_id, j, float(q[k]), vel[k], physicsClientId=self.client
            )

    def true_state(self) -> JointState:
        """Ground-truth joint positions and velocities (for evaluation, not for skills)."""
        states = self._p.getJointStates(
            self.body_id, self.joint_indices, physicsClientId=self.client
        )
        return JointState(np.array([s[0] for s in states]), np.array([s[1] for s in states]))

    def true_base_wrench(self) -> FloatArray:
        """Ground-truth base wrench (Fx, Fy, Fz [N], Mx, My, Mz [N*m]) in the base frame."""
        raw = np.array(
            self._p.getJointState(self.body_id, self.ft_joint, physicsClientId=self.client)[2]
        )
        # PyBullet reports the moment about the child link's centre of mass; move it to the RCM.
        raw[3:] += np.cross(self._base_com, raw[:3])
        return raw

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
        th = self._theta
        rest = (
            np.asarray(tau, dtype=float)
            - dynamics.coriolis_vector(q, qd, th)
            - dynamics.gravity_vector(q, th, self.model_params.gravity)
        ).tolist()
        dt = self.dt
        wl = [[dt * x for x in row] for row in dynamics.mass_matrix_inverse(q, th)]
        qdl = [float(v) for v in qd]
        ql = [float(v) for v in q]
        if self._predicted is not None and (ql, qdl) != self._last_state:
            # the last step's unmodelled generalised force: the estimate it already
            # contained plus M (q̇ - q̇_pred) / h (an unchanged state means no step ran)
            dv = [a - b for a, b in zip(qdl, self._predicted, strict=True)]
            m_prev = self._last_mass
            self.external_torque = self.external_torque + np.array(
                [sum(m_prev[i][j] * dv[j] for j in range(4)) / dt for i in range(4)]
            )
        self._last_state = (ql, qdl)
        self._last_mass = dynamics.mass_matrix(q, th).tolist()
        ext = self.external_torque.tolist()
        rest = [r + e for r, e in zip(rest, ext, strict=True)]
        vf = [qdl[i] + sum(wl[i][j] * rest[j] for j in range(4)) for i in range(4)]
        static = self.friction_model in (FrictionModel.STATIC, FrictionModel.STRIBECK)
        stribeck = self.friction_model is FrictionModel.STRIBECK
        slide: list[float] = []  # sliding friction level per joint (Coulomb + Stribeck)
        brk: list[float] = []  # largest torque static friction can hold
        for i in range(4):
            at_rest = abs(qdl[i]) <= _REST_VELOCITY
            fc = self._fc[i]
            if stribeck and not at_rest:
                fc += (self._fs[i] - fc) * math.exp(-(abs(qdl[i] / self._vs[i]) ** self._ds[i]))
            slide.append(fc)
            brk.append(self._fs[i] if (static and at_rest) else fc)
        tf = [0.0, 0.0, 0.0, 0.0]
        for _ in range(_PGS_ITERATIONS):
            for i in range(4):
                wi = wl[i]
                v_other = vf[i] - sum(wi[j] * tf[j] for j in range(4) if j != i)
                wii = wi[i]
                if abs(v_other) <= wii * brk[i]:
                    tf[i] = v_other / wii  # held: exactly the torque that stops the joint
                else:
                    s = 1.0 if v_other > 0.0 else -1.0
                    v = (v_other - wii * slide[i] * s) / (1.0 + wii * self._fv[i])
                    tf[i] = slide[i] * s + self._fv[i] * v
        self._predicted = [vf[i] - sum(wl[i][j] * tf[j] for j in range(4)) for i in range(4)]
        return np.array(tf)

    def apply(self, tau: Vec) -> None:
        """Command joint torques for the next step only (friction added here).

        PyBullet clears joint torques after each ``stepSimulation``: call this every tick.

        Args:
            tau: motor torques [N*m, N*m, N*m, N]; clipped to the motor limits when
                ``saturate``.

        Raises:
            SimulationError: on a wrong shape or a non-finite torque.
        """
        cmd = np.asarray(tau, dtype=float)
        if cmd.shape != (4,) or not np.all(np.isfinite(cmd)):
            raise SimulationError(self.params.name, f"bad torque command {tau!r}")
        if self.saturate:
            cmd = np.clip(cmd, -self._limits, self._limits)
        self.last_command = cmd
        total = cmd
        if self.friction_enabled:
            q, qd = self.true_state()
            self.last_friction = self.friction_torques(q, qd, cmd)
            total = cmd - self.last_friction
        self._p.setJointMotorControlArray(
            self.body_id,
            self.joint_indices,
            self._p.TORQUE_CONTROL,
            forces=total.tolist(),
            physicsClientId=self.client,
        )

    def measure(self) -> EndoBotMeasurement:
        """Sample the encoders and the base F/T sensor once (one control tick)."""
        q, _ = self.true_state()
        return EndoBotMeasurement(
            self._encoder.measure(q), self._ft.measure(self.true_base_wrench())
        )

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
