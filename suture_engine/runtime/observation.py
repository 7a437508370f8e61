"""What skills receive each tick, and what they return.

Skills see only what the real EndoBot measures (DESIGN section 3): encoder
joint positions, joint velocities *estimated* from them (washout filter,
thesis (3.78-3.79), (5.50)), the base force/torque sensor wrench, tool states,
the simulation time and the geometry the scene declares. They never see the
simulator's ground truth of the suture; that goes to the trace only, through
:meth:`backends.base.Backend.ground_truth`.

Backends return a :class:`Measurement` (raw sensor values, no velocity);
the interpreter turns it into an :class:`Observation` by running the washout
filter (:class:`suture_engine.control.filters.WashoutFilter`) on the encoder
positions.

Skills return a :class:`Command`: per robot a :class:`RobotCommand` holding a
joint position setpoint, a joint velocity setpoint or joint torques, and a
tool command. The interpreter's controller turns setpoints into torques
(chapter 5 laws) before the backend applies them.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "BACKEND_EVENTS",
    "N_JOINTS",
    "BackendEvent",
    "Command",
    "CommandMode",
    "Measurement",
    "Observation",
    "RobotCommand",
    "RobotMeasurement",
    "RobotObservation",
    "SceneGeometry",
    "SkillStatus",
    "StepResult",
    "ToolCommand",
    "ToolState",
    "scene_geometry",
]

N_JOINTS = 4
"""Joints of one EndoBot: yaw about x, pitch about y, roll about z, insertion along z."""

FloatArray = NDArray[np.float64]


def _frozen_array(values: object, size: int | None = None) -> FloatArray:
    if type(values) is np.ndarray and values.dtype == np.float64 and values.ndim == 1:
        arr = values.copy()  # the common case, without the generic conversion
    else:
        arr = np.array(values, dtype=np.float64, copy=True).reshape(-1)
    if size is not None and arr.shape != (size,):
        raise ValueError(f"expected {size} values, got {arr.shape[0]}")
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True)
class ToolState:
    """The measured state of one robot's tool.

    Attributes:
        kind: tool type ("grasper", "hook-grasper", "bent-tip-grasper", "stitcher").
        jaw_closed: a grasper's jaw valve: the EndoBot's tools are pneumatic with no
            jaw sensor (thesis 4.4), so it turns true on the tick the jaw is commanded shut,
            and the jaws reach the thread one travel time later (0.1 s on the simulated
            grasper); a skill that acts on a grasp waits that travel (``grasp``'s
            ``dwell``). A stitcher's: its first jaw holds the needle, both jaws shut.
        jaw2_closed: a stitcher's second jaw holds the needle, both jaws shut (False for
            other tools).
        hook_extension: flexible-hook extension [m] (0 when retracted or absent).
        bend: the bent-tip grasper's universal joint angles from its encoders, about the
            shaft's x then about the turned y [rad, rad] ((0, 0): straight or absent).
        hook_load: the flexible hook's actuator load along its stroke [N], positive when
            something pulls the hook out against a retraction (a dragged thread); 0 when
            the tool has no hook or the backend does not measure it.
    """

    kind: str = "grasper"
    jaw_closed: bool = False
    jaw2_closed: bool = False
    hook_extension: float = 0.0
    bend: tuple[float, float] = (0.0, 0.0)
    hook_load: float = 0.0


@dataclass(frozen=True)
class RobotMeasurement:
    """Raw sensor values of one EndoBot, as a backend measures them.

    Attributes:
        q: encoder joint positions [rad, rad, rad, m].
        base_wrench: base force/torque sensor (Fx, Fy, Fz [N], Mx, My, Mz [N*m]).
        tool: the tool's measured state.
        fault: True when a sensor reported a dropout this tick (held value).
    """

    q: FloatArray
    base_wrench: FloatArray
    tool: ToolState = field(default_factory=ToolState)
    fault: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "q", _frozen_array(self.q, N_JOINTS))
        object.__setattr__(self, "base_wrench", _frozen_array(self.base_wrench, 6))

    @classmethod
    def trusted(
        cls, q: FloatArray, base_wrench: FloatArray, tool: ToolState, fault: bool = False
    ) -> RobotMeasurement:
        """A measurement from read-only float64 arrays of shapes (4,) and (6,) that the
        caller never changes (no copy, no checks): a backend's per-tick fast path."""
        m = object.__new__(cls)
        # The instance dict filled directly: the fields' values, as __init__ would set them.
        d = m.__dict__
        d["q"] = q
        d["base_wrench"] = base_wrench
        d["tool"] = tool
        d["fault"] = fault
        return m


@dataclass(frozen=True)
class SceneGeometry:
    """Geometry the scene declares (known a priori, not measured).

    Attributes:
        entry_point: stitch entry point in the world frame [m].
        exit_point: stitch exit point in the world frame [m].
        tissue_normal: unit normal of the tissue surface.
        base_positions: each robot's base (RCM) position in the world frame [m].
    """

    entry_point: FloatArray = field(default_factory=lambda: _frozen_array([0.0, 0.0, 0.0]))
    exit_point: FloatArray = field(default_factory=lambda: _frozen_array([0.0, 0.0, 0.0]))
    tissue_normal: FloatArray = field(default_factory=lambda: _frozen_array([0.0, 0.0, 1.0]))
    base_positions: Mapping[str, tuple[float, float, float]] = field(
        default_factory=lambda: MappingProxyType({})
    )

    def __post_init__(self) -> None:
        object.__setattr__(self, "entry_point", _frozen_array(self.entry_point, 3))
        object.__setattr__(self, "exit_point", _frozen_array(self.exit_point, 3))
        object.__setattr__(self, "tissue_normal", _frozen_array(self.tissue_normal, 3))
        object.__setattr__(self, "base_positions", MappingProxyType(dict(self.base_positions)))


def scene_geometry(
    scene: object,
    default_bases: Mapping[str, tuple[float, float, float]] | None = None,
) -> SceneGeometry:
    """The geometry a scene model declares, the same for every backend.

    Args:
        scene: the scene model (``robots`` with base poses, ``tissue`` with ``points`` and
            ``normal``), or None.
        default_bases: base positions [m] used when the scene declares no robots.

    Returns:
        The SceneGeometry (points and base positions [m] in the world frame).
    """
    robots = getattr(scene, "robots", None)
    if robots:
        bases = {
            str(name): tuple(float(v) for v in spec.base.position) for name, spec in robots.items()
        }
    else:
        bases = {str(k): tuple(float(v) for v in pos) for k, pos in (default_bases or {}).items()}
    tissue = getattr(scene, "tissue", None)
    points = getattr(tissue, "points", None) or {}
    return SceneGeometry(
        entry_point=np.asarray(points.get("entry", (0.0, 0.0, 0.0)), dtype=float),
        exit_point=np.asarray(points.get("exit", (0.0, 0.0, 0.0)), dtype=float),
        tissue_normal=np.asarray(getattr(tissue, "normal", (0.0, 0.0, 1.0)), dtype=float),
        base_positions=bases,  # type: ignore[arg-type]
    )


BACKEND_EVENTS = frozenset({"grip-slip", "needle-stall"})
"""Names of the events a backend may report (:class:`BackendEvent`): the thread slid
through a grasper's jaws; a needle hand-over stopped short."""


@dataclass(frozen=True)
class BackendEvent:
    """Something the simulated world did that no sensor measures (e.g. the thread slid
    through a grasper's jaws). Evaluation and traces only, like the ground truth.

    A backend that has such events offers ``backend_events() -> list[BackendEvent]`` (the ones
    since the last call); the interpreter records each on ``/events`` as an ``info``
    event, which starts no transition. The replay backend has none, so the replay does
    not compare them.

    Attributes:
        name: one of :data:`BACKEND_EVENTS`.
        robot: the robot concerned, or None.
        detail: the event's values, as compact JSON (SI units unless the key says).
    """

    name: str
    robot: str | None
    detail: str

    def __post_init__(self) -> None:
        if self.name not in BACKEND_EVENTS:
            raise ValueError(f"unknown backend event {self.name!r}")


@dataclass(frozen=True)
class Measurement:
    """Everything a backend measured at one tick.

    Attributes:
        tick: tick index since reset.
        t: simulation time [s].
        robots: per-robot raw measurements, keyed by robot name ("endobot_1").
    """

    tick: int
    t: float
    robots: Mapping[str, RobotMeasurement]

    @classmethod
    def trusted(cls, tick: int, t: float, robots: Mapping[str, RobotMeasurement]) -> Measurement:
        """A measurement from fields the caller never changes afterwards (no checks): a
        backend's per-tick fast path."""
        m = object.__new__(cls)
        d = m.__dict__
        d["tick"] = tick
        d["t"] = t
        d["robots"] = robots
        return m


@dataclass(frozen=True)
class RobotObservation:
    """What a skill knows about one EndoBot.

    Attributes:
        q: encoder joint positions [rad, rad, rad, m].
        qd: estimated joint velocities [rad/s, rad/s, rad/s, m/s] (washout filter (3.79)).
        base_wrench: base force/torque sensor (Fx, Fy, Fz [N], Mx, My, Mz [N*m]).
        tool: the tool's measured state.
    """

    q: FloatArray
    qd: FloatArray
    base_wrench: FloatArray
    tool: ToolState

    @classmethod
    def trusted(
        cls, q: FloatArray, qd: FloatArray, base_wrench: FloatArray, tool: ToolState
    ) -> RobotObservation:
        """An observation from read-only float64 arrays that the caller never changes (no
        copy, no checks): the interpreter's per-tick fast path."""
        o = object.__new__(cls)
        d = o.__dict__
        d["q"] = q
        d["qd"] = qd
        d["base_wrench"] = base_wrench
        d["tool"] = tool
        return o


@dataclass(frozen=True)
class Observation:
    """The observation handed to skills each tick; holds no suture ground truth.

    Attributes:
        tick: tick index since reset.
        t: simulation time [s].
        robots: per-robot observations keyed by robot name.
        scene: the declared scene geometry.
    """

    tick: int
    t: float
    robots: Mapping[str, RobotObservation]
    scene: SceneGeometry

    @classmethod
    def trusted(
        cls, tick: int, t: float, robots: Mapping[str, RobotObservation], scene: SceneGeometry
    ) -> Observation:
        """An observation from fields the caller never changes afterwards (no checks): the
        interpreter's per-tick fast path (a frozen dataclass's __init__ sets each field
        through object.__setattr__)."""
        o = object.__new__(cls)
        d = o.__dict__
        d["tick"] = tick
        d["t"] = t
        d["robots"] = robots
        d["scene"] = scene
        return o


class CommandMode(enum.Enum):
    """How a :class:`RobotCommand` drives the joints."""

    POSITION = "position"
    """Track ``q`` (and feed forward ``qd`` if given) with the state's joint controller."""
    VELOCITY = "velocity"
    """Track ``qd``; the position setpoint integrates it."""
    TORQUE = "torque"
    """Apply ``tau`` directly [N*m, N*m, N*m, N]."""


# Bound once for the per-tick constructors (CommandMode.X on the class costs ~60 ns).
_POSITION, _TORQUE = CommandMode.POSITION, CommandMode.TORQUE


@dataclass(frozen=True)
class ToolCommand:
    """A tool command; ``None`` fields leave the tool as it is.

    Attributes:
        jaw_closed: close (True) or open (False) the (first) jaw.
        jaw2_closed: close or open the stitcher's second jaw.
        hook_extension: flexible-hook extension setpoint [m].
        bend: the bent-tip grasper's universal joint setpoint, about the shaft's x then
            about the turned y [rad, rad]; the joint moves towards it at a bounded rate.
    """

    jaw_closed: bool | None = None
    jaw2_closed: bool | None = None
    hook_extension: float | None = None
    bend: tuple[float, float] | None = None


@dataclass(frozen=True)
class RobotCommand:
    """One robot's command for one tick.

    Attributes:
        mode: which fields drive the joints.
        q: joint position setpoint [rad, rad, rad, m] (POSITION, VELOCITY).
        qd: joint velocity setpoint / feed-forward [rad/s, ..., m/s].
        tau: joint torques [N*m, N*m, N*m, N] (TORQUE; after the controller, always).
        tool: tool command.
    """

    mode: CommandMode
    q: FloatArray | None = None
    qd: FloatArray | None = None
    tau: FloatArray | None = None
    tool: ToolCommand | None = None

    def __post_init__(self) -> None:
        for name in ("q", "qd", "tau"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _frozen_array(value, N_JOINTS))
        if self.mode is CommandMode.POSITION and self.q is None:
            raise ValueError("a POSITION command needs q")
        if self.mode is CommandMode.VELOCITY and self.qd is None:
            raise ValueError("a VELOCITY command needs qd")
        if self.mode is CommandMode.TORQUE and self.tau is None:
            raise ValueError("a TORQUE command needs tau")

    @classmethod
    def position(
        cls, q: object, qd: FloatArray | None = None, tool: ToolCommand | None = None
    ) -> RobotCommand:
        """A joint position setpoint [rad, rad, rad, m], with optional velocity feed-forward."""
        return cls(
            CommandMode.POSITION, q=_frozen_array(q), qd=None if qd is None else qd, tool=tool
        )

    @classmethod
    def trusted_position(
        cls, q: FloatArray, qd: FloatArray | None = None, tool: ToolCommand | None = None
    ) -> RobotCommand:
        """A position setpoint from arrays the caller hands over (no copy, no checks).

        A skill's per-tick fast path; ``q`` (and ``qd``) must be fresh float64 arrays of
        shape (4,) that the caller never changes afterwards. They are made read-only.
        """
        cmd = object.__new__(cls)
        q.flags.writeable = False
        if qd is not None:
            qd.flags.writeable = False
        d = cmd.__dict__
        d["mode"] = _POSITION
        d["q"] = q
        d["qd"] = qd
        d["tau"] = None
        d["tool"] = tool
        return cmd

    @classmethod
    def torque(cls, tau: object, tool: ToolCommand | None = None) -> RobotCommand:
        """Joint torques [N*m, N*m, N*m, N]."""
        return cls(CommandMode.TORQUE, tau=_frozen_array(tau), tool=tool)

    @classmethod
    def trusted_torque(cls, tau: FloatArray, tool: ToolCommand | None = None) -> RobotCommand:
        """Joint torques from an array the caller owns and never changes (no copy, no checks).

        The interpreter's per-tick fast path; ``tau`` must be a float64 array of shape (4,).
        """
        cmd = object.__new__(cls)
        tau.flags.writeable = False
        d = cmd.__dict__
        d["mode"] = _TORQUE
        d["q"] = None
        d["qd"] = None
        d["tau"] = tau
        d["tool"] = tool
        return cmd


@dataclass(frozen=True)
class Command:
    """All robots' commands for one tick; robots not named keep the Lock law (4.44).

    Attributes:
        robots: per-robot commands keyed by robot name.
    """

    robots: Mapping[str, RobotCommand]


class SkillStatus(enum.Enum):
    """What a skill reports after a tick."""

    RUNNING = "running"
    """The activity continues; no event."""
    SUCCESS = "success"
    """The activity is over: the planned event e_i (thesis Fig. 4.25)."""
    FAILURE = "failure"
    """The skill failed: an unpredictable event, to the step's NOT-BE state."""


_RUNNING = SkillStatus.RUNNING  # bound once (SkillStatus.X on the class costs ~60 ns)


@dataclass(frozen=True)
class StepResult:
    """A skill's answer for one tick.

    Attributes:
        command: the command for this tick.
        status: running, success (planned event) or failure (unpredictable event).
        message: why it failed (empty otherwise).
        event: with a failure, the named failure event it is (one of the skill's
            :attr:`skills.base.Skill.events`, e.g. ``taut-early``), which a state may
            route on its own (``on: {taut-early: free-loop}``); empty: a plain failure.
    """

    command: Command
    status: SkillStatus = SkillStatus.RUNNING
    message: str = ""
    event: str = ""

    @classmethod
    def running(cls, command: Command) -> StepResult:
        """``StepResult(command)``, without the frozen dataclass's checks: a skill's
        per-tick fast path (the command is handed over)."""
        r = object.__new__(cls)
        d = r.__dict__
        d["command"] = command
        d["status"] = _RUNNING
        d["message"] = ""
        d["event"] = ""
        return r
