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

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from backends.pybullet.suture import capsule_axis
from suture_engine.arithmetic import row_dot, sin
from suture_engine.errors import SutureError

if TYPE_CHECKING:
    from backends.pybullet.suture import Suture

__all__ = ["WOUND_GAP", "Tissue", "TissueError", "channel_friction"]

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


WOUND_GAP = 1e-3
"""Width of the wound between the pad's two halves, as the thread's contacts meet it [m]
(:meth:`Tissue.create`'s default, which every result so far was measured with). The
thread collides as capsules 1.8 mm thick (``SutureParams.collision_radius``), six times
the 2-0 thread's 0.3 mm, so a capsule pressed down into a 1 mm slit is pinched between
the two static halves, about 1 mm deep in each: the contacts then hold it with tens of
newtons, and the joints beside it read a tension no pull made. On algorithm 3's draw 1
with friction alone (14.09 N), a capsule got there when it got its contacts back inside
a half and was thrown out (:attr:`Tissue.clear_depth` makes such capsules wait); a
press alone still pinches one (``tests/test_tissue.py``). A slit wider than the capsules
lets the thread fall through the pad. A floor 0.4 mm under the surface (``wound_depth``:
the edges apposed below a groove) keeps the capsules out of the slit's walls; 0 (the
wound closed) leaves no groove. Both tie fewer squares with algorithm 3 (docs/status.md)."""

CLEAR_DEPTH = 0.1e-3
"""The depth to give :attr:`Tissue.clear_depth` to turn its wait on [m]: a capsule resting
on the pad under a 0.5 N press sinks 0.02-0.03 mm into it (contactERP 0.4, 1 kHz), so one
deeper than this is inside the pad. Off by default: it removed algorithm 3's two spikes
with friction alone, but tied fewer squares, and one unperturbed run drew 16.71 N in its
mirrored tighten (docs/status.md, "Contacts given back inside the pad")."""

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
    clear_depth: float | None = None
    """A capsule leaving the channel gets its contact with a pad body back only once it
    lies no deeper than this in the body [m] (:data:`CLEAR_DEPTH`); None: at once, wherever
    it is (the default, which every result was measured with)."""
    bodies: list[int] = field(default_factory=list)
    channel: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    suture: Suture | None = None
    inside: list[int] = field(default_factory=list)
    _passing: set[int] = field(default_factory=set)
    _clearing: set[tuple[int, int]] = field(default_factory=set)
    """(capsule, pad body) pairs left out of the channel but not yet clear of that body:
    their contacts wait (see :meth:`_pass_through`)."""
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
        wound_gap: float = WOUND_GAP,
        wound_depth: float | None = None,
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
            wound_gap: width of the wound between the two halves [m] (:data:`WOUND_GAP`).
            wound_depth: how deep the wound stays open under the surface [m]: below it
                a floor closes it (the edges apposed under the surface); None: open
                through the pad. No floor without a gap.
            **kwargs: ``f_static`` [N], ``f_viscous`` [N*s/m], ``k_lateral`` [N/m],
                ``c_lateral`` [N*s/m], ``k_hole`` [N/m], ``capture`` [m], ``clear_depth`` [m].

        Raises:
            TissueError: a zero normal, coincident entry/exit, a non-positive depth, a
                wound gap that is negative or not narrower than the pad, a wound depth
                outside the pad's thickness, or a negative clear depth.
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
        if not 0 <= wound_gap < size[0]:
            raise TissueError("wound_gap", wound_gap, f"must be in [0, {size[0]:g}) [m]")
        ex = across / np.linalg.norm(across)
        c = np.asarray(center, dtype=float)
        inside = min(abs(float(ex @ (a - c))), abs(float(ex @ (b - c))))
        if inside < wound_gap / 2:
            raise TissueError(
                "wound_gap",
                wound_gap,
                f"leaves a bite in the opening: the entry or exit point lies "
                f"{inside * 1e3:.3g} mm from the wound's middle, inside its "
                f"{wound_gap * 1e3:.3g} mm opening",
            )
        clear_depth = kwargs.get("clear_depth")
        if clear_depth is not None and not clear_depth >= 0:
            raise TissueError("clear_depth", clear_depth, "must be >= 0 [m] or None")
        if wound_depth is not None and not 0 < wound_depth < size[2]:
            raise TissueError(
                "wound_depth", wound_depth, f"must be in (0, {size[2]:g}) [m] or None"
            )
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
        self.channel = a + s[:, None] * (b - a) - depth * sin(np.pi * s)[:, None] * n
        ey = np.cross(n, ex)
        rot = np.column_stack([ex, ey, n])
        quat = _quat_from_matrix(rot)
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
        if wound_depth is not None and wound_gap > 0:
            # the wound's floor: the slit's width, from wound_depth down to the pad's bottom
            floor = np.array([wound_gap / 2, size[1] / 2, (size[2] - wound_depth) / 2])
            col = p.createCollisionShape(
                p.GEOM_BOX, halfExtents=floor.tolist(), physicsClientId=client
            )
            vis = p.createVisualShape(
                p.GEOM_BOX,
                halfExtents=floor.tolist(),
                rgbaColor=[0.8, 0.4, 0.4, 1.0],
                physicsClientId=client,
            )
            pos = c - n * (wound_depth + floor[2])
            body = p.createMultiBody(0.0, col, vis, pos.tolist(), quat, physicsClientId=client)
            p.changeDynamics(body, -1, lateralFriction=0.5, physicsClientId=client)
            self.bodies.append(body)
        return self

    def park(self, at: Sequence[float]) -> None:
        """Take the pad and its hold on the thread out of play, and forget the thread (an
        interrupted suture's cut: the next stitch gets a pad of its own). The hold's
        constraints go; the pad's bodies stay (see :meth:`Suture.park` for why), moved to
        ``at`` [m] far from the scene and touching nothing. Call it before the thread is
        parked."""
        import pybullet as p

        c = self.client
        for cons in self._anchors.values():
            p.removeConstraint(cons, physicsClientId=c)
        self._anchors.clear()
        where = [float(v) for v in at]
        for body in self.bodies:
            p.setCollisionFilterGroupMask(body, -1, 0, 0, physicsClientId=c)
            p.resetBasePositionAndOrientation(body, where, [0, 0, 0, 1], physicsClientId=c)
        self.bodies.clear()
        self.suture = self._tracked = None
        self._passing.clear()
        self._clearing.clear()

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
        """Let thread capsule ``index`` pass through the pad (no collision), or not.

        With :attr:`clear_depth` set, a capsule given its contacts back is given them body
        by body, and only once it lies no deeper than that in the body: until then the pair
        waits in ``_clearing`` (see :meth:`_clear_passed`). Without it, a capsule that
        leaves the channel's set while still inside the pad (the thread slipping a capsule
        through the stitch) is thrown out by the contact's penetration recovery in one
        step."""
        import pybullet as p

        sut = self.suture or self._tracked
        if sut is None:
            return
        c = self.client
        capsule = sut.bodies[index]
        for body in self.bodies:
            if through:
                self._clearing.discard((index, body))
                enable = 0
            elif self.clear_depth is not None and p.getClosestPoints(
                body, capsule, -self.clear_depth, physicsClientId=c
            ):
                self._clearing.add((index, body))
                continue  # still inside the body: stays passable until it has come out
            else:
                enable = 1
            p.setCollisionFilterPair(capsule, body, -1, -1, enable, physicsClientId=c)
        if through:
            self._passing.add(index)
        else:
            self._passing.discard(index)

    def _clear_passed(self, sut: Suture) -> None:
        """Give each waiting capsule (``_clearing``) its contact with a pad body once it
        lies no deeper than :attr:`clear_depth` in it (at once if the wait was turned off)."""
        import pybullet as p

        c = self.client
        depth = self.clear_depth
        for index, body in sorted(self._clearing):
            capsule = sut.bodies[index]
            if depth is None or not p.getClosestPoints(body, capsule, -depth, physicsClientId=c):
                p.setCollisionFilterPair(capsule, body, -1, -1, 1, physicsClientId=c)
                self._clearing.discard((index, body))

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

    def _tangents(self, x: FloatArray) -> FloatArray:
        """The unit tangent of the channel's segment nearest each point in ``x`` [m]."""
        _, _, a, u, uu = self._channel_geometry()
        t = np.clip(row_dot(x[:, None, :] - a[None], u) / uu, 0.0, 1.0)
        d = a[None] + t[..., None] * u[None] - x[:, None, :]
        # np.linalg.norm(d, axis=2) by the ufunc calls it makes (the same bits)
        k = np.sqrt(np.add.reduce(d * d, axis=2)).argmin(axis=1)
        out: FloatArray = u[k] / np.sqrt(uu[k])[:, None]
        return out

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
        uu = np.maximum(row_dot(u, u), 1e-18)
        self._geometry = (ch, lam, a, u, uu)
        return self._geometry  # type: ignore[return-value]

    def _thread_axes(
        self, sut: Suture, span: float
    ) -> tuple[FloatArray, FloatArray, list[Vec3 | None], list[Vec3 | None]]:
        """Centre [m] and unit axis (tail to needle) of the capsules of ``sut`` that can be
        in or next to the channel (``span`` [m] long) this step: all of them the first
        time, then those within two capsules of where the thread was (the rest: NaN).

        Returns them as arrays and as per-capsule tuples of Python floats (None outside
        the window), for the per-capsule arithmetic. Poses the suture read in this step's
        :meth:`Suture.pre_step` are used as they are (no body moved since)."""
        import pybullet as p

        c = self.client
        n = len(sut.bodies)
        window = range(n)
        if self._sigma is not None:
            seg = sut.params.segment_length
            lo = max(0, int(self._sigma / seg) - 2)
            window = range(lo, min(n, int((self._sigma + span) / seg) + 3))
        pos_t: list[Vec3 | None] = [None] * n
        axis_t: list[Vec3 | None] = [None] * n
        read = sut.take_step_poses()
        for i in window:
            if read is not None:
                pos_t[i], axis_t[i] = read.positions[i], read.axis(i)
            else:
                x, q = p.getBasePositionAndOrientation(sut.bodies[i], physicsClientId=c)
                pos_t[i], axis_t[i] = x, capsule_axis(q)
        pos = np.full((n, 3), np.nan)
        axis = np.full((n, 3), np.nan)
        if len(window):
            pos[window.start : window.stop] = pos_t[window.start : window.stop]
            axis[window.start : window.stop] = axis_t[window.start : window.stop]
        return pos, axis, pos_t, axis_t

    def _update_sigma(self, pos_t: list[Vec3 | None], axis_t: list[Vec3 | None], h: float) -> None:
        """Follow the thread's arc length at the entry point as the thread slides.

        Per capsule, in Python floats: the nearest point of the capsule's axis to the
        entry point, and their distance (sums of products in order, as numpy's 3-vector
        ``@`` and ``np.linalg.norm`` take them, so the values are theirs to the bit)."""
        seg = 2 * h
        e0, e1, e2 = self.channel[0].tolist()
        n = len(pos_t)
        if self._sigma is None:
            window = range(n)
        else:
            k = int(self._sigma / seg)
            window = range(max(0, k - 1), min(n, k + 2))
        best, sigma = math.inf, 0.0
        for i in window:
            x, a = pos_t[i], axis_t[i]
            if x is None or a is None or math.isnan(x[0]):
                continue
            # t = clip(((entry - (x - h a)) . a) / (2 h), 0, 1)
            dot = (e0 - (x[0] - h * a[0])) * a[0]
            dot = dot + (e1 - (x[1] - h * a[1])) * a[1]
            dot = dot + (e2 - (x[2] - h * a[2])) * a[2]
            t = min(max(dot / (2 * h), 0.0), 1.0)
            s = (2 * t - 1) * h
            r0, r1, r2 = x[0] + s * a[0] - e0, x[1] + s * a[1] - e1, x[2] + s * a[2] - e2
            d = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
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
        pos, axes, pos_t, axis_t = self._thread_axes(sut, span)
        seg = sut.params.segment_length
        h = seg / 2
        n = len(pos)
        total = seg * n
        self._update_sigma(pos_t, axis_t, h)
        sigma = float(self._sigma or 0.0)
        first = max(0, int(sigma / seg))
        last = min(n - 1, int(min(sigma + span, total - 1e-12) / seg))
        inside = list(range(first, last + 1)) if sigma < total else []
        # The capsules in the channel and their neighbours pass through the pad.
        passing = set(range(max(0, first - 1), min(n, last + 2))) if inside else set()
        if self._tracked is sut and sut.bodies:
            passing.add(len(sut.bodies) - 1)  # the needle's own capsule goes where it goes
        for i in passing ^ self._passing:
            self._pass_through(i, i in passing)
        self._passing = passing
        if self._clearing:
            self._clear_passed(sut)
        self.inside = inside
        # Friction the anchors applied in the last step, along the channel (4.5, static part).
        tan_t: dict[int, Vec3] = {}
        if inside:
            tan = self._tangents(pos[inside])  # row k: capsule inside[k]
            tan_t = dict(zip(inside, map(tuple, tan.tolist()), strict=True))
        static = 0.0
        for i, cons in list(self._anchors.items()):
            if i in tan_t:
                f0, f1, f2 = p.getConstraintState(cons, physicsClientId=c)[:3]
                t0, t1, t2 = tan_t[i]
                static -= f0 * t0 + f1 * t1 + f2 * t2
            else:
                p.removeConstraint(cons, physicsClientId=c)
                del self._anchors[i]
        if not inside:
            self.last_friction = self.last_sliding_speed = 0.0
            return
        vel_t = [p.getBaseVelocity(sut.bodies[i], physicsClientId=c)[0] for i in inside]
        vel = np.array(vel_t)
        axial = row_dot(vel, tan)
        axial_t = axial.tolist()
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
        idx = np.minimum((arc[keep] / seg).astype(int), n - 1)
        x = self.channel[keep]
        ax = axes[idx]
        start = pos[idx] - h * ax
        t = np.clip(row_dot(x - start, ax) / seg, 0.0, 1.0)
        at = start + (seg * t)[:, None] * ax
        err = x - at
        err -= ax * row_dot(err, ax)[:, None]
        pull = (self.k_lateral / len(self.channel)) * err
        force_sum = np.zeros((n, 3))
        torque_sum = np.zeros((n, 3))
        np.add.at(force_sum, idx, pull)
        np.add.at(torque_sum, idx, _cross(at - pos[idx], pull))
        # The puncture holes hold the thread like eyelets: the thread's point nearest each
        # hole (among the capsules near its arc length there) is pulled onto it. Only once
        # the stitch is made (while the needle is in the tissue it leads the thread), and
        # taken up over HOLE_RAMP [s] so that the switch does not jerk the thread.
        touched = set(idx.tolist())
        force_t = force_sum.tolist()
        torque_t = torque_sum.tolist()
        if self.exited:
            self._hole_gain = min(1.0, self._hole_gain + dt / HOLE_RAMP)
            gain = self._hole_gain * self.k_hole
            for hole, near in ((self.channel[0], sigma), (self.channel[-1], sigma + span)):
                held = _hole_pull(hole.tolist(), near, pos_t, axis_t, h, gain)
                if held is not None:
                    cap_i, f, tq = held
                    # added to the capsule's sums as floats (numpy's row += adds the same)
                    fs, ts = force_t[cap_i], torque_t[cap_i]
                    force_t[cap_i] = [fs[0] + f[0], fs[1] + f[1], fs[2] + f[2]]
                    torque_t[cap_i] = [ts[0] + tq[0], ts[1] + tq[1], ts[2] + tq[2]]
                    touched.add(cap_i)
        for row, i in enumerate(inside):
            xi, ai = pos_t[i], axis_t[i]
            assert xi is not None and ai is not None  # inside the window by construction
            at_i = list(xi)
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
                    at_i,
                    physicsClientId=c,
                )
                self._anchors[i] = anchor
            p.changeConstraint(anchor, jointChildPivot=at_i, maxForce=cap, physicsClientId=c)
            force = _guided_force(
                force_t[i], vel_t[row], ai, c_lat, c_visc * axial_t[row], tan_t[i]
            )
            p.applyExternalForce(sut.bodies[i], -1, force, at_i, p.WORLD_FRAME, physicsClientId=c)
            torque_i = torque_t[i]
            if torque_i[0] != 0.0 or torque_i[1] != 0.0 or torque_i[2] != 0.0:
                p.applyExternalTorque(sut.bodies[i], -1, torque_i, p.WORLD_FRAME, physicsClientId=c)
        # a hole's capsule just outside the channel (the thread leaving it) gets its pull too
        for i in sorted(touched):
            fi = force_t[i]
            if i in tan_t or (fi[0] == 0.0 and fi[1] == 0.0 and fi[2] == 0.0):
                continue
            xi, ai = pos_t[i], axis_t[i]
            assert xi is not None and ai is not None  # pulled capsules lie in the window
            v = p.getBaseVelocity(sut.bodies[i], physicsClientId=c)[0]
            force = _guided_force(fi, v, ai, c_lat, 0.0, None)
            at_i = list(xi)
            p.applyExternalForce(sut.bodies[i], -1, force, at_i, p.WORLD_FRAME, physicsClientId=c)
            p.applyExternalTorque(sut.bodies[i], -1, torque_t[i], p.WORLD_FRAME, physicsClientId=c)


def _hole_pull(
    hole: list[float],
    near: float,
    pos_t: list[Vec3 | None],
    axis_t: list[Vec3 | None],
    h: float,
    gain: float,
) -> tuple[int, Vec3, Vec3] | None:
    """A puncture hole's eyelet pull (see :meth:`Tissue.pre_step`): the capsule (near arc
    length ``near`` [m]) whose axis passes nearest ``hole`` [m], the force ``gain`` [N/m]
    times the offset across the thread, and its torque about the capsule's centre.

    Python floats, with the operations and their order of the 3-vector numpy expressions
    they replace (``@`` and ``np.linalg.norm`` of 3-vectors sum their products in order),
    so the values are the same to the bit. None when no capsule near is known.
    """
    seg = 2 * h
    h0, h1, h2 = hole
    k0 = int(near / seg)
    n = len(pos_t)
    best, where, cap_i, at_t = math.inf, (0.0, 0.0, 0.0), -1, 0.5
    for i in range(max(0, k0 - 2), min(n, k0 + 3)):
        x, a = pos_t[i], axis_t[i]
        if x is None or a is None or math.isnan(x[0]):
            continue
        s0, s1, s2 = x[0] - h * a[0], x[1] - h * a[1], x[2] - h * a[2]
        dot = (h0 - s0) * a[0] + (h1 - s1) * a[1] + (h2 - s2) * a[2]
        tt = min(max(dot / seg, 0.0), 1.0)
        st = seg * tt
        q = (s0 + st * a[0], s1 + st * a[1], s2 + st * a[2])
        r0, r1, r2 = h0 - q[0], h1 - q[1], h2 - q[2]
        d = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        if d < best:
            best, where, cap_i, at_t = d, q, i, tt
    if cap_i < 0:
        return None
    e0, e1, e2 = h0 - where[0], h1 - where[1], h2 - where[2]
    # across the thread only, the thread's direction there blended with the neighbouring
    # capsule's towards a joint: the thread slides through the hole freely (against the
    # channel's friction alone), with no detent at the joints
    other = cap_i + (1 if at_t > 0.5 else -1)
    t_axis = axis_t[cap_i]
    assert t_axis is not None
    t0, t1, t2 = t_axis
    o = axis_t[other] if 0 <= other < n else None
    if o is not None and not math.isnan(o[0]):
        w = 2.0 * abs(at_t - 0.5)
        t0, t1, t2 = t0 + w * o[0], t1 + w * o[1], t2 + w * o[2]
        norm = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        t0, t1, t2 = t0 / norm, t1 / norm, t2 / norm
    dd = e0 * t0 + e1 * t1 + e2 * t2
    f0, f1, f2 = gain * (e0 - t0 * dd), gain * (e1 - t1 * dd), gain * (e2 - t2 * dd)
    x = pos_t[cap_i]
    assert x is not None
    r0, r1, r2 = where[0] - x[0], where[1] - x[1], where[2] - x[2]
    torque = (r1 * f2 - r2 * f1, r2 * f0 - r0 * f2, r0 * f1 - r1 * f0)
    return cap_i, (f0, f1, f2), torque


def _guided_force(
    pull: list[float],
    v: Vec3,
    axis: Vec3,
    c_lat: float,
    c_axial: float,
    tangent: Vec3 | None,
) -> list[float]:
    """A guided capsule's force [N]: its summed ``pull`` [N], lateral damping ``c_lat``
    [N*s/m] of its velocity ``v`` [m/s] across its ``axis``, and, with a channel
    ``tangent``, the viscous friction ``c_axial`` [N] (coefficient times sliding speed)
    along it. Python floats, in the operation order of the numpy expressions they replace.
    """
    a0, a1, a2 = axis
    dd = v[0] * a0 + v[1] * a1 + v[2] * a2
    p0 = pull[0] - c_lat * (v[0] - a0 * dd)
    p1 = pull[1] - c_lat * (v[1] - a1 * dd)
    p2 = pull[2] - c_lat * (v[2] - a2 * dd)
    if tangent is None:
        return [p0, p1, p2]
    return [p0 - c_axial * tangent[0], p1 - c_axial * tangent[1], p2 - c_axial * tangent[2]]


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``np.cross`` of 3-vectors (or N×3 rows), with the same products and differences in
    the same order (the same bits) at a fraction of its call overhead."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    shape = a.shape if a.shape == b.shape else np.broadcast_shapes(a.shape, b.shape)
    out = np.empty(shape)
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
