"""Tool tips: grasper jaws with a flexible hook, a bent-tip grasper, and the stitcher.

Every tool is a small rigid body held by a fixed "drive" constraint. The drive's parent is
either the world (the tool is then driven kinematically along a pose trajectory by
:meth:`Tool.set_pose`, which is what scripted tests do) or a link of a robot body
(:meth:`Tool.mount`, e.g. the EndoBot's tool link), in which case the tool follows that
link. The drive applies at most ``drive_force`` [N], so a tool pulling on a snagged thread
lags instead of tearing the simulation apart.

* :class:`Grasper` (4.1): pneumatic jaws, binary open/close with a travel time [s].
  Closing on the thread creates a fixed constraint to the nearest thread capsule within
  ``reach`` [m] of the jaw centre; opening removes it. The jaws hold the thread with at
  most ``grip_limit`` [N]: pulled harder, it slides through them (:class:`GripSlip`).
  It carries the flexible hook
  (Fig. 4.6), a curved body that extends over the jaw hinge or retracts, and catches the
  thread by contact.
* :class:`BentTipGrasper`: a grasper whose jaw sits behind a universal joint (two bend
  angles [rad]), for knot-tying algorithm 3.
* :class:`Stitcher` (4.1, Fig. 4.3): EndoStitch-like, two jaws with the needle locked in one;
  :meth:`Stitcher.pass_needle` hands it to the other jaw after the travel time. The needle
  lock has no grip limit (see :class:`Stitcher`).

Call :meth:`Tool.step` once per physics step (it advances jaw travel and the hook).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.arithmetic import row_dot
from suture_engine.errors import SutureError

if TYPE_CHECKING:
    from backends.pybullet.suture import Suture

__all__ = [
    "HOOK_MOUTH",
    "SHAFT_RADIUS",
    "BentTipGrasper",
    "Grasper",
    "GripSlip",
    "JawState",
    "NeedleStall",
    "Stitcher",
    "Tool",
    "ToolError",
]

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
FloatArray = NDArray[np.float64]
_IDENTITY: Quat = (0.0, 0.0, 0.0, 1.0)
SHAFT_RADIUS = 1.5e-3
"""Radius of a grasper's instrument shaft [m]."""
HOOK_MOUTH = 3.5e-3
"""Distance from the hook's shank to its barb, along the tip's x [m]."""
_CAP_RISE = 1.02
"""Largest rise of a grasp rows' cap from one step to the next [-]."""
_SATURATED = 0.99
"""A grasp row transmitting this fraction of its cap is taken as held at the cap [-]."""


class ToolError(SutureError):
    """A tool was asked for something it cannot do.

    Attributes:
        tool: the tool's name.
        action: what was asked.
        reason: why it cannot be done.
    """

    code = "tool-error"

    def __init__(self, tool: str, action: str, reason: str) -> None:
        super().__init__(f"{tool}: cannot {action}: {reason}")
        self.tool = tool
        self.action = action
        self.reason = reason


class GripSlip(NamedTuple):
    """The thread slid through a grasper's jaws (pulled harder than ``grip_limit``).

    Attributes:
        time: the tool's clock when the slide was seen (its steps times ``dt``) [s].
        from_segment: thread capsule the jaws held before.
        to_segment: capsule they hold now (the same one if it is still between the
            jaws; -1 if the thread slid out of them).
        distance: how far the held capsule moved along its axis since the jaws last
            gripped it [m].
        force: force the jaws transmitted in the step before [N].
    """

    time: float
    from_segment: int
    to_segment: int
    distance: float
    force: float


class NeedleStall(NamedTuple):
    """A needle hand-over that stopped short: the thread held the needle back harder than
    the hand-over's drive pushes (``Stitcher.needle_drive_force``).

    Attributes:
        time: the tool's clock when the hand-over ended (its steps times ``dt``) [s].
        shortfall: how far the needle stopped from the receiving jaw [m].
        giving: index of the jaw that keeps the needle (0: the -x jaw, 1: the +x jaw).
    """

    time: float
    shortfall: float
    giving: int


class JawState(Enum):
    """State of pneumatic jaws (binary with a travel time)."""

    OPEN = "open"
    """Fully open; nothing held."""
    CLOSING = "closing"
    """Travelling towards closed."""
    CLOSED = "closed"
    """Fully closed; holds the thread capsule it closed on, if any."""
    OPENING = "opening"
    """Travelling towards open; releases what it held at the start of travel."""


@dataclass
class Tool:
    """Base of all tool tips: a rigid body held by a force-limited fixed drive constraint.

    Attributes:
        client: PyBullet physics client id.
        name: the tool's name (used in errors).
        body: PyBullet body id of the tool tip.
        drive: constraint id of the drive.
        drive_force: largest force the drive applies [N].
    """

    client: int
    name: str
    body: int = -1
    drive: int = -1
    drive_force: float = 50.0
    dt: float = 1e-3
    _weights: dict[int, list[float]] = field(default_factory=dict, init=False, repr=False)
    """Per part body, the force [N] that holds up its weight (read once: its mass never
    changes)."""

    def _make_body(self, half_extents: Vec3, mass: float, rgba: list[float]) -> None:
        import pybullet as p

        col = p.createCollisionShape(
            p.GEOM_BOX, halfExtents=list(half_extents), physicsClientId=self.client
        )
        vis = p.createVisualShape(
            p.GEOM_BOX, halfExtents=list(half_extents), rgbaColor=rgba, physicsClientId=self.client
        )
        self.body = p.createMultiBody(mass, col, vis, [0, 0, 0], physicsClientId=self.client)
        # Jaws hold by constraint, not by contact: the tip body does not collide.
        p.setCollisionFilterGroupMask(self.body, -1, 0, 0, physicsClientId=self.client)

    def _drive_to_world(self, position: Vec3, orientation: Quat) -> None:
        import pybullet as p

        p.resetBasePositionAndOrientation(
            self.body, position, orientation, physicsClientId=self.client
        )
        self.drive = p.createConstraint(
            self.body,
            -1,
            -1,
            -1,
            p.JOINT_FIXED,
            [0, 0, 0],
            [0, 0, 0],
            list(position),
            childFrameOrientation=orientation,
            physicsClientId=self.client,
        )
        p.changeConstraint(self.drive, maxForce=self.drive_force, physicsClientId=self.client)

    def set_pose(self, position: Vec3, orientation: Quat = _IDENTITY) -> None:
        """Command the tool tip's pose (kinematic drive from the world).

        Args:
            position: tip position, world frame [m].
            orientation: tip orientation, quaternion (x, y, z, w).

        Raises:
            ToolError: the tool is mounted on a robot link.
        """
        import pybullet as p

        if self._mounted:
            raise ToolError(self.name, "set a pose", "it is mounted on a robot link")
        p.changeConstraint(
            self.drive,
            jointChildPivot=list(position),
            jointChildFrameOrientation=list(orientation),
            maxForce=self.drive_force,
            physicsClientId=self.client,
        )

    _mounted: bool = False

    def mount(self, robot_body: int, link: int, offset: Vec3 = (0.0, 0.0, 0.0)) -> None:
        """Attach the tool tip to a robot link (e.g. the EndoBot's tool link).

        Args:
            robot_body: PyBullet body id of the robot.
            link: link index of the tool link.
            offset: tip position in the link frame [m].
        """
        import pybullet as p

        state = p.getLinkState(robot_body, link, physicsClientId=self.client)
        pos, orn = p.multiplyTransforms(state[4], state[5], offset, _IDENTITY)
        p.removeConstraint(self.drive, physicsClientId=self.client)
        p.resetBasePositionAndOrientation(self.body, pos, orn, physicsClientId=self.client)
        self.drive = p.createConstraint(
            robot_body,
            link,
            self.body,
            -1,
            p.JOINT_FIXED,
            [0, 0, 0],
            list(offset),
            [0, 0, 0],
            physicsClientId=self.client,
        )
        p.changeConstraint(self.drive, maxForce=self.drive_force, physicsClientId=self.client)
        self._mounted = True

    def pose(self) -> tuple[Vec3, Quat]:
        """The tool tip's current pose: position [m] and quaternion (x, y, z, w)."""
        import pybullet as p

        pos, orn = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        return (tuple(pos), tuple(orn))  # type: ignore[return-value]

    def step(self) -> None:
        """Advance the tool's own motions by one physics step (default: nothing)."""
        self._cancel_weight()

    def _parts(self) -> list[int]:
        """Every body of the tool tip."""
        return [self.body]

    def _cancel_weight(self) -> None:
        """Hold up the tool tip's own weight: the robot model already carries its tool."""
        import pybullet as p

        c = self.client
        weights = self._weights
        for b in self._parts():
            if b < 0:
                continue
            lift = weights.get(b)
            if lift is None:
                mass = p.getDynamicsInfo(b, -1, physicsClientId=c)[0]
                lift = weights[b] = [0.0, 0.0, mass * 9.81]
            pos, _ = p.getBasePositionAndOrientation(b, physicsClientId=c)
            p.applyExternalForce(b, -1, lift, pos, p.WORLD_FRAME, physicsClientId=c)

    def _attach(
        self, body: int, other: int, max_force: float | None = None, at: Vec3 | None = None
    ) -> int:
        """A fixed constraint from ``body`` to ``other`` at their current relative pose,
        applying at most ``max_force`` [N] per row (None: ``drive_force``); with ``at``,
        it holds ``other``'s origin at that point of ``body``'s frame [m] instead of
        where it lies."""
        import pybullet as p

        c = self.client
        pa, oa = p.getBasePositionAndOrientation(body, physicsClientId=c)
        pb, ob = p.getBasePositionAndOrientation(other, physicsClientId=c)
        ia, iao = p.invertTransform(pa, oa)
        rel_p, rel_o = p.multiplyTransforms(ia, iao, pb, ob)
        if at is not None:
            rel_p = at
        cons = p.createConstraint(
            body,
            -1,
            other,
            -1,
            p.JOINT_FIXED,
            [0, 0, 0],
            rel_p,
            [0, 0, 0],
            parentFrameOrientation=rel_o,
            physicsClientId=c,
        )
        limit = self.drive_force if max_force is None else max_force
        p.changeConstraint(cons, maxForce=limit, physicsClientId=c)
        return cons


@dataclass
class Grasper(Tool):
    """Pneumatic grasper jaws with the flexible hook (4.1, Fig. 4.6).

    Attributes:
        travel_time: jaw travel time, open to closed or back [s].
        reach: largest distance from the jaw centre to a thread capsule's axis that the
            closing jaws still catch [m].
        hook_travel_time: hook travel time, retracted to extended [s].
        hook_reach: how far the extended hook's shank passes the jaw centre [m]. At 1.5 mm
            the hook's crook (the mouth between shank and barb, 4.5 mm deep) spans the jaws
            from 3 mm behind the jaw centre to 2 mm beyond it, so a strand seated there
            lies over the grip (a crook beyond the jaws' end, 6 mm, held the strand
            distal of the held tail, and the loop slid off the tip without catching it).
        hook_release: the hook touches the thread only while it is extended beyond this
            fraction of its travel [-]: retracting, it lets the strand go after
            ``(1 - hook_release) * (hook_reach + 12 mm)`` of travel (0.8: 2.7 mm, the crook
            still over the jaws, where the solid jaws take the loop; dragged further, to
            half travel, the strand caught on the jaws' end and spiked to 9.7 N for 8 ms).
        hook_drive_force: the most force the hook's actuator applies along (and across)
            its stroke [N]; pushed harder, the hook gives way. With the tools' 50 N drive,
            the extending hook pressed the thread end the jaws hold (the tail-held start)
            at 50-59 N, shoving it (true tension 4.45 N), and the retracting hook dragged
            the strand over the jaws to 9.88 N true (full chain, seed 0; 0.40 N at 5 N).
            The hook now passes the held capsule (see :meth:`_set_hook_collision`).
        solid: the jaws, once they hold the thread, collide with the rest of it (not with
            the held capsule and its ``spare`` neighbours, which the closed jaws enclose,
            nor with the needle), so that a loop around them rests on them as on real
            jaws; otherwise the jaws never touch the thread.
        spare: capsules on each side of the held one that the solid jaws let through.
        jaw_friction: friction coefficient of the solid jaws against the thread [-].
        grip_limit: largest pull along the thread the closed jaws hold it with [N] (inf:
            any, the grasp of the scripted rigs that pull to a set tension). Pulled
            harder, the thread slides through them: the grasp passes at most this pull
            along the held capsule's axis (:meth:`grip_pull`), and once the capsule has
            moved ``slip_step`` along it they grip it again where it now is, on the
            jaws' line (or, when its neighbour has come between the jaws, that capsule;
            when the thread's end has left them, nothing). Each re-grip is a
            :class:`GripSlip` in ``slips``. A push across the thread (the hook grasper's
            grasp carried 5.9 N in algorithm 2, seed 3, with at most 0.55 N of tension)
            is held at any force, as real jaws do. The capsule the needle is swaged to
            is the exception: jaws on it hold the needle, as a needle holder does, with
            ``drive_force`` (the needle cannot slide through them; a thread sliding
            towards the needle stops there). PyBullet caps each of the constraint's
            world-axis rows at one force (``maxForce``); the cap stays ``drive_force``,
            as without a limit, until the pull passes half the limit, and is then
            ``grip_limit * max|f_i| / pull`` for the last step's force ``f``, so that
            rows held at the cap scale the force down to a pull of the limit (lowered at
            once, raised by at most 2 % a step). Measured (tests/test_tools.py, 3 N
            limit, 20 mm drawn through at 20 mm/s): at the limit along a world axis;
            up to 4 % over along a diagonal and 9 % (99th percentile 6 %) along a skew
            line, in the steps after a re-grip turns the force. The limit bounds the
            pull through the grasp only: thread wrapped round the jaws, the hook or the
            shaft is also held by contact friction.
        slip_step: how far the held capsule moves in the jaws, while they transmit
            ``grip_limit``, before they grip it anew [m]. Below the limit it sits off its
            grip by the solver's compliance only (about 0.05 mm/N) and is never re-gripped.
        slips: every slide of the thread through the jaws, in order.
    """

    travel_time: float = 0.1
    reach: float = 3e-3
    hook_travel_time: float = 0.3
    hook_reach: float = 1.5e-3
    hook_release: float = 0.8
    hook_drive_force: float = 5.0
    solid: bool = False
    spare: int = 2
    jaw_friction: float = 0.1
    grip_limit: float = math.inf
    slip_step: float = 0.25e-3
    slips: list[GripSlip] = field(default_factory=list)
    state: JawState = JawState.OPEN
    suture: Suture | None = None
    held_segment: int = -1
    hook_body: int = -1
    shaft_body: int = -1
    hook_extension: float = 0.0
    _hook_target: float = 0.0
    _timer: float = 0.0
    _grasp: int = -1
    _jaw_offset: Vec3 = (0.0, 0.0, 0.0)
    _jaw_orientation: Quat = _IDENTITY
    _hook_drive: int = -1
    _held: list[int] = field(default_factory=list)
    _solid_for: int = -1
    _hook_on: bool = False
    _hook_for: int = -1
    _anchor: FloatArray = field(default_factory=lambda: np.zeros(3))
    _gripped_at: FloatArray = field(default_factory=lambda: np.zeros(3))
    _lag: float | None = None
    _row_cap: float = math.inf
    _steps: int = 0

    @classmethod
    def create(
        cls,
        client: int,
        name: str = "grasper",
        position: Vec3 = (0.0, 0.0, 0.1),
        orientation: Quat = _IDENTITY,
        suture: Suture | None = None,
        hook: bool = True,
        shaft: float = 0.0,
        **kwargs: float,
    ) -> Grasper:
        """Add a grasper tip to the world, driven kinematically from ``position``.

        Args:
            client: PyBullet physics client id.
            name: tool name.
            position: initial jaw centre, world frame [m].
            orientation: initial orientation; the jaws point along the tip's +z.
            suture: the thread the jaws can grasp and the hook can catch.
            hook: whether to build the flexible hook.
            shaft: length of the instrument shaft behind the jaws [m] that the thread
                collides with (to wrap the thread around it, as in an instrument tie);
                0 for none.
            **kwargs: any of ``travel_time`` [s], ``reach`` [m], ``hook_travel_time`` [s],
                ``hook_reach`` [m], ``drive_force`` [N], ``grip_limit`` [N].
        """
        self = cls(client=client, name=name, suture=suture, **kwargs)  # type: ignore[arg-type]
        self._make_body((1.5e-3, 1.5e-3, 4e-3), 0.02, [0.7, 0.7, 0.7, 1.0])
        self._drive_to_world(position, orientation)
        if hook:
            self._make_hook()
        if shaft > 0:
            self._make_shaft(shaft)
        return self

    def _make_shaft(self, length: float) -> None:
        """A capsule of radius ``SHAFT_RADIUS`` along the tip's -z, from 3 mm behind the jaws."""
        import pybullet as p

        c = self.client
        col = p.createCollisionShape(
            p.GEOM_CAPSULE, radius=SHAFT_RADIUS, height=length, physicsClientId=c
        )
        vis = p.createVisualShape(
            p.GEOM_CAPSULE,
            radius=SHAFT_RADIUS,
            length=length,
            rgbaColor=[0.6, 0.6, 0.65, 1.0],
            physicsClientId=c,
        )
        offset = [0.0, 0.0, -(3e-3 + SHAFT_RADIUS + length / 2)]
        pos, orn = self.pose()
        at, _ = p.multiplyTransforms(pos, orn, offset, _IDENTITY)
        self.shaft_body = p.createMultiBody(0.01, col, vis, at, orn, physicsClientId=c)
        p.changeDynamics(self.shaft_body, -1, lateralFriction=0.2, physicsClientId=c)
        for other in (self.body, self.hook_body):
            if other >= 0:
                p.setCollisionFilterPair(self.shaft_body, other, -1, -1, 0, physicsClientId=c)
        cons = p.createConstraint(
            self.body,
            -1,
            self.shaft_body,
            -1,
            p.JOINT_FIXED,
            [0, 0, 0],
            offset,
            [0, 0, 0],
            physicsClientId=c,
        )
        p.changeConstraint(cons, maxForce=self.drive_force, physicsClientId=c)

    # ---- jaws ---------------------------------------------------------------------------

    def close(self) -> None:
        """Start closing the jaws (pneumatic: takes ``travel_time``)."""
        if self.state in (JawState.OPEN, JawState.OPENING):
            self.state = JawState.CLOSING
            self._timer = self.travel_time

    def open(self) -> None:
        """Start opening the jaws; whatever they hold is released at once."""
        import pybullet as p

        if self.state in (JawState.CLOSED, JawState.CLOSING):
            self.state = JawState.OPENING
            self._timer = self.travel_time
            if self._grasp >= 0:
                p.removeConstraint(self._grasp, physicsClientId=self.client)
                self._grasp = -1
                self.held_segment = -1

    @property
    def holding(self) -> bool:
        """Whether the jaws hold a thread capsule."""
        return self._grasp >= 0

    def grip(self, segment: int) -> None:
        """Close the jaws at once on thread capsule ``segment`` (a start state: the jaws
        already hold it).

        Raises:
            ToolError: no thread, or no such capsule.
        """
        if self.suture is None or not 0 <= segment < len(self.suture.bodies):
            raise ToolError(self.name, "grip the thread", f"no thread capsule {segment}")
        if self._grasp < 0:
            self._grip_capsule(segment)
        self.state = JawState.CLOSED
        self._timer = 0.0

    def _grip_capsule(
        self, segment: int, slide: FloatArray | None = None, lag: float = 0.0
    ) -> None:
        """Hold thread capsule ``segment`` where it lies, with at most ``grip_limit``.

        A re-grip after a slide (``slide``: its direction in the jaw frame) holds the
        capsule with the jaw centre on its axis, where the jaws pinch it, and ``lag``
        [m] short of where it lies along that axis, so that the constraint pulls on at
        once as the one it replaces did."""
        assert self.suture is not None
        capsule = self.suture.bodies[segment]
        if not self._limited(segment):
            self._grasp = self._attach(self.body, capsule)
            self.held_segment = segment
            return
        centre, axis = self._in_jaws(capsule)
        anchor = centre
        if slide is None:  # a fresh grip, as an unlimited one (a re-grip keeps the cap)
            self._row_cap = self.drive_force
        else:
            along = float(np.dot(centre, axis))
            back = math.copysign(lag, float(np.dot(slide, axis)))
            anchor = (along - back) * axis
        at = (float(anchor[0]), float(anchor[1]), float(anchor[2]))
        self._grasp = self._attach(self.body, capsule, self._row_cap, at)
        self._anchor = anchor
        self._gripped_at = centre
        self._lag = None
        self.held_segment = segment

    def _limited(self, segment: int) -> bool:
        """Whether the jaws' grip on capsule ``segment`` is limited: not with an infinite
        ``grip_limit``, and not on the capsule the needle is swaged to, which the jaws
        hold by the needle (a needle holder's grip; the needle cannot slide through)."""
        if math.isinf(self.grip_limit) or self.suture is None:
            return False
        return not (self.suture.needle_body >= 0 and segment == len(self.suture.bodies) - 1)

    def _in_jaws(self, body: int) -> tuple[FloatArray, FloatArray]:
        """Centre [m] and axis [-] of thread capsule ``body`` in the jaw frame."""
        import pybullet as p

        c = self.client
        pa, oa = p.getBasePositionAndOrientation(self.body, physicsClientId=c)
        pb, ob = p.getBasePositionAndOrientation(body, physicsClientId=c)
        ia, iao = p.invertTransform(pa, oa)
        rel, orn = p.multiplyTransforms(ia, iao, pb, ob)
        axis = np.asarray(p.getMatrixFromQuaternion(orn), dtype=float)[2::3]
        return np.asarray(rel, dtype=float), axis

    def slip(self) -> bool:
        """The held capsule slips out of the closed jaws (a fault): they hold nothing.

        Returns:
            Whether a capsule was held.
        """
        import pybullet as p

        if self._grasp < 0:
            return False
        p.removeConstraint(self._grasp, physicsClientId=self.client)
        self._grasp = -1
        self.held_segment = -1
        return True

    def grip_force(self) -> float:
        """Force the jaws transmit to the held capsule [N] (0 if none)."""
        import pybullet as p

        if self._grasp < 0:
            return 0.0
        f = p.getConstraintState(self._grasp, physicsClientId=self.client)
        return float(np.linalg.norm(f[:3]))

    def grip_pull(self) -> float:
        """Force the jaws transmit to the held capsule along its axis [N] (0 if none):
        the pull along the thread that ``grip_limit`` bounds (:meth:`grip_force` also
        counts pushes across the thread, which the jaws hold at any force)."""
        import pybullet as p

        if self._grasp < 0 or self.suture is None:
            return 0.0
        c = self.client
        f = np.asarray(p.getConstraintState(self._grasp, physicsClientId=c)[:3], dtype=float)
        _, orn = p.getBasePositionAndOrientation(
            self.suture.bodies[self.held_segment], physicsClientId=c
        )
        along = np.asarray(p.getMatrixFromQuaternion(orn), dtype=float)[2::3]
        return abs(float(np.dot(f, along)))

    def _limit_grip(self) -> None:
        """Keep the grasp's pull along the thread under ``grip_limit`` and let the thread
        slide through the jaws once it has moved ``slip_step`` in them (see
        ``grip_limit``)."""
        import pybullet as p

        assert self.suture is not None
        c = self.client
        f = np.asarray(p.getConstraintState(self._grasp, physicsClientId=c)[:3], dtype=float)
        held = self.held_segment
        at, axis = self._in_jaws(self.suture.bodies[held])
        _, jaw = p.getBasePositionAndOrientation(self.body, physicsClientId=c)
        along = np.asarray(p.getMatrixFromQuaternion(jaw), dtype=float).reshape(3, 3) @ axis
        pull = abs(float(np.dot(f, along)))
        rows = float(np.max(np.abs(f)))
        # held at the cap in the last step: the jaws' friction gave way
        saturated = rows >= _SATURATED * self._row_cap
        cap = self.drive_force
        if pull > 0.5 * self.grip_limit:
            # rows at this cap scale the force down until its pull is the limit
            cap = min(cap, self.grip_limit * rows / pull)
        # down at once, up slowly: a step's force below the cap may point elsewhere
        cap = min(cap, self._row_cap * _CAP_RISE)
        if cap != self._row_cap:
            p.changeConstraint(self._grasp, maxForce=cap, physicsClientId=c)
            self._row_cap = cap
        off = at - self._anchor
        moved = abs(float(np.dot(off, axis)))
        if saturated and self._lag is None:
            # how far off its grip the capsule sits once held at the cap: a re-grip keeps
            # it (the force halved for a few steps otherwise, a stick-slip)
            self._lag = min(moved, self.slip_step / 2)
        # below the cap the capsule only sits off its grip by the solver's compliance
        # (about 0.05 mm/N), which a re-grip would turn into a creep
        if not saturated or moved <= self.slip_step:
            return
        slid = abs(float(np.dot(at - self._gripped_at, axis)))
        to = self._between_jaws(held)
        p.removeConstraint(self._grasp, physicsClientId=c)
        self._grasp = -1
        self.held_segment = -1
        if to >= 0:
            self._grip_capsule(to, off, self._lag or 0.0)
        self.slips.append(GripSlip(self._steps * self.dt, held, to, slid, pull))

    def _between_jaws(self, held: int) -> int:
        """The capsule between the jaws now: the held one, or its neighbour once the jaw
        centre has passed the held one's end; -1 once it has passed the thread's end by
        more than ``reach`` (the thread has slid out of the jaws)."""
        assert self.suture is not None
        x = np.asarray(self.pose()[0])
        pts = self.suture.centerline()
        a, b = pts[held], pts[held + 1]
        u = b - a
        t = float(np.dot(x - a, u) / np.dot(u, u))
        if 0.0 <= t <= 1.0:
            return held
        nxt = held + 1 if t > 1.0 else held - 1
        if 0 <= nxt < len(self.suture.bodies):
            return nxt
        end = b if t > 1.0 else a
        return held if float(np.linalg.norm(x - end)) <= self.reach else -1

    @property
    def slid(self) -> float:
        """Total distance the thread has slid through the jaws [m] (sum of ``slips``)."""
        return float(sum(s.distance for s in self.slips))

    def _nearest_segment(self) -> int:
        if self.suture is None:
            return -1
        (x, _) = self.pose()
        pts = self.suture.centerline()
        a, b = pts[:-1], pts[1:]
        u = b - a
        t = np.clip(row_dot(np.asarray(x) - a, u) / row_dot(u, u), 0, 1)
        d = np.linalg.norm(a + t[:, None] * u - np.asarray(x), axis=1)
        i = int(np.argmin(d))
        return i if d[i] <= self.reach else -1

    def _parts(self) -> list[int]:
        return [self.body, self.hook_body, self.shaft_body]

    def step(self) -> None:
        """Advance jaw travel and hook motion by one physics step."""
        self._cancel_weight()
        if self.state in (JawState.CLOSING, JawState.OPENING):
            self._timer -= self.dt
            if self._timer <= 0.0:
                if self.state is JawState.CLOSING:
                    self.state = JawState.CLOSED
                    i = self._nearest_segment()
                    if i >= 0 and self.suture is not None:
                        self._grip_capsule(i)
                else:
                    self.state = JawState.OPEN
        self._steps += 1
        if self._grasp >= 0 and self._limited(self.held_segment):
            self._limit_grip()
        if self.solid and self.held_segment != self._solid_for:
            self._solidify()
        if self._hook_on and self.held_segment != self._hook_for:
            self._set_hook_collision(True)
        self._step_hook()

    def _solidify(self) -> None:
        """Solid jaws (see ``solid``): collide with the thread while they hold it, except
        with the held capsule, its ``spare`` neighbours and the needle; never with the
        other tool (the stitcher slides along them, 4.4.1 step 5)."""
        import pybullet as p

        c = self.client
        held = self.held_segment
        on = held >= 0 and self.suture is not None
        # the group mask stays 0 (no contact with the tools, robots or tissue); a pair
        # filter overrides it, so each thread capsule is turned on one by one
        if self.suture is not None:
            for i, body in enumerate(self.suture.bodies):
                enable = int(on and abs(i - held) > self.spare)
                p.setCollisionFilterPair(self.body, body, -1, -1, enable, physicsClientId=c)
            if self.suture.needle_body >= 0:
                p.setCollisionFilterPair(
                    self.body, self.suture.needle_body, -1, -1, 0, physicsClientId=c
                )
        if self.hook_body >= 0:
            p.setCollisionFilterPair(self.body, self.hook_body, -1, -1, 0, physicsClientId=c)
        p.changeDynamics(self.body, -1, lateralFriction=self.jaw_friction, physicsClientId=c)
        self._solid_for = held

    def set_thread(self, suture: Suture | None) -> None:
        """Take ``suture`` as the thread the jaws grasp and the hook catches (None: no
        thread): the thread was cut and another loaded (an interrupted suture).

        Whatever the jaws held of the old thread is let go (its grasp removed; the jaws
        stay as commanded), and the jaws' and hook's contacts are set for the new one.
        Call it before the old thread's bodies are removed.
        """
        import pybullet as p

        if self._grasp >= 0:
            p.removeConstraint(self._grasp, physicsClientId=self.client)
            self._grasp = -1
        self.held_segment = -1
        self._lag = None
        self.suture = suture
        if self.solid:  # the new capsules' contacts with the jaws
            self._solidify()
        if self.hook_body >= 0:
            self._set_hook_collision(self._hook_on)

    # ---- flexible hook (Fig. 4.6) -------------------------------------------------------

    def _make_hook(self) -> None:
        """A J-shaped hook of three capsules that slides along the jaw's +z."""
        import pybullet as p

        c = self.client
        r = 0.4e-3
        shapes = [p.GEOM_CAPSULE] * 3
        # Shank along z up to z = 1 mm, a bend across to x = HOOK_MOUTH and a barb pointing
        # back down to z = -4 mm: the mouth between shank and barb opens towards -z.
        w = HOOK_MOUTH
        positions = [[0.0, 0, -3e-3], [w / 2, 0, 0.5e-3], [w, 0, -1.75e-3]]
        q_shank = _IDENTITY
        q_bend = p.getQuaternionFromEuler([0, math.pi / 2, 0])
        orientations = [q_shank, q_bend, q_shank]
        lengths = [8e-3, w, 4.5e-3]
        col = p.createCollisionShapeArray(
            shapeTypes=shapes,
            radii=[r] * 3,
            lengths=lengths,
            collisionFramePositions=positions,
            collisionFrameOrientations=orientations,
            physicsClientId=c,
        )
        vis = p.createVisualShapeArray(
            shapeTypes=shapes,
            radii=[r] * 3,
            lengths=lengths,
            visualFramePositions=positions,
            visualFrameOrientations=orientations,
            rgbaColors=[[0.9, 0.6, 0.1, 1.0]] * 3,
            physicsClientId=c,
        )
        pos, orn = self.pose()
        self.hook_body = p.createMultiBody(0.005, col, vis, pos, orn, physicsClientId=c)
        p.changeDynamics(self.hook_body, -1, lateralFriction=0.6, physicsClientId=c)
        p.setCollisionFilterPair(self.hook_body, self.body, -1, -1, 0, physicsClientId=c)
        self._set_hook_collision(False)
        self._drive_hook()

    def _set_hook_collision(self, on: bool) -> None:
        """A retracted hook lies inside the shaft and touches nothing; an extended one
        touches the thread and the needle, except the capsule the jaws hold: that lies
        between the jaw faces, and the hook runs along the jaws' back. (Touching it, the
        hook extending over jaws that held the thread's end capsule stalled 2.4 mm short
        against its 5 N drive, its crook off the jaws, and no loop stayed on them.)"""
        import pybullet as p

        held = self.held_segment
        others = list(self.suture.bodies) if self.suture is not None else []
        for i, b in enumerate(others):
            p.setCollisionFilterPair(
                self.hook_body, b, -1, -1, int(on and i != held), physicsClientId=self.client
            )
        if self.suture is not None and self.suture.needle_body >= 0:
            p.setCollisionFilterPair(
                self.hook_body,
                self.suture.needle_body,
                -1,
                -1,
                int(on),
                physicsClientId=self.client,
            )
        self._hook_on, self._hook_for = on, held

    def hook_load(self) -> float:
        """Load on the hook's actuator along its stroke [N] (0 without a hook).

        The force the drive applies to keep the hook at its offset, along the jaws' +z
        (the stroke; the guide bears the rest). Positive when something pulls the hook
        out against the drive, as a thread does that the retracting hook drags. The
        hook's weight is compensated, so an unloaded hook reads 0.
        """
        import pybullet as p

        if self._hook_drive < 0:
            return 0.0
        c = self.client
        f = p.getConstraintState(self._hook_drive, physicsClientId=c)
        _, orn = p.getBasePositionAndOrientation(self.body, physicsClientId=c)
        z = p.getMatrixFromQuaternion(orn)[2::3]
        return float(f[0] * z[0] + f[1] * z[1] + f[2] * z[2])

    def _hook_offset(self) -> float:
        """Hook position along the jaw axis [m]: retracted behind the hinge or extended."""
        retracted = -12e-3
        return retracted + self.hook_extension * (self.hook_reach - retracted)

    def extend_hook(self) -> None:
        """Start extending the hook over the jaw hinge (takes ``hook_travel_time``)."""
        self._hook_target = 1.0

    def retract_hook(self) -> None:
        """Start retracting the hook behind the hinge (takes ``hook_travel_time``)."""
        self._hook_target = 0.0

    def _step_hook(self) -> None:

        if self.hook_body < 0 or self.hook_extension == self._hook_target:
            return
        rate = self.dt / self.hook_travel_time
        delta = self._hook_target - self.hook_extension
        before = self.hook_extension
        self.hook_extension += max(-rate, min(rate, delta))
        if (before < self.hook_release) != (self.hook_extension < self.hook_release):
            self._set_hook_collision(self.hook_extension >= self.hook_release)
        self._drive_hook()

    def _drive_hook(self) -> None:
        """(Re)build the fixed constraint holding the hook at its current offset on the jaws."""
        import pybullet as p

        c = self.client
        if self._hook_drive >= 0:
            p.removeConstraint(self._hook_drive, physicsClientId=c)
        self._hook_drive = p.createConstraint(
            self.body,
            -1,
            self.hook_body,
            -1,
            p.JOINT_FIXED,
            [0, 0, 0],
            [0, 0, self._hook_offset()],
            [0, 0, 0],
            physicsClientId=c,
        )
        p.changeConstraint(self._hook_drive, maxForce=self.hook_drive_force, physicsClientId=c)


@dataclass
class BentTipGrasper(Grasper):
    """Grasper whose jaws sit behind a universal joint (for algorithm 3).

    The shaft pose is commanded with :meth:`set_pose`; the jaw frame is the shaft frame
    turned by ``bend_x`` [rad] about the shaft's x (the joint's outer axis), then by
    ``bend_y`` [rad] about the turned y (its inner axis), i.e. Rx(bend_x) Ry(bend_y), and
    the jaw centre sits ``tip_length`` [m] along the bent z.

    Mounted on a robot and bent by more than ``collide_above`` [rad] about either axis,
    the bent link from the joint to the jaws (``link_body``) collides with the thread, so
    that a loop wrapped around the bent arm rests on it (4.4.3: the bend keeps the loop
    from slipping off), except with the capsule the jaws hold and ``spare`` capsules on
    each side of it, and with the needle; it then also meets the other robot's
    instrument (the scene filters the pad and their own robot). The jaws collide likewise,
    as a capsule of their half width (drawn as a box), so that a loop drawn along the
    bent arm slides over the link and the closed jaws and off their end onto what they
    hold (4.4.3 step 4), and cannot slip between the jaws and the held thread. Straight,
    link and jaws pass through the thread and grasp it by constraint (the solid jaws
    would shove a thread they close on).
    """

    bend_x: float = 0.0
    bend_y: float = 0.0
    tip_length: float = 12e-3
    collide_above: float = 0.5
    link_body: int = -1
    _link_drive: int = -1
    _shaft: tuple[Vec3, Quat] = ((0.0, 0.0, 0.1), _IDENTITY)
    _passed: dict[int, list[int]] = field(default_factory=dict)
    _clearing: dict[int, set[int]] = field(default_factory=dict)
    _filtered_for: int = -3
    _collides: tuple[bool, bool] = (False, False)

    def _make_body(self, half_extents: Vec3, mass: float, rgba: list[float]) -> None:
        """The jaws (about the jaw centre) and, as a second body fixed to them, the
        bent link behind them: a capsule of the jaws' half width from the universal joint
        (``tip_length`` behind the jaw centre) to the jaws, so a loop cannot slip between
        the shaft and the jaws."""
        import pybullet as p

        c = self.client
        # The jaws collide as a capsule of their half width (their box is only drawn),
        # so that a loop slides smoothly from the bent link over the closed jaws.
        radius = min(half_extents[0], half_extents[1])
        jaw_col = p.createCollisionShape(
            p.GEOM_CAPSULE, radius=radius, height=2 * (half_extents[2] - radius), physicsClientId=c
        )
        jaw_vis = p.createVisualShape(
            p.GEOM_BOX, halfExtents=list(half_extents), rgbaColor=rgba, physicsClientId=c
        )
        self.body = p.createMultiBody(mass, jaw_col, jaw_vis, [0, 0, 0], physicsClientId=c)
        p.setCollisionFilterGroupMask(self.body, -1, 0, 0, physicsClientId=c)
        link = self.tip_length - half_extents[2]
        frame = [0.0, 0.0, -(half_extents[2] + link / 2)]
        col = p.createCollisionShape(
            p.GEOM_CAPSULE,
            radius=radius,
            height=link,
            collisionFramePosition=frame,
            physicsClientId=c,
        )
        vis = p.createVisualShape(
            p.GEOM_CAPSULE,
            radius=radius,
            length=link,
            visualFramePosition=frame,
            rgbaColor=rgba,
            physicsClientId=c,
        )
        self.link_body = p.createMultiBody(mass / 4, col, vis, [0, 0, 0], physicsClientId=c)
        p.setCollisionFilterGroupMask(self.link_body, -1, 0, 0, physicsClientId=c)
        p.setCollisionFilterPair(self.body, self.link_body, -1, -1, 0, physicsClientId=c)
        self._link_drive = p.createConstraint(
            self.body,
            -1,
            self.link_body,
            -1,
            p.JOINT_FIXED,
            [0, 0, 0],
            [0, 0, 0],
            [0, 0, 0],
            physicsClientId=c,
        )
        p.changeConstraint(self._link_drive, maxForce=self.drive_force, physicsClientId=c)

    def _parts(self) -> list[int]:
        return [*super()._parts(), self.link_body]

    def mount(self, robot_body: int, link: int, offset: Vec3 = (0.0, 0.0, 0.0)) -> None:
        """Mount the jaws (see :meth:`Tool.mount`) and bring the bent link with them."""
        import pybullet as p

        super().mount(robot_body, link, offset)
        pos, orn = self.pose()
        p.resetBasePositionAndOrientation(self.link_body, pos, orn, physicsClientId=self.client)

    def _update_collision(self) -> None:
        """Link and jaws collide when mounted and bent beyond ``collide_above``; never
        with the needle nor the held capsules."""
        import pybullet as p

        bent = self._mounted and max(abs(self.bend_x), abs(self.bend_y)) > self.collide_above
        want = (bent, bent)
        if want == self._collides:
            return
        c = self.client
        for body, on, was in zip((self.link_body, self.body), want, self._collides, strict=True):
            if on == was:
                continue
            group, mask = (1, 0x7FFF) if on else (0, 0)
            p.setCollisionFilterGroupMask(body, -1, group, mask, physicsClientId=c)
            if on and self.suture is not None and self.suture.needle_body >= 0:
                p.setCollisionFilterPair(
                    body, self.suture.needle_body, -1, -1, 0, physicsClientId=c
                )
        self._collides = want
        self._filtered_for = -3
        self._filter_thread()

    def _filter_thread(self) -> None:
        """Per thread capsule and part, a pair filter: collide when the part collides,
        except with the held capsule and its ``spare`` neighbours (a pair filter overrides
        the group mask, so a passing part gets every pair off).

        A pair is turned on only once the capsule is clear of the part: until then it
        waits in ``_clearing`` (see :meth:`_clear_passed`). A capsule the jaws held lies
        inside them; turned on there at the release, the contact's penetration recovery
        threw it out in one step, and the thread's joints read 12.1 N for one step (a
        perturbed run of algorithm 3, the jaws opening on the tail)."""
        import pybullet as p

        if self.suture is None:
            return
        held = self.held_segment if any(self._collides) else -2
        if held == self._filtered_for and self._passed:
            return
        bodies = self.suture.bodies
        c = self.client
        for part, on in zip((self.link_body, self.body), self._collides, strict=True):
            passed = self._passed.setdefault(part, [])
            if len(passed) != len(bodies):
                passed[:] = [-1] * len(bodies)
            clearing = self._clearing.setdefault(part, set())
            for i, body in enumerate(bodies):
                near = held >= 0 and abs(i - held) <= self.spare
                enable = int(on and not near)
                if not enable:
                    clearing.discard(i)
                if passed[i] == enable or i in clearing:
                    continue
                if enable and p.getClosestPoints(part, body, 0.0, physicsClientId=c):
                    # inside the part (or touching it): passable until clear
                    clearing.add(i)
                    if passed[i] != 0:
                        p.setCollisionFilterPair(part, body, -1, -1, 0, physicsClientId=c)
                        passed[i] = 0
                    continue
                p.setCollisionFilterPair(part, body, -1, -1, enable, physicsClientId=c)
                passed[i] = enable
        self._filtered_for = held

    def _clear_passed(self) -> None:
        """Turn on each waiting pair (``_clearing``) whose capsule is now clear of the part
        (no closest point at or under zero distance)."""
        import pybullet as p

        assert self.suture is not None
        c = self.client
        bodies = self.suture.bodies
        for part, clearing in self._clearing.items():
            for i in sorted(clearing):
                if not p.getClosestPoints(part, bodies[i], 0.0, physicsClientId=c):
                    p.setCollisionFilterPair(part, bodies[i], -1, -1, 1, physicsClientId=c)
                    self._passed[part][i] = 1
                    clearing.discard(i)

    def step(self) -> None:
        """Advance the jaws (as :meth:`Grasper.step`) and keep the held capsules passable."""
        super().step()
        self._update_collision()
        if any(self._collides) and self.held_segment != self._filtered_for:
            self._filter_thread()
        if self.suture is not None and any(self._clearing.values()):
            self._clear_passed()

    def set_thread(self, suture: Suture | None) -> None:
        """Take ``suture`` as the thread (see :meth:`Grasper.set_thread`), and give the
        bent link and jaws its pair filters: each capsule collides with a part that
        collides (once clear of it, as at the start), the new needle never."""
        import pybullet as p

        super().set_thread(suture)
        self._passed = {}
        self._clearing = {}
        self._filtered_for = -3
        if suture is None:
            return
        if suture.needle_body >= 0:
            for body, on in zip((self.link_body, self.body), self._collides, strict=True):
                if on:
                    p.setCollisionFilterPair(
                        body, suture.needle_body, -1, -1, 0, physicsClientId=self.client
                    )
        self._filter_thread()

    def set_bend(self, bend_x: float, bend_y: float) -> None:
        """Command the universal joint's two angles [rad].

        Mounted on a robot link, the universal joint sits ``tip_length`` behind the link
        (the robot's tool tip, where the unbent jaws are) and the jaws turn about it.
        """
        self.bend_x, self.bend_y = bend_x, bend_y
        if self._mounted:
            self._bend_mounted()
        else:
            self.set_pose(*self._shaft)
        self._update_collision()

    def _bend(self) -> tuple[Vec3, Quat]:
        """The jaw frame in the universal joint's frame: Rx(bend_x) Ry(bend_y), then
        ``tip_length`` along the bent z."""
        import pybullet as p

        outer = p.getQuaternionFromEuler([self.bend_x, 0.0, 0.0])
        inner = p.getQuaternionFromEuler([0.0, self.bend_y, 0.0])
        _, bend = p.multiplyTransforms([0, 0, 0], outer, [0, 0, 0], inner)
        pos, orn = p.multiplyTransforms([0, 0, 0], bend, [0, 0, self.tip_length], _IDENTITY)
        return tuple(pos), tuple(orn)  # type: ignore[return-value]

    def _bend_mounted(self) -> None:
        """Re-pose the jaws on the link: J = T(-tip_length) B; the drive's child frame is
        J^-1 (the fixed drive makes link (x) parent frame = body (x) child frame)."""
        import pybullet as p

        bp, bo = self._bend()
        jp, jo = p.multiplyTransforms([0, 0, -self.tip_length], _IDENTITY, bp, bo)
        ip, io = p.invertTransform(jp, jo)
        p.changeConstraint(
            self.drive,
            jointChildPivot=list(ip),
            jointChildFrameOrientation=list(io),
            maxForce=self.drive_force,
            physicsClientId=self.client,
        )

    def set_pose(self, position: Vec3, orientation: Quat = _IDENTITY) -> None:
        """Command the shaft end (the universal joint) pose; the jaws follow the bend.

        Args:
            position: universal joint position, world frame [m].
            orientation: shaft orientation, quaternion (x, y, z, w).
        """
        import pybullet as p

        self._shaft = (position, orientation)
        # Universal joint: the outer axis x is fixed in the shaft, the inner axis y turns
        # with it, so the jaw frame is Rx(bend_x) Ry(bend_y) in the shaft frame.
        bp, bo = self._bend()
        pos, orn = p.multiplyTransforms(position, orientation, bp, bo, physicsClientId=self.client)
        super().set_pose(tuple(pos), tuple(orn))  # type: ignore[arg-type]


@dataclass
class Stitcher(Tool):
    """EndoStitch-like stitcher: two jaws, the needle locked in one (4.1, Fig. 4.3).

    The jaws open apart along the tip's x and close together, each taking ``travel_time``;
    with the jaws closed, :meth:`pass_needle` hands the needle to the other jaw (after
    ``travel_time``), which then carries it when the jaws open.

    The needle lock has no grip limit (it holds with ``drive_force``), unlike a grasper's
    jaws on the thread: the stitcher latches the needle in its jaw, and a needle, unlike a
    thread, cannot slide through the jaw and be held further along; pulled out, it would
    be lost, which is the fault :meth:`drop_needle` already models. A pull through the
    needle is bounded by the monitor's layers, not by the jaws.

    The hand-over's drive is weaker than the jaws': it pushes the needle across with at
    most ``needle_drive_force``. A thread that holds the needle back harder (caught on a
    jaw or a tool, with no slack left) stops it short; the hand-over then fails, the
    giving jaw keeps the needle where it stopped, and the receiving jaw never reads
    closed on it (a :class:`NeedleStall` is recorded). With the full drive, such a
    hand-over stretched the thread to 13.8 N inside the jaws, where no base sensor sees it.

    The thread leaves the needle inside the jaw that holds it (the needle's origin, where
    the thread is fixed, lies in the jaw), so its last capsules never touch the jaws
    (:meth:`collide_with`). They may therefore leave the jaw through its outer face, away
    from the gap, where a real jaw would have turned them back. A hand-over then dragged
    them back through that jaw until the first capsule that does collide caught on its
    outer face and held the needle back at the drive's force (a model artefact: the main
    job's seeds 0 and 9 stalled so, capsule 37 of 40 on the giving jaw at 5.3 N). So while
    it hands the needle over, the giving jaw also lets through the ``handover_carry``
    capsules next to those, and each collides with it again once it is clear of it.

    Those last capsules did still collide with the rest of their thread. Where the thread
    doubled back at the needle, the hand-over then pressed a capsule lying outside the
    jaws against the receiving jaw's face with the one at the needle, and the needle
    stopped short at the drive's force while the thread's joints carried 0.35 N (a model
    artefact: the main job's seed 11, capsule 36 of 40 pinned by capsule 39 at 5-6 N).
    With ``handover_pass_thread``, while a hand-over carries them, the capsules inside the
    jaw pass through the rest of their thread too, and collide with each capsule again
    once clear of it. It is off by default: it changes the contacts of every hand-over, so
    it re-deals every run on the thread from the first one on (the main job's seed 12 still
    ties its square; seed 11 then ends ``succeeded`` with one trefoil, its mirrored throw's
    check fooled), and the bundled procedures' layouts and checks were measured without it.

    Attributes:
        gap: distance between the closed jaws along the tip's x [m].
        open_width: how far each jaw moves out when opening [m].
        travel_time: jaw travel time and needle hand-over time [s].
        needle_holder: index (0: the -x jaw, 1: the +x jaw) of the jaw holding the needle.
        opening: jaw opening, 0 closed to 1 open [-].
        needle_drive_force: the most force the hand-over's drive applies to the needle [N].
        handover_carry: how many thread capsules, next to the ones that never touch the
            jaws, the giving jaw lets through during a hand-over [-].
        handover_pass_thread: whether, during a hand-over, the capsules inside the jaw
            pass through the rest of their thread (off by default; see above).
        stalls: the hand-overs that stopped short, in order.
    """

    HANDOVER_TOLERANCE: ClassVar[float] = 1e-3
    """How far from the receiving jaw a needle may end its hand-over and still be taken
    [m]."""
    CLEAR_OVERLAP: ClassVar[float] = 2e-4
    """A let-through capsule overlapping its jaw by less than this counts as clear of it
    (one resting on the jaw's face) and collides with it again [m]."""

    gap: float = 8e-3
    open_width: float = 4e-3
    travel_time: float = 0.2
    needle_holder: int = 0
    opening: float = 0.0
    needle_drive_force: float = 5.0
    handover_carry: int = 3
    handover_pass_thread: bool = False
    stalls: list[NeedleStall] = field(default_factory=list)
    stalled: bool = False
    """The last hand-over stopped short (until the jaws open or another is asked for)."""
    _steps: int = 0
    jaws: list[int] = field(default_factory=list)
    needle_body: int = -1
    _target: float = 0.0
    _jaw_drives: list[int] = field(default_factory=list)
    _lock: int = -1
    _timer: float = -1.0
    _pending: bool = False
    _sweep_from: FloatArray = field(default_factory=lambda: np.zeros(3))
    _sweep_orientation: Quat = _IDENTITY
    _carried: list[int] = field(default_factory=list)
    """The thread's capsules a giving jaw lets through (see the class docstring)."""
    _in_jaw: list[int] = field(default_factory=list)
    """The thread's capsules at the needle, inside its jaw (the jaws never touch them)."""
    _thread: list[int] = field(default_factory=list)
    """All the thread's capsules, tail to needle."""
    _let_through: dict[int, set[int]] = field(default_factory=dict)
    """Per jaw body (or in-jaw capsule), the capsules it does not collide with yet."""

    @classmethod
    def create(
        cls,
        client: int,
        name: str = "stitcher",
        position: Vec3 = (0.0, 0.0, 0.1),
        orientation: Quat = _IDENTITY,
        needle_body: int = -1,
        place_needle: bool = True,
        **kwargs: float,
    ) -> Stitcher:
        """Add a stitcher to the world, jaws closed, the needle locked in jaw 0.

        Args:
            client: PyBullet physics client id.
            name: tool name.
            position: tip centre (between the jaws), world frame [m].
            orientation: tip orientation; the jaws sit at ±``gap``/2 along its x.
            needle_body: body id of the needle (``Suture.needle_body``); -1 for none.
            place_needle: move the needle into jaw 0's pose before locking it there; False
                locks it where it lies (a thread laid to end at jaw 0 already put it there).
            **kwargs: ``gap`` [m], ``open_width`` [m], ``travel_time`` [s],
                ``drive_force`` [N].
        """
        import pybullet as p

        self = cls(client=client, name=name, needle_body=needle_body, **kwargs)  # type: ignore[arg-type]
        self._make_body((self.gap / 2 + 1e-3, 1e-3, 1e-3), 0.02, [0.5, 0.5, 0.55, 1.0])
        self._drive_to_world(position, orientation)
        half = [1e-3, 1.5e-3, 3e-3]
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client)
        vis = p.createVisualShape(
            p.GEOM_BOX, halfExtents=half, rgbaColor=[0.4, 0.4, 0.45, 1.0], physicsClientId=client
        )
        for side in (-1, 1):
            offset = [side * self.gap / 2, 0.0, 3e-3]
            pos, orn = p.multiplyTransforms(position, orientation, offset, _IDENTITY)
            jaw = p.createMultiBody(0.005, col, vis, pos, orn, physicsClientId=client)
            p.setCollisionFilterGroupMask(jaw, -1, 0, 0, physicsClientId=client)
            self.jaws.append(jaw)
            self._jaw_drives.append(-1)
        self._drive_jaws()
        if needle_body >= 0:
            if place_needle:
                jaw_pos, jaw_orn = p.getBasePositionAndOrientation(
                    self.jaws[0], physicsClientId=client
                )
                p.resetBasePositionAndOrientation(
                    needle_body, jaw_pos, jaw_orn, physicsClientId=client
                )
            self._lock = self._attach(self.jaws[0], needle_body)
        return self

    def _parts(self) -> list[int]:
        return [self.body, *self.jaws]

    def collide_with(self, suture: Suture, spare: int = 2) -> None:
        """Let the jaws touch ``suture`` (a thread can rest on an open jaw, 4.4.1), except
        its needle and its last ``spare`` capsules (at the needle, in a jaw).

        The jaws then collide with whatever else collides by default (other tools,
        robots); the caller filters what they must pass through (the tissue pad, the
        robot carrying them).
        """
        import pybullet as p

        c = self.client
        n = len(suture.bodies)
        for jaw in self.jaws:
            p.setCollisionFilterGroupMask(jaw, -1, 1, 0x7FFF, physicsClientId=c)
            others = [*suture.bodies[n - spare :], suture.needle_body]
            for body in (b for b in others if b >= 0):
                p.setCollisionFilterPair(jaw, body, -1, -1, 0, physicsClientId=c)
        self._carried = list(suture.bodies[max(n - spare - self.handover_carry, 0) : n - spare])
        self._in_jaw = list(suture.bodies[max(n - spare, 0) :])
        self._thread = list(suture.bodies)

    def set_thread(self, suture: Suture | None) -> None:
        """Take ``suture``'s needle into the jaw that holds the needle (``needle_holder``),
        where it lies, and let the jaws touch the new thread (:meth:`collide_with`);
        None: the jaw holds no needle. The old thread was cut (an interrupted suture): its
        needle's lock and any hand-over under way end. Call it before the old thread's
        bodies are removed.
        """
        import pybullet as p

        c = self.client
        if self._lock >= 0:
            p.removeConstraint(self._lock, physicsClientId=c)
            self._lock = -1
        self._timer = -1.0
        self._pending = False
        self.stalled = False
        self._let_through = {}
        self._carried, self._in_jaw, self._thread = [], [], []
        self.needle_body = -1
        if suture is None:
            return
        self.needle_body = suture.needle_body
        self.collide_with(suture)
        if self.needle_body >= 0:
            self._lock = self._attach(self.jaws[self.needle_holder], self.needle_body)

    def needle_jaw(self) -> tuple[Vec3, Vec3]:
        """Where a needle in the holding jaw has its swaged end, and the direction the
        thread runs into that jaw (outwards from the gap towards it), world frame
        ([m], unit vector)."""
        import pybullet as p

        pos, orn = self.pose()
        at, _ = p.multiplyTransforms(
            pos, orn, [float(v) for v in self._jaw_offset(self.needle_holder)], _IDENTITY
        )
        x = p.getMatrixFromQuaternion(orn)[0::3]
        sign = 1.0 if self.needle_holder == 0 else -1.0
        axis = (sign * x[0], sign * x[1], sign * x[2])
        return (float(at[0]), float(at[1]), float(at[2])), axis

    def _let_thread_pass(self) -> None:
        """The capsules inside the jaw with the needle stop colliding with the rest of
        their thread (all but their neighbours, which never collide) while a hand-over
        carries them: on the model's terms they lie inside the jaw, so they cannot press
        thread lying outside it against the receiving jaw."""
        import pybullet as p

        index = {b: i for i, b in enumerate(self._thread)}
        for a in self._in_jaw:
            held = self._let_through.setdefault(a, set())
            for b in self._thread:
                if abs(index[a] - index[b]) > 1 and b not in self._in_jaw and b not in held:
                    p.setCollisionFilterPair(a, b, -1, -1, 0, physicsClientId=self.client)
                    held.add(b)

    def _let_thread_through(self, jaw: int) -> None:
        """The giving ``jaw`` stops colliding with the carried capsules (a hand-over)."""
        import pybullet as p

        held = self._let_through.setdefault(jaw, set())
        for body in self._carried:
            if body not in held:
                p.setCollisionFilterPair(jaw, body, -1, -1, 0, physicsClientId=self.client)
                held.add(body)

    def _restore_thread_contact(self) -> None:
        """Each let-through capsule clear of its jaw, or of the in-jaw capsule it passed
        (``CLEAR_OVERLAP``), collides with it again."""
        import pybullet as p

        c = self.client
        for jaw, held in self._let_through.items():
            for body in sorted(held):
                near = p.getClosestPoints(jaw, body, 0.0, physicsClientId=c)
                if all(pt[8] > -self.CLEAR_OVERLAP for pt in near):
                    p.setCollisionFilterPair(jaw, body, -1, -1, 1, physicsClientId=c)
                    held.discard(body)
        self._let_through = {jaw: held for jaw, held in self._let_through.items() if held}

    def _drive_jaws(self) -> None:
        """(Re)build the constraints holding the jaws at the current opening."""
        import pybullet as p

        c = self.client
        for k, side in enumerate((-1, 1)):
            if self._jaw_drives[k] >= 0:
                p.removeConstraint(self._jaw_drives[k], physicsClientId=c)
            x = side * (self.gap / 2 + self.opening * self.open_width)
            cons = p.createConstraint(
                self.body,
                -1,
                self.jaws[k],
                -1,
                p.JOINT_FIXED,
                [0, 0, 0],
                [x, 0.0, 3e-3],
                [0, 0, 0],
                physicsClientId=c,
            )
            p.changeConstraint(cons, maxForce=self.drive_force, physicsClientId=c)
            self._jaw_drives[k] = cons

    def open_jaws(self) -> None:
        """Start opening the jaws (takes ``travel_time``); a hand-over not yet started is
        called off."""
        self._target = 1.0
        self._pending = False
        self.stalled = False

    def close_jaws(self) -> None:
        """Start closing the jaws (takes ``travel_time``)."""
        self._target = 0.0

    @property
    def passing(self) -> bool:
        """Whether a needle hand-over is under way (or asked for and waiting for the jaws
        to close)."""
        return self._timer >= 0.0 or self._pending

    def request_pass(self) -> None:
        """Hand the needle over as soon as the jaws are closed (now if they are)."""
        if self.needle_body >= 0 and self._lock >= 0 and not self.passing:
            self._pending = True
            self.stalled = False

    @property
    def holds_needle(self) -> bool:
        """Whether a jaw (or a hand-over under way) holds the needle."""
        return self._lock >= 0

    def drop_needle(self) -> bool:
        """The needle slips out of the jaw that holds it (a fault); a hand-over under way
        stops.

        Returns:
            Whether the needle was held.
        """
        import pybullet as p

        if self._lock < 0:
            return False
        p.removeConstraint(self._lock, physicsClientId=self.client)
        self._lock = -1
        self._timer = -1.0
        self._pending = False
        return True

    def pass_needle(self) -> None:
        """Start handing the needle to the other jaw (takes ``travel_time``).

        Raises:
            ToolError: there is no needle, the jaws are not closed, or a hand-over is
                already under way.
        """
        if self.needle_body < 0 or self._lock < 0:
            raise ToolError(self.name, "pass the needle", "it holds no needle")
        if self.opening > 0.0 or self._target > 0.0:
            raise ToolError(self.name, "pass the needle", "the jaws are not closed")
        if self._timer >= 0.0:
            raise ToolError(self.name, "pass the needle", "a hand-over is under way")
        self._pending = False
        self._timer = self.travel_time

    def _jaw_offset(self, k: int) -> FloatArray:
        """Jaw ``k``'s position in the tip frame at the current opening [m]."""
        side = (-1, 1)[k]
        return np.array([side * (self.gap / 2 + self.opening * self.open_width), 0.0, 3e-3])

    def _needle_in_tip(self) -> tuple[Any, Any]:
        """The needle's pose in the tip body's frame (position [m], quaternion)."""
        import pybullet as p

        c = self.client
        pb, ob = p.getBasePositionAndOrientation(self.body, physicsClientId=c)
        pn, on = p.getBasePositionAndOrientation(self.needle_body, physicsClientId=c)
        inv_p, inv_o = p.invertTransform(pb, ob)
        rel_p, rel_o = p.multiplyTransforms(inv_p, inv_o, pn, on)
        return rel_p, rel_o

    def _start_sweep(self) -> None:
        """Hand the needle from its jaw to the tip body's sweep constraint (same pose)."""
        import pybullet as p

        c = self.client
        rel_p, rel_o = self._needle_in_tip()
        p.removeConstraint(self._lock, physicsClientId=c)
        self._let_thread_through(self.jaws[self.needle_holder])
        if self.handover_pass_thread:
            self._let_thread_pass()
        # Parent: the needle at its origin; child: the tip body at the needle's pose in the
        # tip frame, so that changeConstraint's child pivot moves the needle in that frame.
        self._sweep_from = np.asarray(rel_p, dtype=float) - self._jaw_offset(self.needle_holder)
        self._sweep_orientation = tuple(rel_o)
        self._lock = p.createConstraint(
            self.needle_body,
            -1,
            self.body,
            -1,
            p.JOINT_FIXED,
            [0, 0, 0],
            [0, 0, 0],
            list(rel_p),
            childFrameOrientation=list(rel_o),
            physicsClientId=c,
        )
        p.changeConstraint(self._lock, maxForce=self.needle_drive_force, physicsClientId=c)

    def _sweep_target(self, fraction: float) -> FloatArray:
        """Where the sweep holds the needle's origin, ``fraction`` of the way across, in the
        tip body's frame [m]."""
        a = self._jaw_offset(self.needle_holder)
        b = self._jaw_offset(1 - self.needle_holder)
        return a + (b - a) * min(max(fraction, 0.0), 1.0) + self._sweep_from

    def _shortfall(self) -> float:
        """How far the needle's origin is from the sweep's end point, in the tip frame [m]."""
        rel, _ = self._needle_in_tip()
        return float(np.linalg.norm(np.asarray(rel) - self._sweep_target(1.0)))

    def _sweep(self, fraction: float) -> None:
        """Move the needle ``fraction`` of the way from the giving to the receiving jaw."""
        import pybullet as p

        at = self._sweep_target(fraction)
        p.changeConstraint(
            self._lock,
            jointChildPivot=at.tolist(),
            jointChildFrameOrientation=list(self._sweep_orientation),
            maxForce=self.needle_drive_force,
            physicsClientId=self.client,
        )

    def step(self) -> None:
        """Advance jaw travel and a needle hand-over by one physics step.

        During a hand-over the needle (and with it the thread's end) sweeps across the
        gap from the giving jaw to the receiving one over ``travel_time``, keeping its
        pose relative to the jaw; the receiving jaw then locks it.
        """
        import pybullet as p

        self._steps += 1
        self._cancel_weight()
        if self.opening != self._target:
            rate = self.dt / self.travel_time
            delta = self._target - self.opening
            self.opening += max(-rate, min(rate, delta))
            self._drive_jaws()
        if self._pending and self.opening == 0.0 and self._target == 0.0:
            self.pass_needle()
        if self._timer < 0.0:
            if self._let_through:
                self._restore_thread_contact()
            return
        if self._timer >= self.travel_time - 1e-12:
            self._start_sweep()
        self._timer -= self.dt
        self._sweep(1.0 - max(self._timer, 0.0) / self.travel_time)
        if self._timer < 0.0:
            self._timer = -1.0
            short = self._shortfall()
            p.removeConstraint(self._lock, physicsClientId=self.client)
            if short > self.HANDOVER_TOLERANCE:  # stopped short: the giving jaw keeps it
                self.stalls.append(NeedleStall(self._steps * self.dt, short, self.needle_holder))
                self.stalled = True
            else:
                self.needle_holder = 1 - self.needle_holder
            self._lock = self._attach(self.jaws[self.needle_holder], self.needle_body)
