"""The tissue pad: a wound, declared entry/exit points, and the channel the suture slides in.

The pad is two static boxes on either side of the wound (the wound runs perpendicular to
the entry-exit line, on the surface whose normal is declared). A stitch is a curved
channel under the surface from the entry point to the exit point,

    c(s) = entry + s (exit - entry) - depth sin(pi s) n,   s in [0, 1],

(the needle's path; ``depth`` [m] below the surface at mid-span). Once a thread is
:meth:`Tissue.thread`-ed, every capsule whose centre projects inside the channel and lies
within ``capture`` [m] of it

* stops colliding with the pad (it is inside the tissue),
* is pulled onto the channel by a lateral spring-damper (``k_lateral`` [N/m],
  ``c_lateral`` [N*s/m]), so the thread slides along the channel but cannot leave it
  sideways,
* feels the suture-tissue friction (4.5), f = -(F_s sgn(l_dot) + F_v l_dot), where
  ``l_dot`` [m/s] is the thread's sliding speed along the channel, shared equally by the
  capsules inside:

  - the static (Coulomb) part F_s is solved *implicitly*: each capsule inside is held by a
    point-to-point constraint to the world, re-anchored at the capsule's position every
    step, whose force is capped at F_s / n. It stops the capsule (stiction) unless the
    pull exceeds the cap and then resists with exactly the cap. An explicit
    ``F_s sgn(l_dot)`` force chatters at 1 kHz on mass-scaled capsules;
  - the viscous part F_v l_dot is an explicit force, its per-capsule coefficient
    capped at half of mass / time step for stability.

Call :meth:`Tissue.pre_step` before every physics step.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from suture_engine.errors import SutureError

if TYPE_CHECKING:
    from backends.pybullet.suture import Suture

__all__ = ["Tissue", "TissueError", "channel_friction"]

Vec3 = tuple[float, float, float]
FloatArray = NDArray[np.float64]


class TissueError(SutureError):
    """The tissue's geometry is invalid.

    Attributes:
        field: the offending field.
        value: its value.
        reason: why it is invalid.
    """

    code = "invalid-tissue"

    def __init__(self, field: str, value: object, reason: str) -> None:
        super().__init__(f"tissue {field}={value!r}: {reason}")
        self.field = field
        self.value = value
        self.reason = reason


def channel_friction(l_dot: float, f_static: float, f_viscous: float) -> float:
    """Suture-tissue friction force along the channel (4.5) [N].

    Args:
        l_dot: sliding speed of the thread along the channel [m/s].
        f_static: static (Coulomb) friction F_s [N].
        f_viscous: viscous coefficient F_v [N*s/m].

    Returns:
        The force opposing the sliding, -(F_s sgn(l_dot) + F_v l_dot).
    """
    return -(f_static * float(np.sign(l_dot)) + f_viscous * l_dot)


@dataclass
class Tissue:
    """A tissue pad with a wound and a stitch channel from ``entry`` to ``exit``.

    Attributes:
        client: PyBullet physics client id.
        entry: needle entry point on the surface, world frame [m].
        exit: needle exit point on the surface [m].
        normal: outward unit surface normal.
        depth: channel depth below the surface at mid-span [m].
        f_static: static suture-tissue friction F_s [N] (4.5).
        f_viscous: viscous suture-tissue friction F_v [N*s/m] (4.5).
        bodies: the pad's static bodies (one per side of the wound).
        channel: M×3 polyline of the channel [m].
    """

    client: int
    entry: Vec3
    exit: Vec3
    normal: Vec3
    depth: float
    f_static: float = 0.3
    f_viscous: float = 2.0
    k_lateral: float = 200.0
    c_lateral: float = 0.2
    capture: float = 3e-3
    bodies: list[int] = field(default_factory=list)
    channel: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    suture: Suture | None = None
    inside: list[int] = field(default_factory=list)
    _passing: set[int] = field(default_factory=set)
    _anchors: dict[int, int] = field(default_factory=dict)
    last_friction: float = 0.0
    last_sliding_speed: float = 0.0

    @classmethod
    def create(
        cls,
        client: int,
        center: Vec3,
        entry: Vec3,
        exit: Vec3,
        normal: Vec3 = (0.0, 0.0, 1.0),
        depth: float = 3e-3,
        size: tuple[float, float, float] = (0.04, 0.04, 0.01),
        wound_gap: float = 1e-3,
        **kwargs: float,
    ) -> Tissue:
        """Add a tissue pad to the world.

        Args:
            client: PyBullet physics client id.
            center: centre of the pad's top surface [m].
            entry: entry point [m] (on the surface).
            exit: exit point [m] (on the surface).
            normal: outward surface normal (normalised here).
            depth: channel depth at mid-span [m].
            size: pad length along entry->exit, width along the wound, thickness [m].
            wound_gap: width of the wound between the two halves [m].
            **kwargs: ``f_static`` [N], ``f_viscous`` [N*s/m],
                ``k_lateral`` [N/m], ``c_lateral`` [N*s/m], ``capture`` [m].

        Raises:
            TissueError: a zero normal, coincident entry/exit, or non-positive depth.
        """
        import pybullet as p

        n = np.asarray(normal, dtype=float)
        if np.linalg.norm(n) < 1e-12:
            raise TissueError("normal", normal, "must be non-zero")
        n = n / np.linalg.norm(n)
        a, b = np.asarray(entry, dtype=float), np.asarray(exit, dtype=float)
        across = (b - a) - n * float(n @ (b - a))
        if np.linalg.norm(across) < 1e-6:
            raise TissueError("exit", exit, "must differ from entry along the surface")
        if depth <= 0:
            raise TissueError("depth", depth, "must be > 0 [m]")
        self = cls(
            client=client,
            entry=entry,
            exit=exit,
            normal=(float(n[0]), float(n[1]), float(n[2])),
            depth=depth,
            **kwargs,  # type: ignore[arg-type]
        )
        s = np.linspace(0.0, 1.0, 25)
        self.channel = a + s[:, None] * (b - a) - depth * np.sin(np.pi * s)[:, None] * n
        ex = across / np.linalg.norm(across)
        ey = np.cross(n, ex)
        rot = np.column_stack([ex, ey, n])
        quat = _quat_from_matrix(rot)
        c = np.asarray(center, dtype=float)
        half = np.array([size[0] / 4 - wound_gap / 4, size[1] / 2, size[2] / 2])
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half.tolist(), physicsClientId=client)
        vis = p.createVisualShape(
            p.GEOM_BOX,
            halfExtents=half.tolist(),
            rgbaColor=[0.9, 0.55, 0.55, 1.0],
            physicsClientId=client,
        )
        for side in (-1, 1):
            pos = c + ex * side * (half[0] + wound_gap / 2) - n * half[2]
            body = p.createMultiBody(0.0, col, vis, pos.tolist(), quat, physicsClientId=client)
            p.changeDynamics(body, -1, lateralFriction=0.5, physicsClientId=client)
            self.bodies.append(body)
        return self

    def thread(self, suture: Suture) -> None:
        """Declare that ``suture`` passes through the stitch channel (after the needle pass)."""
        self.suture = suture

    def _project(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Nearest channel point, unit tangent and channel parameter s of each point in x."""
        a, b = self.channel[:-1], self.channel[1:]
        u = b - a
        uu = np.einsum("ij,ij->i", u, u)
        t = np.clip(np.einsum("kij,ij->ki", x[:, None, :] - a[None], u) / uu, 0.0, 1.0)
        q = a[None] + t[..., None] * u[None]
        d = np.linalg.norm(q - x[:, None, :], axis=2)
        k = np.argmin(d, axis=1)
        idx = np.arange(len(x))
        s = (k + t[idx, k]) / len(u)
        tangent = u[k] / np.sqrt(uu[k])[:, None]
        return q[idx, k], tangent, s

    def pre_step(self) -> None:
        """Apply channel guidance and friction (4.5) to the capsules inside the channel."""
        import pybullet as p

        sut = self.suture
        if sut is None:
            return
        c = self.client
        pos = np.array(
            [p.getBasePositionAndOrientation(b, physicsClientId=c)[0] for b in sut.bodies]
        )
        q, tangent, s = self._project(pos)
        dist = np.linalg.norm(q - pos, axis=1)
        inside = [i for i in range(len(pos)) if 0.0 < s[i] < 1.0 and dist[i] < self.capture]
        # Capsules in the channel or crossing the surface at its ends pass through the pad.
        hole = self.capture + sut.params.segment_length / 2
        passing = {i for i in range(len(pos)) if dist[i] < hole}
        for i in passing ^ self._passing:
            enable = 0 if i in passing else 1
            for tb in self.bodies:
                p.setCollisionFilterPair(sut.bodies[i], tb, -1, -1, enable, physicsClientId=c)
        self._passing = passing
        self.inside = inside
        # Friction the anchors applied in the last step, along the channel (4.5, static part).
        static = 0.0
        for i, cons in list(self._anchors.items()):
            force = np.asarray(p.getConstraintState(cons, physicsClientId=c)[:3])
            if i in inside:
                static -= float(force @ tangent[i])
            else:
                p.removeConstraint(cons, physicsClientId=c)
                del self._anchors[i]
        if not inside:
            self.last_friction = self.last_sliding_speed = 0.0
            return
        vel = np.array([p.getBaseVelocity(sut.bodies[i], physicsClientId=c)[0] for i in inside])
        axes = np.array(
            [
                p.getMatrixFromQuaternion(
                    p.getBasePositionAndOrientation(sut.bodies[i], physicsClientId=c)[1]
                )[2::3]
                for i in inside
            ]
        )
        tan = tangent[inside]
        axial = np.einsum("ij,ij->i", vel, tan)
        l_dot = float(axial.mean())
        mass = sut.params.segment_mass
        dt = float(p.getPhysicsEngineParameters(physicsClientId=c)["fixedTimeStep"])
        c_visc = min(self.f_viscous / len(inside), 0.5 * mass / dt)
        c_lat = min(self.c_lateral, 0.5 * mass / dt)
        cap = self.f_static / len(inside)
        self.last_sliding_speed = l_dot
        self.last_friction = static - c_visc * len(inside) * l_dot
        for row, i in enumerate(inside):
            anchor = self._anchors.get(i)
            if anchor is None:
                anchor = p.createConstraint(
                    sut.bodies[i],
                    -1,
                    -1,
                    -1,
                    p.JOINT_POINT2POINT,
                    [0, 0, 0],
                    [0, 0, 0],
                    pos[i].tolist(),
                    physicsClientId=c,
                )
                self._anchors[i] = anchor
            p.changeConstraint(
                anchor, jointChildPivot=pos[i].tolist(), maxForce=cap, physicsClientId=c
            )
            # Guidance acts across the capsule's own axis as well as across the channel,
            # so where a straight capsule cuts a curved channel it cannot push the thread
            # along itself (only friction acts along the thread).
            err = pos[i] - q[i]
            err -= tan[row] * float(err @ tan[row])
            err -= axes[row] * float(err @ axes[row])
            v_perp = vel[row] - tan[row] * axial[row]
            force = -self.k_lateral * err - c_lat * v_perp - c_visc * axial[row] * tan[row]
            p.applyExternalForce(
                sut.bodies[i],
                -1,
                force.tolist(),
                pos[i].tolist(),
                p.WORLD_FRAME,
                physicsClientId=c,
            )


def _quat_from_matrix(r: FloatArray) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of a rotation matrix."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(r).as_quat()
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
