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
* passes through the two puncture holes as through eyelets once the stitch is made: the
  thread's point nearest each hole is pulled onto it, across the thread only
  (``k_hole`` [N/m]). Without them a strand pulled back over the wound (a tightening
  stitch loop) drew the thread out of the exit hole a capsule at a time, and algorithm
  3's tightening pulled the stitch out of the tissue at 0.3 N,
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
from typing import TYPE_CHECKING, Any

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


HOLE_RAMP = 1.0
"""Time over which the holes' hold is taken up once the stitch is made [s]."""


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
        k_hole: stiffness with which each puncture hole holds the thread [N/m] (within
            the explicit-spring stability bound of a 1 g capsule at 1 kHz, ~4000 N/m).
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
    k_lateral: float = 1000.0
    c_lateral: float = 0.2
    k_hole: float = 1500.0
    capture: float = 3e-3
    bodies: list[int] = field(default_factory=list)
    channel: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    suture: Suture | None = None
    inside: list[int] = field(default_factory=list)
    _passing: set[int] = field(default_factory=set)
    _anchors: dict[int, int] = field(default_factory=dict)
    last_friction: float = 0.0
    last_sliding_speed: float = 0.0
    surface: Vec3 = (0.0, 0.0, 0.0)
    half_size: tuple[float, float] = (0.02, 0.02)
    punctured: bool = False
    """Whether a tracked needle has entered the tissue (:meth:`track`)."""
    exited: bool = False
    """Whether it has come out again: the channel is then its path through the tissue."""
    _tracked: Suture | None = None
    _geometry: tuple[Any, ...] = ()
    """Per-channel constants (the channel, its arc lengths, segment starts, vectors and
    squared lengths), rebuilt when :attr:`channel` is replaced."""
    _path: list[FloatArray] = field(default_factory=list)
    _last_end: FloatArray | None = None
    _snag_extra: float = 0.0
    _snag_steps: int = 0
    _sigma: float | None = None
    _hole_gain: float = 0.0
    _dt: float | None = None

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
                ``k_lateral`` [N/m], ``c_lateral`` [N*s/m], ``k_hole`` [N/m], ``capture`` [m].

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
            surface=(float(center[0]), float(center[1]), float(center[2])),
            half_size=(size[0] / 2, size[1] / 2),
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

    def track(self, suture: Suture) -> None:
        """Let ``suture``'s needle puncture the tissue (the puncture model).

        The needle passes through the pad (no collision); its swaged end, where the
        thread starts, is followed each :meth:`pre_step`. When it goes below the surface
        inside the pad, the tissue is punctured: the channel becomes the path of the
        swaged end from that surface crossing on, and the thread is :meth:`thread`-ed
        into it (captured: guided and held by the friction (4.5)) as it follows. When
        the swaged end comes back above the surface, the channel is closed at that exit
        point and stays as it is. One stitch per tissue: a later puncture is not made
        (nor is one on a tissue already threaded), but the needle still passes through.
        """
        import pybullet as p

        self._tracked = suture
        if self.suture is not None:  # already threaded: the stitch is made
            self.punctured = self.exited = True
        for body in self.bodies:
            p.setCollisionFilterPair(
                suture.needle_body, body, -1, -1, 0, physicsClientId=self.client
            )

    def snag(self, extra_static: float, duration: float) -> None:
        """Add ``extra_static`` [N] to the static friction F_s (4.5) for ``duration`` [s]
        (a snag of the thread in the tissue; counted in :meth:`pre_step` calls)."""
        import pybullet as p

        dt = float(p.getPhysicsEngineParameters(physicsClientId=self.client)["fixedTimeStep"])
        self._snag_extra = float(extra_static)
        self._snag_steps = max(1, round(duration / dt))

    def _pass_through(self, index: int, through: bool) -> None:
        """Let thread capsule ``index`` pass through the pad (no collision), or not."""
        import pybullet as p

        sut = self.suture or self._tracked
        if sut is None:
            return
        for body in self.bodies:
            p.setCollisionFilterPair(
                sut.bodies[index], body, -1, -1, int(not through), physicsClientId=self.client
            )
        if through:
            self._passing.add(index)
        else:
            self._passing.discard(index)

    def _height(self, x: FloatArray) -> float:
        """Height of ``x`` above the pad's top surface [m]."""
        return float(np.asarray(self.normal) @ (x - np.asarray(self.surface)))

    def _over_pad(self, x: FloatArray) -> bool:
        n = np.asarray(self.normal)
        d = x - np.asarray(self.surface)
        d = d - n * float(n @ d)
        ex = np.asarray(self.exit) - np.asarray(self.entry)
        ex = ex - n * float(n @ ex)
        ex = ex / np.linalg.norm(ex)
        ey = np.cross(n, ex)
        return abs(float(d @ ex)) <= self.half_size[0] and abs(float(d @ ey)) <= self.half_size[1]

    def _crossing(self, a: FloatArray, b: FloatArray) -> FloatArray:
        """Where the segment a -> b crosses the surface [m]."""
        ha, hb = self._height(a), self._height(b)
        t = ha / (ha - hb) if ha != hb else 0.0
        out: FloatArray = a + min(max(t, 0.0), 1.0) * (b - a)
        return out

    def _track_needle(self) -> None:
        """The puncture model (:meth:`track`): follow the needle's swaged end."""
        import pybullet as p

        sut = self._tracked
        if sut is None or self.exited:
            return
        # The needle's frame origin is its swaged end, where the thread is attached.
        pos, _ = p.getBasePositionAndOrientation(sut.needle_body, physicsClientId=self.client)
        end = np.asarray(pos, dtype=float)
        last = self._last_end if self._last_end is not None else end
        self._last_end = end
        below = self._height(end) < 0.0
        if not self.punctured:
            if below and self._over_pad(end):
                self.punctured = True
                entry = self._crossing(last, end)
                self._path = [entry, end]
                self.entry = (float(entry[0]), float(entry[1]), float(entry[2]))
                self.channel = np.array(self._path)
                self.suture = sut
            return
        if below:
            if np.linalg.norm(end - self._path[-1]) > 0.25e-3:
                self._path.append(end)
            self.channel = np.array([*self._path[:-1], end])
            return
        exit_ = self._crossing(last, end)
        self._path.append(exit_)
        self.exit = (float(exit_[0]), float(exit_[1]), float(exit_[2]))
        self.channel = _resample_polyline(np.array(self._path), 25)
        self.exited = True

    def _project(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Nearest channel point, unit tangent and channel parameter s of each point in x."""
        _, _, a, u, uu = self._channel_geometry()
        t = np.clip(np.einsum("kij,ij->ki", x[:, None, :] - a[None], u) / uu, 0.0, 1.0)
        q = a[None] + t[..., None] * u[None]
        d = np.linalg.norm(q - x[:, None, :], axis=2)
        k = np.argmin(d, axis=1)
        idx = np.arange(len(x))
        s = (k + t[idx, k]) / len(u)
        tangent = u[k] / np.sqrt(uu[k])[:, None]
        return q[idx, k], tangent, s

    def _channel_geometry(
        self,
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """The channel, its arc length at each point [m], and its segments' starts, vectors
        [m] and squared lengths [m^2] (at least 1e-18), computed once per channel."""
        cached = self._geometry
        if cached and cached[0] is self.channel:
            return cached  # type: ignore[return-value]
        ch = self.channel
        lam = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ch, axis=0), axis=1))])
        a, b = ch[:-1], ch[1:]
        u = b - a
        uu = np.maximum(np.einsum("ij,ij->i", u, u), 1e-18)
        self._geometry = (ch, lam, a, u, uu)
        return self._geometry  # type: ignore[return-value]

    def _thread_axes(self, sut: Suture, span: float) -> tuple[FloatArray, FloatArray]:
        """Centre [m] and unit axis (tail to needle) of the capsules of ``sut`` that can be
        in or next to the channel (``span`` [m] long) this step: all of them the first
        time, then those within two capsules of where the thread was (the rest: NaN)."""
        import pybullet as p

        c = self.client
        n = len(sut.bodies)
        pos = np.full((n, 3), np.nan)
        axis = np.full((n, 3), np.nan)
        window = range(n)
        if self._sigma is not None:
            seg = sut.params.segment_length
            lo = max(0, int(self._sigma / seg) - 2)
            window = range(lo, min(n, int((self._sigma + span) / seg) + 3))
        for i in window:
            x, q = p.getBasePositionAndOrientation(sut.bodies[i], physicsClientId=c)
            pos[i] = x
            axis[i] = p.getMatrixFromQuaternion(q)[2::3]
        return pos, axis

    def _closest_on(
        self, x: FloatArray, pos: FloatArray, axis: FloatArray, i: int, h: float
    ) -> float:
        """Parameter t in [0, 1] of the point of capsule ``i``'s axis nearest ``x``."""
        a = pos[i] - h * axis[i]
        return min(max(float((x - a) @ axis[i]) / (2 * h), 0.0), 1.0)

    def _update_sigma(self, pos: FloatArray, axis: FloatArray, h: float) -> None:
        """Follow the thread's arc length at the entry point as the thread slides."""
        seg = 2 * h
        entry = np.asarray(self.channel[0])
        n = len(pos)
        if self._sigma is None:
            window = range(n)
        else:
            k = int(self._sigma / seg)
            window = range(max(0, k - 1), min(n, k + 2))
        best, sigma = np.inf, 0.0
        for i in window:
            if np.isnan(pos[i, 0]):
                continue
            t = self._closest_on(entry, pos, axis, i, h)
            d = float(np.linalg.norm(pos[i] + (2 * t - 1) * h * axis[i] - entry))
            if d < best:
                best, sigma = d, (i + t) * seg
        self._sigma = sigma

    def pre_step(self) -> None:
        """Apply channel guidance and friction (4.5) to the thread in the channel.

        The thread is followed by arc length: ``sigma`` [m], its arc length (from the tail
        end) at the entry point, is updated each step from where the thread crosses it.
        The thread from ``sigma`` to ``sigma`` plus the channel's length lies in the channel:
        each channel sample point pulls the point of the capsule at that arc length nearest
        it, across the capsule's axis only (``k_lateral`` [N/m] shared by the samples,
        ``c_lateral`` [N*s/m]), so the thread passes through the puncture points and along
        the channel but slides freely along itself, against the friction (4.5) alone.
        """
        import pybullet as p

        self._track_needle()
        if self._snag_steps > 0:
            self._snag_steps -= 1
            if self._snag_steps == 0:
                self._snag_extra = 0.0
        sut = self.suture
        if sut is None and self._tracked is not None and not self._passing:
            self._pass_through(len(self._tracked.bodies) - 1, True)
        if sut is None or len(self.channel) < 2:
            return
        c = self.client
        lam = self._channel_geometry()[1]
        span = float(lam[-1])
        pos, axes = self._thread_axes(sut, span)
        seg = sut.params.segment_length
        h = seg / 2
        total = seg * len(pos)
        self._update_sigma(pos, axes, h)
        sigma = float(self._sigma or 0.0)
        first = max(0, int(sigma / seg))
        last = min(len(pos) - 1, int(min(sigma + span, total - 1e-12) / seg))
        inside = list(range(first, last + 1)) if sigma < total else []
        # The capsules in the channel and their neighbours pass through the pad.
        passing = set(range(max(0, first - 1), min(len(pos), last + 2))) if inside else set()
        if self._tracked is sut and sut.bodies:
            passing.add(len(sut.bodies) - 1)  # the needle's own capsule goes where it goes
        for i in passing ^ self._passing:
            self._pass_through(i, i in passing)
        self._passing = passing
        self.inside = inside
        # Friction the anchors applied in the last step, along the channel (4.5, static part).
        tangent = {}
        if inside:
            _, tan_in, _ = self._project(pos[inside])
            tangent = dict(zip(inside, tan_in, strict=True))
        static = 0.0
        for i, cons in list(self._anchors.items()):
            if i in tangent:
                force = np.asarray(p.getConstraintState(cons, physicsClientId=c)[:3])
                static -= float(force @ tangent[i])
            else:
                p.removeConstraint(cons, physicsClientId=c)
                del self._anchors[i]
        if not inside:
            self.last_friction = self.last_sliding_speed = 0.0
            return
        vel = np.array([p.getBaseVelocity(sut.bodies[i], physicsClientId=c)[0] for i in inside])
        tan = np.array([tangent[i] for i in inside])
        axial = np.einsum("ij,ij->i", vel, tan)
        l_dot = float(axial.sum() / len(axial))  # the mean, as np.mean computes it
        mass = sut.params.segment_mass
        if self._dt is None:
            self._dt = float(p.getPhysicsEngineParameters(physicsClientId=c)["fixedTimeStep"])
        dt = self._dt
        c_visc = min(self.f_viscous / len(inside), 0.5 * mass / dt)
        c_lat = min(self.c_lateral, 0.5 * mass / dt)
        cap = (self.f_static + self._snag_extra) / len(inside)
        self.last_sliding_speed = l_dot
        self.last_friction = static - c_visc * len(inside) * l_dot
        # Guidance: each channel point pulls the nearest point of the capsule at its arc
        # length, across that capsule's axis; summed per capsule as a force at its centre
        # and a torque.
        arc = sigma + lam
        keep = arc < total
        idx = np.minimum((arc[keep] / seg).astype(int), len(pos) - 1)
        x = self.channel[keep]
        ax = axes[idx]
        start = pos[idx] - h * ax
        t = np.clip(np.einsum("ij,ij->i", x - start, ax) / seg, 0.0, 1.0)
        at = start + (seg * t)[:, None] * ax
        err = x - at
        err -= ax * np.einsum("ij,ij->i", err, ax)[:, None]
        pull = (self.k_lateral / len(self.channel)) * err
        force_sum = np.zeros((len(pos), 3))
        torque_sum = np.zeros((len(pos), 3))
        np.add.at(force_sum, idx, pull)
        np.add.at(torque_sum, idx, _cross(at - pos[idx], pull))
        # The puncture holes hold the thread like eyelets: the thread's point nearest each
        # hole (among the capsules near its arc length there) is pulled onto it. Only once
        # the stitch is made (while the needle is in the tissue it leads the thread), and
        # taken up over HOLE_RAMP [s] so that the switch does not jerk the thread.
        holes = []
        if self.exited:
            holes = [(self.channel[0], sigma), (self.channel[-1], sigma + span)]
            self._hole_gain = min(1.0, self._hole_gain + dt / HOLE_RAMP)
        for hole, near in holes:
            k0 = int(near / seg)
            best, where, cap_i, at_t = np.inf, None, -1, 0.5
            for i in range(max(0, k0 - 2), min(len(pos), k0 + 3)):
                if np.isnan(pos[i, 0]):
                    continue
                a0 = pos[i] - h * axes[i]
                tt = min(max(float((hole - a0) @ axes[i]) / seg, 0.0), 1.0)
                q = a0 + seg * tt * axes[i]
                d = float(np.linalg.norm(hole - q))
                if d < best:
                    best, where, cap_i, at_t = d, q, i, tt
            if where is not None:
                err_h = hole - where
                # across the thread only, the thread's direction there blended with the
                # neighbouring capsule's towards a joint: the thread slides through the hole
                # freely (against the channel's friction alone), with no detent at the joints
                other = cap_i + (1 if at_t > 0.5 else -1)
                tangent_h = axes[cap_i].copy()
                if 0 <= other < len(pos) and not np.isnan(axes[other, 0]):
                    tangent_h += 2.0 * abs(at_t - 0.5) * axes[other]
                    tangent_h /= np.linalg.norm(tangent_h)
                err_h = err_h - tangent_h * float(err_h @ tangent_h)
                f = self._hole_gain * self.k_hole * err_h
                force_sum[cap_i] += f
                torque_sum[cap_i] += _cross(where - pos[cap_i], f)
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
            v_perp = vel[row] - axes[i] * float(vel[row] @ axes[i])
            force = force_sum[i] - c_lat * v_perp - c_visc * axial[row] * tan[row]
            p.applyExternalForce(
                sut.bodies[i],
                -1,
                force.tolist(),
                pos[i].tolist(),
                p.WORLD_FRAME,
                physicsClientId=c,
            )
            if np.any(torque_sum[i]):
                p.applyExternalTorque(
                    sut.bodies[i], -1, torque_sum[i].tolist(), p.WORLD_FRAME, physicsClientId=c
                )
        # a hole's capsule just outside the channel (the thread leaving it) gets its pull too
        for j in np.flatnonzero(np.any(force_sum != 0.0, axis=1)):
            i = int(j)
            if i in tangent:
                continue
            v = np.asarray(p.getBaseVelocity(sut.bodies[i], physicsClientId=c)[0])
            v_perp = v - axes[i] * float(v @ axes[i])
            force = force_sum[i] - c_lat * v_perp
            p.applyExternalForce(
                sut.bodies[i], -1, force.tolist(), pos[i].tolist(), p.WORLD_FRAME, physicsClientId=c
            )
            p.applyExternalTorque(
                sut.bodies[i], -1, torque_sum[i].tolist(), p.WORLD_FRAME, physicsClientId=c
            )


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``np.cross`` of 3-vectors (or N×3 rows), with the same products and differences in
    the same order (the same bits) at a fraction of its call overhead."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def _resample_polyline(path: FloatArray, count: int) -> FloatArray:
    """``count`` points evenly spaced by arc length along ``path`` [m]."""
    d = np.linalg.norm(np.diff(path, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(d)])
    if s[-1] <= 0.0:
        return np.repeat(path[:1], count, axis=0)
    at = np.linspace(0.0, s[-1], count)
    out: FloatArray = np.stack([np.interp(at, s, path[:, k]) for k in range(3)], axis=1)
    return out


def _quat_from_matrix(r: FloatArray) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of a rotation matrix."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(r).as_quat()
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
