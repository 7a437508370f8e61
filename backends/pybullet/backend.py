"""The PyBullet backend: two EndoBots (:class:`backends.pybullet.robot.EndoBotSim`).

Each robot of the scene stands at its base pose (the base origin is the RCM);
torques are applied at the control rate (1 kHz) and PyBullet steps once per
tick. Measurements are what the real robot has: encoder positions and the base
force/torque sensor, through the sensor models of :mod:`backends.pybullet.sensors`
(seeded, so a seed gives the same run; the scene's ``physics.force_noise`` and
``physics.measurement_delay`` set the base sensor's noise and delay). Headless
(``p.DIRECT``) by default; ``gui=True`` opens a window.

With ``surgical_scene=True`` (the ``pybullet-surgical`` backend), the world is the
surgical scene of :mod:`backends.pybullet.scene`
(:func:`~backends.pybullet.scene.build_scene`): the robots with their tools mounted,
the tissue pad and the thread. Each tick the tools, the thread and the tissue run
their pre-step hooks before PyBullet steps; tool commands drive the tools (grasper
jaws and hook, stitcher jaws and the needle hand-over); ``ground_truth`` adds the
thread's centerline [m] and its largest segment tension [N], which the recorder
writes on ``/ground_truth/*``. Skills never see them (they get observations only).
Likewise evaluation only: :meth:`~PyBulletBackend.backend_events` gives each slide of
the thread through a grasper's jaws (``grip-slip``, pulled harder than its grip force),
which the interpreter records on ``/events``, and :meth:`~PyBulletBackend.run_metrics`
their count and length for ``summary.json``.
The plain ``pybullet`` backend holds the robots alone.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Callable, Iterator, Mapping
from typing import Any

import numpy as np

from backends.base import BackendError
from backends.pybullet.suture import CONTACT_DAMPING
from suture_engine.errors import SutureError
from suture_engine.runtime.observation import (
    BackendEvent,
    Command,
    CommandMode,
    Measurement,
    RobotMeasurement,
    SceneGeometry,
    ToolState,
    scene_geometry,
)

__all__ = [
    "DEFAULT_BASES",
    "DEFAULT_Q0",
    "PyBulletBackend",
    "StitchedSurgicalPyBulletBackend",
    "SurgicalPyBulletBackend",
]

DEFAULT_Q0 = (0.0, 0.0, 0.0, 0.08)
"""Start joints when the scene gives none [rad, rad, rad, m]."""

DEFAULT_BASES: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "endobot_1": ((-0.05, 0.0, 0.12), (math.pi, 0.0, 0.0)),
    "endobot_2": ((0.05, 0.0, 0.12), (math.pi, 0.0, 0.0)),
}
"""Base position [m] and roll-pitch-yaw [rad] when no scene is given (z axes pointing down)."""


def _quaternion(rpy: tuple[float, float, float]) -> tuple[float, float, float, float]:
    """(x, y, z, w) of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = (0.5 * float(a) for a in rpy)
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def _tool_tip(sim: Any) -> Any:
    return sim.true_tool_pose()[0]


def _towards(value: float, goal: float, step: float) -> float:
    """``value`` moved towards ``goal`` by at most ``step`` (exactly ``goal`` once within)."""
    if abs(goal - value) <= step:
        return goal
    return value + step if goal > value else value - step


class _LazyTruth(Mapping[str, Any]):
    """A read-only mapping whose values are computed on first look-up, then kept."""

    def __init__(self, getters: dict[str, Callable[[], Any]]) -> None:
        self._getters = getters
        self._values: dict[str, Any] = {}

    def __getitem__(self, key: str) -> Any:
        if key not in self._values:
            self._values[key] = self._getters[key]()
        return self._values[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._getters)

    def __len__(self) -> int:
        return len(self._getters)


class PyBulletBackend:
    """Two EndoBots in PyBullet.

    Args:
        gui: open a window (``p.GUI``) instead of running headless.
        dt: control and physics period [s].
        q0: start joints per robot (default :data:`DEFAULT_Q0`).
        friction: simulate joint friction.
        surgical_scene: build the tissue, thread and tools of the scene: True needs a
            scene with robots, a tissue and a suture; False (the default) builds the
            robots alone (the mounted tools' and thread's weight is not in the engine's
            gravity model, so the base-sensor tension estimate of a robots-only
            procedure would read it as tension). None: when the scene declares them.
        start: the surgical scene's start state with a stitcher: ``"needle"`` (the thread
            hangs from the needle in the stitcher's jaw), ``"tail-held"`` (the needle in
            the stitcher's jaw, the thread's free end held by the first grasper ``tail``
            out of the entry point), ``"stitched"`` (the stitch is
            made: the thread runs through the tissue from entry to exit, ``tail`` lies out
            of the entry point on the surface, the rest runs from the exit to the needle
            in the stitcher's jaw), or None for the scene's ``suture.start``.
        tail: the tail out of the entry point [m]: the stitched start's, or where the
            tail-held start's grasper holds the thread's free end.
        stitch: names of the stitch's entry and exit points; None: ``entry``/``exit``,
            else the numbered pair nearest the wound's middle
            (:func:`backends.pybullet.scene.stitch_points`).
        bend: the universal joint's start angles (about x, then about the turned y)
            [rad] of every bent-tip grasper; None: straight. The jaws turn about a point
            ``tip_length`` (12 mm) behind the robot's tool tip, so the bent jaws are off
            the tool tip that the robot's kinematics reports. A tool command's ``bend``
            then drives the joint towards its setpoint at :attr:`BEND_RATE` per axis,
            and the tool state reports the joint's angles (its encoders), in both the
            surgical and the robots-only world.
        base_error: perturbation: robot name -> displacement [m] of its actual base from
            the scene's declared base (a calibration error: the skills' model, from the
            declared geometry, is off by it).
        friction_scale: perturbation: every simulated joint friction (Coulomb, static,
            viscous; (3.42)-(3.45)) times this factor [-].
        suture_bending_stiffness: the thread's flexural rigidity EI [N*m^2] (surgical
            scene); 0, the default, is the limp thread the knot physics is tuned with.
        suture_stiffness_scale: perturbation: EI times this factor [-].
        wound_gap: the wound's width between the tissue pad's two halves, as the thread's
            contacts meet it [m] (surgical scene; None: the scene's ``tissue.wound.gap``,
            else :data:`backends.pybullet.tissue.WOUND_GAP`, 1 mm, which pinches the
            thread's 1.8 mm collision capsules; 0 closes the wound: see there).
        wound_depth: how deep the wound stays open under the surface [m], a floor below
            (surgical scene; None: open through the pad).
        pad_clear_depth: a thread capsule leaving the stitch channel inside the pad gets
            its contacts with the pad back only once it lies no deeper than this in it [m]
            (surgical scene; :attr:`backends.pybullet.tissue.Tissue.clear_depth`; None, the
            default: at once, wherever it is).
        thread_contact_stiffness: every contact of the thread's capsules becomes a
            spring-damper of this stiffness [N/m] (surgical scene;
            :meth:`backends.pybullet.suture.Suture.soften_contacts`); None, the default:
            the scene's ``suture.contact_stiffness``, else rigid contacts, which push an
            overlap out whatever force that takes.
        thread_contact_damping: the damping of those contacts [N*s/m] (with
            ``thread_contact_stiffness``).
        thread_smooth_joints: the thread's capsules reach over its joints, so that its
            surface is a round tube through each of them (surgical scene;
            :class:`backends.pybullet.suture.SutureParams`' ``smooth_joints``); None, the
            default: the scene's ``suture.smooth_joints`` (false in every bundled scene:
            the capsules meet tip to tip, with a groove at each joint).
        thread_damping: how fast the thread's free motion dies away [1/s] (surgical
            scene; the scene's ``suture.damping``, which it overrides; None, the default:
            the scene's, else 0.5 /s).
        thread_weight: the mass per length whose weight the thread keeps [kg/m]
            (surgical scene; overrides the scene's ``suture.weight``; None, the default:
            the scene's, else 0.1 g/m).
    """

    name = "pybullet"
    SETTLE_S = 0.2
    """How long the surgical scene settles, robots held, before the first measurement [s]."""
    BEND_RATE = 2.0
    """Largest speed of each of the bent-tip grasper's universal joint axes [rad/s]."""
    BENT_TIP = "bent-tip-grasper"
    """The tool kind that has the universal joint."""
    HOOK_LOAD_DIGITS = 2
    """The hook actuator's load sensor resolves 10^-2 N (0.01 N): the value the skills see
    and the trace records on the ticks it changes."""

    def __init__(
        self,
        gui: bool = False,
        dt: float = 1e-3,
        q0: Mapping[str, tuple[float, ...]] | None = None,
        friction: bool = True,
        surgical_scene: bool | None = False,
        start: str | None = None,
        tail: float = 0.03,
        stitch: tuple[str, str] | None = None,
        bend: tuple[float, float] | None = None,
        base_error: Mapping[str, tuple[float, float, float]] | None = None,
        friction_scale: float = 1.0,
        suture_bending_stiffness: float = 0.0,
        suture_stiffness_scale: float = 1.0,
        wound_gap: float | None = None,
        wound_depth: float | None = None,
        pad_clear_depth: float | None = None,
        thread_contact_stiffness: float | None = None,
        thread_contact_damping: float = CONTACT_DAMPING,
        thread_smooth_joints: bool | None = None,
        thread_damping: float | None = None,
        thread_weight: float | None = None,
    ) -> None:
        self.gui = gui
        self.dt = dt
        self.friction = friction
        self._q0 = dict(q0 or {})
        self._start_q: dict[str, tuple[float, ...]] = dict(self._q0)
        self.client: int | None = None
        self.robots: dict[str, Any] = {}
        self.tick = 0
        self._tools: dict[str, ToolState] = {}
        self._bend_goal: dict[str, tuple[float, float]] = {}
        self._forces: list[tuple[str, np.ndarray, int]] = []
        self._hands: list[list[Any]] = []
        self._geometry = SceneGeometry()
        self._p: Any = None
        self.surgical_scene = surgical_scene
        self.start = start
        self.tail = tail
        self.stitch = stitch
        self.bend = bend
        self.base_error = dict(base_error or {})
        self.friction_scale = friction_scale
        self.suture_bending_stiffness = suture_bending_stiffness
        self.suture_stiffness_scale = suture_stiffness_scale
        self.wound_gap = wound_gap
        self.wound_depth = wound_depth
        if pad_clear_depth is not None and not pad_clear_depth >= 0.0:
            raise BackendError(
                self.name, f"pad_clear_depth must be >= 0 [m], got {pad_clear_depth}"
            )
        self.pad_clear_depth = pad_clear_depth
        if thread_contact_stiffness is not None and not thread_contact_stiffness > 0.0:
            raise BackendError(
                self.name,
                f"thread_contact_stiffness must be > 0 [N/m], got {thread_contact_stiffness}",
            )
        if not thread_contact_damping >= 0.0:
            raise BackendError(
                self.name,
                f"thread_contact_damping must be >= 0 [N*s/m], got {thread_contact_damping}",
            )
        self.thread_contact_stiffness = thread_contact_stiffness
        self.thread_contact_damping = thread_contact_damping
        if thread_smooth_joints is not None and not isinstance(thread_smooth_joints, bool):
            raise BackendError(
                self.name,
                f"thread_smooth_joints must be true or false, got {thread_smooth_joints!r}",
            )
        self.thread_smooth_joints = thread_smooth_joints
        if thread_damping is not None and not thread_damping >= 0.0:
            raise BackendError(
                self.name, f"thread_damping must be >= 0 [1/s], got {thread_damping}"
            )
        self.thread_damping = thread_damping
        if thread_weight is not None and not thread_weight > 0.0:
            raise BackendError(self.name, f"thread_weight must be > 0 [kg/m], got {thread_weight}")
        self.thread_weight = thread_weight
        self._thread_model: dict[str, Any] | None = None
        self.scene: Any = None
        """The :class:`backends.pybullet.scene.Scene` when the surgical scene is built."""
        self._scene_model: Any = None
        self._contact_diameter: float | None = None
        """The thread's contact diameter [m] (its capsules' collision radius, twice)."""
        self.cut_threads: list[Any] = []
        """The threads cut so far (:class:`backends.pybullet.reload.CutThread`), in order."""
        self._slips_seen: dict[str, int] = {}
        """Per robot, how many of its grasper's slips :meth:`backend_events` has given."""
        self._stalls_seen: dict[str, int] = {}
        """Per robot, how many of its stitcher's needle stalls it has given."""

    def _bases(self, scene: Any) -> dict[str, tuple[Any, Any, str]]:
        robots = getattr(scene, "robots", None)
        if not robots:
            return {n: (pos, rpy, "grasper") for n, (pos, rpy) in DEFAULT_BASES.items()}
        return {
            name: (tuple(spec.base.position), tuple(spec.base.rpy), str(spec.tool))
            for name, spec in robots.items()
        }

    def _tail_held_q(self, scene: Any) -> dict[str, tuple[float, float, float, float]]:
        """Without the thread, the start joints of the surgical tail-held start's assistant:
        the first grasper where it would hold the thread's free end, so that a procedure
        starts from the same poses on both backends. Empty when the scene has no stitch
        to make (no tissue, suture or stitcher) or starts otherwise."""
        from backends.pybullet.scene import tail_held_joints

        robots = getattr(scene, "robots", None) or {}
        suture = getattr(scene, "suture", None)
        start = self.start or getattr(suture, "start", None) or "needle"
        if getattr(scene, "tissue", None) is None or suture is None or start != "tail-held":
            return {}
        if not any(str(spec.tool) == "stitcher" for spec in robots.values()):
            return {}
        return tail_held_joints(scene, self.stitch, self.tail)

    def reset(self, scene: Any, seed: int) -> Measurement:
        """Connect, build the robots at the scene's base poses, measure once.

        Args:
            scene: the scene model (robots' base poses, tissue points), or None.
            seed: seeds the sensor models.
        """
        import pybullet as p

        from backends.pybullet.robot import EndoBotSim

        self.close()
        self._p = p
        self.robots = {}
        self._tools = {}
        self._bend_goal = {}
        self._forces = []
        self._hands = []
        self._slips_seen = {}
        self._stalls_seen = {}
        scene = self._thread_options(scene)
        self._scene_model = scene
        self.cut_threads = []
        self._thread_model = None
        self._contact_diameter = None
        self.tick = 0
        self._start_q = dict(self._q0)
        base_positions = {}
        unknown = sorted(set(self.base_error) - set(self._bases(scene)))
        if unknown:
            raise BackendError(self.name, f"base_error for unknown robots {unknown}")
        if not (math.isfinite(self.friction_scale) and self.friction_scale >= 0.0):
            raise BackendError(self.name, f"friction_scale {self.friction_scale!r} must be >= 0")
        ft_model = self._ft_model(scene)
        if self._wants_surgical_scene(scene):
            self._build_surgical_scene(scene, seed, ft_model)
            for name, (pos, _rpy, tool) in sorted(self._bases(scene).items()):
                self._tools[name] = self._start_bend(self._measured_tool(name, tool))
                base_positions[name] = (float(pos[0]), float(pos[1]), float(pos[2]))
        else:
            for name, q in self._tail_held_q(scene).items():
                self._start_q.setdefault(name, q)
            client = p.connect(p.GUI if self.gui else p.DIRECT)
            if client < 0:
                raise BackendError(self.name, "cannot connect to PyBullet")
            self.client = client
            p.setTimeStep(self.dt, physicsClientId=client)
            p.setGravity(0.0, 0.0, -9.81, physicsClientId=client)
            for i, (name, (pos, rpy, tool)) in enumerate(sorted(self._bases(scene).items())):
                offset = np.asarray(self.base_error.get(name, (0.0, 0.0, 0.0)), dtype=float)
                sim = EndoBotSim(
                    client,
                    base_position=tuple(np.asarray(pos, dtype=float) + offset),
                    base_orientation=_quaternion(rpy),
                    q0=self._start_q.get(name, DEFAULT_Q0),
                    friction=self.friction,
                    ft_sensor=ft_model,
                    seed=seed * 1000 + i,
                )
                if self.friction_scale != 1.0:
                    sim.scale_friction(self.friction_scale)
                self.robots[name] = sim
                # a stitcher starts with the needle in jaw 1, as on every surgical start
                # (the thread is not simulated here, the jaw that holds the needle is)
                start_tool = ToolState(kind=tool, jaw_closed=tool == "stitcher")
                self._tools[name] = self._start_bend(start_tool)
                base_positions[name] = (float(pos[0]), float(pos[1]), float(pos[2]))
        # One step held by gravity torques so the base sensors read the weight (PyBullet
        # computes joint reaction forces in the step), then put the joints back.
        from suture_engine.robot.endobot import gravity_vector

        # With the surgical scene, the thread and the mounted tools first settle for
        # SETTLE_S [s] with the robots held, so that the first measurement (which the
        # runtime tares) and the ground truth start from rest, not from a start-up transient.
        steps = 1 if self.scene is None else max(1, round(self.SETTLE_S / self.dt))
        for _ in range(steps):
            for name, sim in self.robots.items():
                sim.apply(gravity_vector(self._start_q.get(name, DEFAULT_Q0), sim.model_params))
            self._physics_step()
            for name, sim in self.robots.items():
                sim.reset(self._start_q.get(name, DEFAULT_Q0))
        self._geometry = scene_geometry(scene, base_positions)
        return self.observe()

    def _wants_surgical_scene(self, scene: Any) -> bool:
        if self.surgical_scene is False or self.gui:
            return False
        declared = (
            getattr(scene, "tissue", None) is not None
            and getattr(scene, "suture", None) is not None
            and bool(getattr(scene, "robots", None))
        )
        if self.surgical_scene and not declared:
            raise BackendError(self.name, "the surgical scene needs robots, a tissue and a suture")
        return declared

    def _build_surgical_scene(self, scene: Any, seed: int, ft_model: Any) -> None:
        """The scene engineer's world (robots with mounted tools, tissue, thread)."""
        import numpy as np

        from backends.pybullet.scene import build_scene
        from backends.pybullet.sensors import Sensor

        try:
            if not (self.suture_stiffness_scale >= 0.0 and self.suture_bending_stiffness >= 0.0):
                raise BackendError(self.name, "suture stiffness and its scale must be >= 0")
            built = build_scene(
                scene,
                seed,
                start=self.start,
                tail=self.tail,
                stitch=self.stitch,
                base_error=self.base_error,
                bending_stiffness=self.suture_bending_stiffness * self.suture_stiffness_scale,
                **self._wound(),
            )
        except SutureError as exc:
            raise BackendError(self.name, str(exc)) from None
        if self.bend is not None:
            from backends.pybullet.tools import BentTipGrasper

            for tool in built.tools.values():
                if isinstance(tool, BentTipGrasper):
                    tool.set_bend(float(self.bend[0]), float(self.bend[1]))
        self.scene = built
        self._configure_contacts()
        self.client = built.client
        if built.suture is not None:  # a freshly built scene always has its thread
            self._contact_diameter = 2.0 * float(built.suture.params.collision_radius)
        for i, (name, sim) in enumerate(sorted(built.robots.items())):
            # the scene's start joints (the stitched start's pulled-out stitcher) unless
            # the caller gave its own
            q0 = self._start_q.setdefault(name, tuple(built.hold.get(name, DEFAULT_Q0)))
            sim.reset(q0)
            sim.friction_enabled = self.friction
            if self.friction_scale != 1.0:
                sim.scale_friction(self.friction_scale)
            if ft_model is not None:
                # build_scene makes ideal base sensors; give them the scene's noise and delay.
                sim._ft = Sensor(ft_model, 6, np.random.default_rng(seed * 1000 + i))
            self.robots[name] = sim

    def _start_bend(self, state: ToolState) -> ToolState:
        """A bent-tip grasper's state with the ``bend`` option's start angles [rad]."""
        if state.kind != self.BENT_TIP or self.bend is None:
            return state
        bend = (float(self.bend[0]), float(self.bend[1]))
        return ToolState(
            state.kind, state.jaw_closed, state.jaw2_closed, state.hook_extension, bend
        )

    def _step_bends(self) -> None:
        """Move each universal joint towards its setpoint by at most BEND_RATE * dt [rad]
        per axis; the surgical scene's bent-tip grasper turns its jaws with it."""
        step = self.BEND_RATE * self.dt
        for name, goal in self._bend_goal.items():
            t = self._tools[name]
            if t.bend == goal:
                continue
            bend = (_towards(t.bend[0], goal[0], step), _towards(t.bend[1], goal[1], step))
            self._tools[name] = ToolState(
                t.kind, t.jaw_closed, t.jaw2_closed, t.hook_extension, bend
            )
            tool = self.scene.tools.get(name) if self.scene is not None else None
            if tool is not None and hasattr(tool, "set_bend"):
                tool.set_bend(*bend)

    def _measured_tool(self, name: str, kind: str) -> ToolState:
        """The tool's state as its sensors report it, from the simulated tool.

        A stitcher reports the jaw that holds the needle closed on it and the other one
        open, as the skills read it (``jaw_closed`` is jaw 1, the -x jaw). A grasper
        reports its valve: closed from the tick it is commanded shut, while the jaws
        are still travelling (``Grasper.travel_time``); it has no jaw sensor.
        """
        from backends.pybullet.tools import Grasper, JawState, Stitcher

        tool = self.scene.tools.get(name) if self.scene is not None else None
        if isinstance(tool, Stitcher):
            closed = tool.opening == 0.0 and tool.needle_body >= 0
            return ToolState(
                kind, closed and tool.needle_holder == 0, closed and tool.needle_holder == 1
            )
        if isinstance(tool, Grasper):
            jaw = tool.state in (JawState.CLOSED, JawState.CLOSING)
            return ToolState(kind, jaw, False, tool.hook_extension)
        return ToolState(kind=kind)

    def _physics_step(self) -> None:
        """One PyBullet step, with the surgical scene's pre-step hooks when it is built."""
        scene = self.scene
        if scene is not None:
            for tool in scene.tools.values():
                tool.step()
            if scene.suture is not None:
                scene.suture.pre_step()
            if scene.tissue is not None:
                scene.tissue.pre_step()
        self._p.stepSimulation(physicsClientId=self.client)
        if scene is not None:
            if scene.suture is not None:
                scene.suture.stepped()
            scene.time += self.dt

    def _drive_tool(self, name: str, old: ToolState, new: ToolState) -> None:
        """Turn a change of the commanded tool state into the simulated tool's actions."""
        scene = self.scene
        tool = scene.tools.get(name) if scene is not None else None
        if tool is None:
            return
        from backends.pybullet.tools import Grasper, Stitcher, ToolError

        try:
            if isinstance(tool, Stitcher):
                # Jaw 1 / jaw 2 are the stitcher's -x / +x jaws; the needle sits in
                # needle_holder. Closing the empty jaw while the holder is closed hands
                # the needle over (Fig. 4.3) once the jaws are closed; the receiving jaw
                # reads closed when the needle is in it; both open opens the jaws.
                closed = (bool(new.jaw_closed), bool(new.jaw2_closed))
                before = (bool(old.jaw_closed), bool(old.jaw2_closed))
                receiver = 1 - tool.needle_holder
                if closed != before:
                    if not any(closed):
                        tool.open_jaws()
                    else:
                        tool.close_jaws()
                        if closed[receiver] and not before[receiver] and closed[1 - receiver]:
                            tool.request_pass()
            elif isinstance(tool, Grasper):
                if new.jaw_closed != old.jaw_closed:
                    (tool.close if new.jaw_closed else tool.open)()
                # The hook's actuator is a reciprocating one (4.4.2): a command that moves
                # out extends it fully, one that moves in retracts it (a skill ramps the
                # setpoint and may end within its tolerance short of 0).
                if new.hook_extension != old.hook_extension:
                    out = new.hook_extension > old.hook_extension
                    (tool.extend_hook if out else tool.retract_hook)()
        except ToolError as exc:
            raise BackendError(self.name, f"tool of {name}: {exc}") from None

    def _ft_model(self, scene: Any) -> Any:
        """The base F/T sensor's imperfections from the scene's physics settings.

        ``force_noise`` [N] is the standard deviation on the three force channels;
        ``measurement_delay`` [s] delays the whole wrench by whole control ticks.
        """
        from backends.pybullet.sensors import SensorModel

        physics = getattr(scene, "physics", None)
        noise = float(getattr(physics, "force_noise", 0.0) or 0.0)
        delay = float(getattr(physics, "measurement_delay", 0.0) or 0.0)
        if noise == 0.0 and delay == 0.0:
            return None
        return SensorModel(
            noise_std=(noise, noise, noise, 0.0, 0.0, 0.0),
            delay_ticks=round(delay / self.dt),
        )

    def _need(self) -> Any:
        if self.client is None:
            raise BackendError(self.name, "not reset (or closed)")
        return self._p

    def _tool_reading(self, name: str) -> ToolState:
        """The tool state as measured: the commanded one, except that a stitcher's
        receiving jaw reads closed only once the needle hand-over is done (never after one
        that stopped short), that a stitcher which lost its needle (a dropped needle) reads
        neither jaw closed (its jaws sense the needle latched in them), and that a
        simulated hook's actuator reports its load."""
        state = self._tools[name]
        tool = self.scene.tools.get(name) if self.scene is not None else None
        if tool is None:
            return state
        if getattr(tool, "hook_body", -1) >= 0:
            load = round(tool.hook_load(), self.HOOK_LOAD_DIGITS)
            return ToolState(
                state.kind,
                state.jaw_closed,
                state.jaw2_closed,
                state.hook_extension,
                state.bend,
                load,
            )
        if getattr(tool, "needle_body", -1) >= 0 and not tool.holds_needle:
            return ToolState(state.kind, False, False, state.hook_extension, state.bend)
        if not (getattr(tool, "passing", False) or getattr(tool, "stalled", False)):
            return state
        if tool.needle_holder == 0:
            return ToolState(state.kind, state.jaw_closed, False, state.hook_extension, state.bend)
        return ToolState(state.kind, False, state.jaw2_closed, state.hook_extension, state.bend)

    def observe(self) -> Measurement:
        """Encoders and base F/T sensors of every robot."""
        self._need()
        robots = {}
        for name, sim in self.robots.items():
            joints, wrench = sim.measure()
            # each reading's array is the sensor's fresh copy, read by nobody else: made
            # read-only, it is what RobotMeasurement's constructor would copy and freeze
            q, w = joints.values, wrench.values
            q.flags.writeable = w.flags.writeable = False
            robots[name] = RobotMeasurement.trusted(
                q, w, self._tool_reading(name), not (joints.fresh and wrench.fresh)
            )
        return Measurement.trusted(self.tick, self.tick * self.dt, robots)

    def apply(self, command: Command) -> None:
        """Apply TORQUE commands; tool commands update the tool state."""
        self._need()
        for name, rc in command.robots.items():
            sim = self.robots.get(name)
            if sim is None:
                raise BackendError(self.name, f"no robot named {name!r}")
            if rc.mode is not CommandMode.TORQUE or rc.tau is None:
                raise BackendError(self.name, "the backend takes joint torques only")
            sim.apply(rc.tau)
            if rc.tool is not None:
                t = self._tools[name]
                self._tools[name] = ToolState(
                    t.kind,
                    t.jaw_closed if rc.tool.jaw_closed is None else rc.tool.jaw_closed,
                    t.jaw2_closed if rc.tool.jaw2_closed is None else rc.tool.jaw2_closed,
                    t.hook_extension if rc.tool.hook_extension is None else rc.tool.hook_extension,
                    t.bend,
                )
                if rc.tool.bend is not None and t.kind == self.BENT_TIP:
                    self._bend_goal[name] = (float(rc.tool.bend[0]), float(rc.tool.bend[1]))
                if self.scene is not None:
                    self._drive_tool(name, t, self._tools[name])

    def apply_external_force(
        self, robot: str, force: tuple[float, float, float], duration: float
    ) -> None:
        """Push ``robot``'s tool tip with ``force`` [N] (world frame) for ``duration`` [s]."""
        if robot not in self.robots:
            raise BackendError(self.name, f"no robot named {robot!r}")
        ticks = max(1, round(duration / self.dt))
        self._forces.append((robot, np.array(force, dtype=np.float64), self.tick + ticks))

    def apply_operator_hand(
        self, robot: str, velocity: tuple[float, float, float], stiffness: float, duration: float
    ) -> None:
        """The surgeon's hand: it starts at the tool tip, moves at ``velocity`` [m/s] (world
        frame) for ``duration`` [s] and drags the tip through a spring of ``stiffness``
        [N/m], the same in every direction: F = K (x_hand - x_tip)."""
        if robot not in self.robots:
            raise BackendError(self.name, f"no robot named {robot!r}")
        ticks = max(1, round(duration / self.dt))
        self._hands.append(
            [robot, None, np.array(velocity, dtype=np.float64), stiffness, self.tick, ticks]
        )

    def _hand_forces(self) -> list[tuple[str, np.ndarray, int]]:
        out = []
        keep = []
        for hand in self._hands:
            robot, x0, v, k, start, ticks = hand
            if self.tick >= start + ticks:
                continue
            keep.append(hand)
            tip, _ = self.robots[robot].true_tool_pose()
            if x0 is None:
                x0 = hand[1] = np.array(tip)
            x_hand = x0 + v * ((self.tick - start) * self.dt)
            out.append((robot, k * (x_hand - tip), self.tick + 1))
        self._hands = keep
        return out

    def step(self) -> None:
        """Advance the world by one period (external forces re-applied each step)."""
        p = self._need()
        self._forces = [f for f in self._forces if self.tick < f[2]]
        for name, force, _until in self._forces + self._hand_forces():
            sim = self.robots[name]
            tip, _ = sim.true_tool_pose()
            p.applyExternalForce(
                sim.body_id,
                sim.tool_link,
                force.tolist(),
                tip.tolist(),
                p.WORLD_FRAME,
                physicsClientId=self.client,
            )
        if self._bend_goal:
            self._step_bends()
        self._physics_step()
        self.tick += 1

    def _graspers(self) -> dict[str, Any]:
        """The surgical scene's graspers (tools that record slips), by robot."""
        tools = self.scene.tools if self.scene is not None else {}
        return {robot: t for robot, t in sorted(tools.items()) if hasattr(t, "slips")}

    def backend_events(self) -> list[BackendEvent]:
        """The events since the last call (evaluation and traces only): a ``grip-slip``
        per slide of the thread through a grasper's jaws
        (:class:`~backends.pybullet.tools.GripSlip`), detail ``t`` (the tool's clock [s]),
        ``force_N`` (the pull the jaws held in the step before [N]), ``slid_mm`` (how far
        the thread slid [mm]), ``from_segment``/``to_segment`` (the capsules held before
        and after; -1: none); and a ``needle-stall`` per needle hand-over that stopped
        short (:class:`~backends.pybullet.tools.NeedleStall`), detail ``t`` [s],
        ``shortfall_mm`` (how far from the receiving jaw [mm]) and ``jaw`` (the jaw that
        keeps the needle, 0 or 1)."""
        events = []
        for robot, tool in self._graspers().items():
            seen = self._slips_seen.get(robot, 0)
            for slip in tool.slips[seen:]:
                detail = {
                    "t": round(slip.time, 6),
                    "force_N": round(slip.force, 4),
                    "slid_mm": round(1e3 * slip.distance, 4),
                    "from_segment": slip.from_segment,
                    "to_segment": slip.to_segment,
                }
                events.append(
                    BackendEvent("grip-slip", robot, json.dumps(detail, separators=(",", ":")))
                )
            self._slips_seen[robot] = len(tool.slips)
        tools = self.scene.tools if self.scene is not None else {}
        for robot, tool in sorted(tools.items()):
            stalls = getattr(tool, "stalls", None)
            if not stalls:
                continue
            seen = self._stalls_seen.get(robot, 0)
            for stall in stalls[seen:]:
                detail = {
                    "t": round(stall.time, 6),
                    "shortfall_mm": round(1e3 * stall.shortfall, 4),
                    "jaw": stall.giving,
                }
                events.append(
                    BackendEvent("needle-stall", robot, json.dumps(detail, separators=(",", ":")))
                )
            self._stalls_seen[robot] = len(stalls)
        return events

    def run_metrics(self) -> dict[str, Any]:
        """The run's figures for ``summary.json`` (surgical scene only): with graspers,
        ``grip_slips`` (how many times the thread slid through a grasper's jaws),
        ``grip_slip_mm`` (how far in all [mm]) and ``grip_slips_by_robot`` (robot ->
        ``{"slips", "mm"}``, the graspers that slipped); with a stitcher,
        ``needle_stalls`` (how many needle hand-overs stopped short); with a thread,
        ``thread`` (:meth:`thread_model`: the model the run's figures were made on)."""
        metrics: dict[str, Any] = {}
        model = self.thread_model()
        if model is not None:
            metrics["thread"] = model
        graspers = self._graspers()
        if graspers:
            slipped = {robot: t for robot, t in graspers.items() if t.slips}
            metrics |= {
                "grip_slips": sum(len(t.slips) for t in slipped.values()),
                "grip_slip_mm": round(1e3 * sum(t.slid for t in slipped.values()), 4),
                "grip_slips_by_robot": {
                    robot: {"slips": len(t.slips), "mm": round(1e3 * t.slid, 4)}
                    for robot, t in slipped.items()
                },
            }
        tools = self.scene.tools.values() if self.scene is not None else ()
        stitchers = [t for t in tools if hasattr(t, "stalls")]
        if stitchers:
            metrics["needle_stalls"] = sum(len(t.stalls) for t in stitchers)
        return metrics

    def thread_model(self) -> dict[str, Any] | None:
        """The simulated thread's model as the run last built it (kept once the thread
        is cut), for ``summary.json``: ``capsules`` (how many), ``capsule_mm`` (each
        one's length [mm]),
        ``damping_per_s`` (its free motion's damping rate [1/s]), ``weight_g_per_m``
        (the weight it keeps [g/m]; the rest of its simulated mass is cancelled),
        ``simulated_g_per_m`` (its simulated mass [g/m]), ``smooth_joints``,
        ``bending_stiffness_Nm2`` (EI [N*m^2]) and ``contact_stiffness_N_per_m`` (None:
        rigid contacts). A check's thresholds are measured on one model: a figure
        names it. None when no thread was built (the robots alone)."""
        suture = self.scene.suture if self.scene is not None else None
        return self._built_thread_model() if suture is not None else self._thread_model

    def _built_thread_model(self) -> dict[str, Any]:
        assert self.scene is not None and self.scene.suture is not None
        prm = self.scene.suture.params
        contact = self._thread_contact()
        return {
            "capsules": prm.n_segments,
            "capsule_mm": round(1e3 * prm.segment_length, 6),
            "damping_per_s": prm.linear_damping,
            "weight_g_per_m": round(1e3 * prm.real_mass_per_length, 9),
            "simulated_g_per_m": round(1e3 * prm.segment_mass / prm.segment_length, 6),
            "smooth_joints": prm.smooth_joints,
            "bending_stiffness_Nm2": prm.bending_stiffness,
            "contact_stiffness_N_per_m": None if contact is None else contact[0],
        }

    def geometry(self) -> SceneGeometry:
        """The scene's declared geometry."""
        return self._geometry

    def ground_truth(self) -> Mapping[str, Any]:
        """True tool-tip positions [m] and, with the surgical scene, the thread's
        ``centerline`` [m], ``tension_N`` (its largest joint tension [N]),
        ``tension_joint`` (where that acts: the joint's index among the centerline's
        points, :meth:`~backends.pybullet.suture.Suture.peak_tension`) and
        ``contact_diameter`` [m]; once a thread is cut, ``cut_centerlines`` [m].
        Evaluation and traces only.

        Each value is read from the simulator when it is first looked up (and kept), so a
        caller pays only for what it reads: look values up before the next :meth:`step`.
        """
        getters: dict[str, Callable[[], Any]] = {}
        for name, sim in self.robots.items():
            getters[f"{name}/tool_tip"] = functools.partial(_tool_tip, sim)
        if self.scene is not None:
            suture = self.scene.suture
            if suture is not None:
                getters["centerline"] = suture.centerline
                peak = functools.lru_cache(maxsize=1)(suture.peak_tension)
                getters["tension_N"] = lambda: peak()[0]
                getters["tension_joint"] = lambda: peak()[1]
            if self.cut_threads:
                cut = tuple(c.centerline for c in self.cut_threads)
                getters["cut_centerlines"] = lambda: cut
            # every thread of a scene has the same parameters, a cut one included
            getters["contact_diameter"] = lambda: self._contact_diameter
        return _LazyTruth(getters)

    def cut_suture(self, withdraw: bool = False) -> Any:
        """Cut the thread and take it out of the world (an interrupted suture: the
        assistant cuts the tied stitch's ends; :func:`backends.pybullet.reload.cut_thread`).

        Args:
            withdraw: the thread is drawn out of the tissue and discarded (replaced before
                any knot): it is not kept, and nothing is returned.

        Returns:
            The cut thread (:class:`~backends.pybullet.reload.CutThread`): ground truth,
            for evaluation and traces only. It is kept in :attr:`cut_threads`, and
            :meth:`ground_truth` gives the cut centerlines as ``cut_centerlines``.
            None when withdrawn.

        Raises:
            BackendError: no surgical scene, or no thread to cut.
        """
        from backends.pybullet.reload import cut_thread

        if self.scene is None:
            raise BackendError(self.name, "no surgical scene: there is no thread to cut")
        try:
            cut = cut_thread(self.scene)
        except SutureError as exc:
            raise BackendError(self.name, str(exc)) from None
        if withdraw:
            return None
        self.cut_threads.append(cut)
        return cut

    def remove_posts(self) -> list[str]:
        """Take the calibration posts out of the world: the assistant lifts the jig off
        the bench once the bases are registered (``remove-posts``;
        :func:`backends.pybullet.scene.remove_posts`).

        Returns:
            The names of the posts taken away.

        Raises:
            BackendError: no surgical scene, or no posts in play.
        """
        from backends.pybullet.scene import remove_posts

        if self.scene is None:
            raise BackendError(self.name, "no surgical scene: there are no posts to remove")
        try:
            return remove_posts(self.scene)
        except SutureError as exc:
            raise BackendError(self.name, str(exc)) from None

    def load_suture(self, entry: str, exit: str) -> None:
        """Load a new thread for the stitch from tissue point ``entry`` to ``exit``, in the
        backend's start state (``stitched``: the stitch made, the needle in the
        stitcher's holding jaw where the stitcher is; ``needle``: the thread hanging from
        it). :func:`backends.pybullet.reload.load_thread`.

        Raises:
            BackendError: no surgical scene, a thread still in the world, another start
                state, an unknown point, or a thread too short to reach the jaw.
        """
        from backends.pybullet.reload import load_thread

        if self.scene is None:
            raise BackendError(self.name, "no surgical scene: no thread can be loaded")
        model = self._scene_model
        start = self.start or getattr(getattr(model, "suture", None), "start", None) or "needle"
        try:
            load_thread(
                self.scene,
                model,
                entry,
                exit,
                start,
                self.tail,
                self.suture_bending_stiffness * self.suture_stiffness_scale,
                **self._wound(),
            )
        except SutureError as exc:
            raise BackendError(self.name, f"cannot load a suture: {exc}") from None
        self._configure_contacts()

    def _configure_contacts(self) -> None:
        """Give the scene's tissue pad the backend's ``pad_clear_depth``, and its thread
        the ``thread_contact_stiffness`` when given."""
        if self.scene is None:
            return
        if self.scene.tissue is not None:
            self.scene.tissue.clear_depth = self.pad_clear_depth
        contact = self._thread_contact()
        if contact is not None and self.scene.suture is not None:
            self.scene.suture.soften_contacts(*contact)
        if self.scene.suture is not None:
            self._thread_model = self._built_thread_model()

    def _thread_contact(self) -> tuple[float, float] | None:
        """The thread's contact stiffness [N/m] and damping [N*s/m]: the backend's
        ``thread_contact_stiffness`` (with its damping), else the scene's
        ``suture.contact_stiffness`` (with the scene's damping); None: rigid."""
        if self.thread_contact_stiffness is not None:
            return float(self.thread_contact_stiffness), float(self.thread_contact_damping)
        suture: Any = getattr(self._scene_model, "suture", None)
        stiffness = getattr(suture, "contact_stiffness", None)
        if stiffness is None:
            return None
        return float(stiffness), float(suture.contact_damping)

    def _thread_options(self, scene: Any) -> Any:
        """The scene model with the backend's ``thread_smooth_joints``,
        ``thread_damping`` and ``thread_weight`` in its suture, when given (the thread is
        built from the model, and every reloaded one with it)."""
        suture = getattr(scene, "suture", None)
        update: dict[str, Any] = {}
        if self.thread_smooth_joints is not None:
            update["smooth_joints"] = self.thread_smooth_joints
        if self.thread_damping is not None:
            update["damping"] = float(self.thread_damping)
        if self.thread_weight is not None:
            update["weight"] = float(self.thread_weight)
        if not update or suture is None:
            return scene
        return scene.model_copy(update={"suture": suture.model_copy(update=update)})

    def _wound(self) -> dict[str, float]:
        """The ``wound_gap`` and ``wound_depth`` keywords for the scene's pads, as given: the
        backend's ``wound_gap``, else the scene's ``tissue.wound.gap``, else the pad's own."""
        gap = self.wound_gap
        if gap is None:
            tissue = getattr(self._scene_model, "tissue", None)
            gap = getattr(getattr(tissue, "wound", None), "gap", None)
        given = {"wound_gap": gap, "wound_depth": self.wound_depth}
        return {k: float(v) for k, v in given.items() if v is not None}

    def close(self) -> None:
        """Disconnect; idempotent."""
        if self.client is not None and self._p is not None:
            try:
                self._p.disconnect(physicsClientId=self.client)
            except Exception:  # already gone (window closed by the user)
                pass
        self.client = None
        self.robots = {}
        self.scene = None


class SurgicalPyBulletBackend(PyBulletBackend):
    """The PyBullet backend with the surgical scene (tissue, thread, mounted tools).

    Fault-injection hooks (called by :class:`suture_engine.faults.backend.FaultyBackend`):

    * :meth:`inject_grasp_slip` ``(robot)``: that robot's jaw loses what it holds, at once,
      while the jaws stay closed and the measured tool state is unchanged (the sensors
      see no slip): a grasper lets go of the thread capsule it held; a stitcher's jaw
      lets go of the needle (it then hangs on the thread, and a commanded needle
      hand-over does nothing).
    * :meth:`inject_snag` ``(extra_friction_N, duration_s)``: the tissue's static friction
      F_s (4.5) is raised by ``extra_friction_N`` [N] for ``duration_s`` [s] (the thread
      catches in the tissue); it acts while thread lies in the stitch channel.

    Args:
        kwargs: as :class:`PyBulletBackend` (``surgical_scene`` is True).
    """

    name = "pybullet-surgical"

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("surgical_scene", True)
        super().__init__(**kwargs)

    def _scene_tool(self, robot: str) -> Any:
        self._need()
        if robot not in self.robots:
            raise BackendError(self.name, f"no robot named {robot!r}")
        if self.scene is None:
            raise BackendError(self.name, "no surgical scene is built")
        return self.scene.tools.get(robot)

    def inject_grasp_slip(self, robot: str) -> bool:
        """Make ``robot``'s jaw lose the suture (or the needle) it holds.

        Returns:
            Whether anything was held (and is now lost).

        Raises:
            BackendError: no such robot, or the backend is not reset.
        """
        from backends.pybullet.tools import Grasper, Stitcher

        tool = self._scene_tool(robot)
        if isinstance(tool, Grasper):
            return tool.slip()
        if isinstance(tool, Stitcher):
            return tool.drop_needle()
        return False

    def inject_snag(self, extra_friction_N: float, duration_s: float) -> None:
        """Raise the tissue's static friction by ``extra_friction_N`` [N] for ``duration_s``
        [s] (4.5).

        Raises:
            BackendError: the backend is not reset, or a negative friction or duration.
        """
        self._need()
        if not (extra_friction_N >= 0.0 and duration_s >= 0.0):
            raise BackendError(
                self.name,
                f"a snag needs friction >= 0 N and duration >= 0 s, got "
                f"{extra_friction_N!r} N for {duration_s!r} s",
            )
        if self.scene is None or self.scene.tissue is None:
            raise BackendError(self.name, "no tissue to snag in")
        self.scene.tissue.snag(float(extra_friction_N), float(duration_s))


class StitchedSurgicalPyBulletBackend(SurgicalPyBulletBackend):
    """The surgical backend starting with the stitch made (``start="stitched"``).

    Args:
        kwargs: as :class:`PyBulletBackend` (``surgical_scene`` is True, ``start`` is
            ``"stitched"``).
    """

    name = "pybullet-surgical-stitched"

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("start", "stitched")
        super().__init__(**kwargs)
