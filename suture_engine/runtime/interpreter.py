"""The tick loop: observe -> skill -> controller -> monitor -> apply -> step -> trace.

:class:`Interpreter` runs a compiled :class:`~suture_engine.runtime.automaton.Plan`
on a backend at the control rate (default 1 kHz). Each tick:

1. **observe**: the backend's measurement; joint velocities are *estimated*
   from the encoders by the washout filter (3.78-3.79, 5.50) -> :class:`Observation`;
2. **operator**: operator events of this tick (lock, manual, resume, abort,
   a force at the tool tip);
3. **skill**: in Autonomous mode the active step's skill computes a command;
   a skill exception or ``FAILURE`` is an unpredictable event, ``SUCCESS`` the
   planned event;
4. **monitor**: the step's invariant (4.43) and timeout; a violation is an
   unpredictable event (to the step's NOT-BE state). Before the operator and
   the skill, in every mode, the monitor's emergency check locks every robot
   when the base-sensor tension estimate (7.6-7.9) reaches a margin below the
   scene's limit, on a non-finite measurement (held at its last finite value)
   or on a sensor stale longer than a bound;
5. **controller**: per robot, the law of its mode (Lock 4.44, Manual 5.1,
   Autonomous 5.10) gives joint torques;
6. **apply, step** the backend; **trace** the tick.

Ground truth from the backend goes to the trace only.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict
from typing import Any, Protocol

import numpy as np

from suture_engine.errors import SutureError
from suture_engine.runtime.automaton import Automaton, Mode, Plan, StepSpec
from suture_engine.runtime.calibration import calibration_offsets
from suture_engine.runtime.context import SkillContext
from suture_engine.runtime.controller import ModeController
from suture_engine.runtime.monitor import BaseSensorTension, Invariant, Monitor, SafetyLimits
from suture_engine.runtime.observation import (
    Command,
    Measurement,
    Observation,
    RobotCommand,
    RobotMeasurement,
    RobotObservation,
    SceneGeometry,
    SkillStatus,
    StepResult,
)
from suture_engine.runtime.operator import OperatorEvent
from suture_engine.runtime.recorder import Recorder
from suture_engine.runtime.summary import RunSummary
from suture_engine.runtime.trajectory import rpy_matrix

__all__ = ["GRAVITY", "Interpreter", "OperatorSource"]

GRAVITY = 9.81
"""Gravity [m/s^2], pointing along -z of the world (the value of the robot model)."""


_MODE_VALUES = {m: m.value for m in Mode}
"""Mode -> its name (Mode.value is a descriptor; the tick records it per robot)."""

# Enum members bound once for the per-tick tests: ``Mode.X`` on the class costs ~60 ns
# in CPython 3.11, a module global ~10 ns.
_AUTONOMOUS, _MANUAL = Mode.AUTONOMOUS, Mode.MANUAL
_FAILURE, _SUCCESS = SkillStatus.FAILURE, SkillStatus.SUCCESS


class OperatorSource(Protocol):
    """Where operator events come from (scripted, interactive, a replayed trace)."""

    def poll(self, t: float, state: str, step: str | None, mode: str) -> list[OperatorEvent]:
        """Events at time ``t`` [s] in automaton state ``state``."""
        ...


def _normalise(result: Any) -> StepResult:
    if isinstance(result, StepResult):
        return result
    if isinstance(result, Command):
        return StepResult(result)
    if result is None:
        return StepResult(Command({}))
    raise TypeError(f"a skill's step must return a StepResult or a Command, not {type(result)}")


class Interpreter:
    """Runs a plan on a backend under the supervisory automaton.

    Args:
        plan: the compiled procedure.
        backend: a :class:`backends.base.Backend`, already reset.
        first: the measurement returned by the backend's reset.
        roles: role -> robot name.
        params: the procedure's resolved parameters (SI).
        scene: the scene model (declared geometry), handed to skills.
        seed: the run's seed (for the summary).
        control_rate_hz: ticks per second [Hz].
        operator: the operator source (None: no operator).
        recorder: where the trace goes (None: nowhere).
        max_time_s: simulated time after which the run stops as failed [s].
        tension_limit_N: the procedure's tension limit, for the summary [N].
        progress: called every 100 ticks with (t [s], max_time_s [s]).
        washout_pole: pole of the washout velocity filter [rad/s] (5.50).
        manual_invariant: the Manual mode invariant (4.45), e.g. the joint limits.
        on_tick: called after every recorded tick with the interpreter (live panel, video).
        emergency_margin: the monitor locks every robot when the estimated tension
            reaches ``(1 - emergency_margin) * tension_limit_N`` [-].
        max_stale_s: the monitor locks every robot when a sensor stays stale (dropped
            readings) longer than this [s]; shorter dropouts are absorbed.
        tension_cutoff_hz: low-pass cut-off of the base-sensor tension estimate [Hz].
        calibration_error: robot -> the engine's believed base position minus the
            robot's actual one [m] (a simulated calibration error: the backend builds
            the robots where the scene declares them, the skills plan from the scene's
            bases plus this). A ``register`` step measures it and takes it out.
    """

    def __init__(
        self,
        plan: Plan,
        backend: Any,
        first: Measurement,
        *,
        roles: Mapping[str, str] | None = None,
        params: Mapping[str, Any] | None = None,
        scene: Any = None,
        seed: int = 0,
        control_rate_hz: float = 1000.0,
        operator: OperatorSource | None = None,
        recorder: Recorder | None = None,
        max_time_s: float = 300.0,
        tension_limit_N: float | None = None,
        progress: Callable[[float, float], None] | None = None,
        washout_pole: float = 150.0,
        manual_invariant: Invariant | None = None,
        on_tick: Callable[[Interpreter], None] | None = None,
        emergency_margin: float = 0.1,
        max_stale_s: float = 0.01,
        tension_cutoff_hz: float = 30.0,
        calibration_error: Mapping[str, Sequence[float]] | None = None,
    ) -> None:
        from suture_engine.control.filters import WashoutFilter

        self.plan = plan
        self.backend = backend
        self._backend_events = getattr(backend, "backend_events", None)
        self.roles = dict(roles or {})
        self.params = dict(params or {})
        self.scene = scene
        self.seed = seed
        self.rate = float(control_rate_hz)
        self.dt = 1.0 / self.rate
        self.period_ns = round(1e9 / self.rate)
        self.operator_source = operator
        self.recorder = recorder or Recorder()
        self.max_time_s = max_time_s
        self.tension_limit_N = tension_limit_N
        self.progress = progress
        self.manual_invariant = manual_invariant
        self.on_tick = on_tick
        self.robots = tuple(first.robots)
        self.geometry: SceneGeometry = backend.geometry()
        self._washout = {r: WashoutFilter(washout_pole, self.dt) for r in self.robots}
        self._base_offsets: dict[str, tuple[float, float, float]] = calibration_offsets(
            calibration_error, scene
        )
        """Robot -> the believed base's offset from the declared one [m]: the calibration
        error, plus the corrections a ``register`` step has measured."""
        gravity: dict[str, tuple[float, float, float]] = {}
        for name, (_pos, rot) in self._base_poses().items():
            g = np.asarray(rot).reshape(3, 3).T @ np.array([0.0, 0.0, -GRAVITY])
            gravity[name] = (float(g[0]), float(g[1]), float(g[2]))
        self.controller = ModeController(self.robots, self.dt, gravity_base=gravity)
        self.monitor = Monitor()
        self.safety = SafetyLimits(tension_limit_N, emergency_margin, max_stale_s)
        from suture_engine.robot.params import E1

        models = {r: dataclasses.replace(E1, gravity=g) for r, g in gravity.items()}
        self.tension = BaseSensorTension(models, self.dt, tension_cutoff_hz)
        self._last_good: dict[str, RobotMeasurement] = {}
        self._non_finite: dict[str, str] = {}
        self._stale: dict[str, bool] = {}
        first = self._sanitise(first)
        self.tension.tare(first)
        self.automaton = Automaton(plan, self._start_skill)
        self.ctx: SkillContext | None = None
        self.operator_events = 0
        self.metrics: dict[str, Any] = {}
        self._pending_meas: Measurement | None = first
        self._obs: Observation | None = None
        self._rest: Observation | None = None  # the first tick's: at rest, thread slack
        self._qp_failures: dict[str, int] = {r: 0 for r in self.robots}
        self.tick_index = 0
        self.wall_time_s = 0.0
        self.stop_reason = ""
        self.last_fault: dict[str, Any] | None = None
        """The last unpredictable event of a step: its ``step``, ``reason`` and time
        ``t_s`` [s] (None when there was none)."""
        self._waiting_ticks = 0
        self._last_skill: Any = None
        self._tension: dict[str, float] = {}
        self._shared_skill: Any = None
        """The running skill when it is a shared-control one (``mode: shared``)."""
        self._true_tension = [-math.inf, math.nan]
        """Peak and last true thread tension of the ground truth [N] (evaluation only)."""
        self._true_peak_at: dict[str, Any] | None = None
        """When (``t_s``), in which state and at which ``joint`` of the thread the true
        tension peaked (evaluation only)."""
        self.interrupted = False
        self.robot_modes: dict[str, Mode] = {}
        """Robots the operator holds alone (lock or manual) while the procedure goes on."""

    # ----------------------------------------------------------------- skills
    def _base_poses(self) -> dict[str, Any]:
        """The scene's declared base poses, plus what a ``register`` step has measured."""
        out: dict[str, Any] = {}
        robots = getattr(self.scene, "robots", None) or {}
        for name, spec in robots.items():
            base = spec.base
            rot = rpy_matrix(base.rpy)
            position = tuple(float(v) for v in base.position)
            offset = self._base_offsets.get(name)
            if offset is not None:
                position = tuple(a + b for a, b in zip(position, offset, strict=True))
            out[name] = (position, tuple(float(v) for v in rot))
        return out

    def _start_skill(self, spec: StepSpec, skill: Any) -> None:
        assert self._obs is not None
        ctx = SkillContext(
            step=spec.name,
            roles={**self.roles, **spec.roles},
            dt=self.dt,
            start=self._obs,
            scene=self.scene,
            params=self.params,
            base_poses=self._base_poses(),
            rest=self._rest,
        )
        start = getattr(skill, "start", None)
        if start is not None:
            start(ctx)
        self.ctx = ctx
        # decided once per step (a pydantic model without ``mode`` raises in getattr)
        params = getattr(skill, "params", None)
        fields = getattr(type(params), "model_fields", None) or {}
        shared = "mode" in fields and getattr(params, "mode", None) == "shared"
        self._shared_skill = skill if shared else None

    # ----------------------------------------------------------------- one tick
    def _sanitise(self, meas: Measurement) -> Measurement:
        """Hold each robot's last finite reading in place of a non-finite one (NaN or inf:
        a physics blow-up or a sensor fault) and note it, with the sensors' dropouts,
        for the monitor's emergency check."""
        self._non_finite = bad = {}
        self._stale = stale = {}
        replaced: dict[str, RobotMeasurement] | None = None
        for name, m in meas.robots.items():
            if m.fault:
                stale[name] = True
            q = m.q.tolist()
            w = m.base_wrench.tolist()
            if math.isfinite(sum(q) + sum(w)):
                self._last_good[name] = m
                continue
            bad[name] = "q" if not all(math.isfinite(v) for v in q) else "base_wrench"
            good = self._last_good.get(name)
            if good is None:
                good = RobotMeasurement(np.zeros(len(q)), np.zeros(6), m.tool, m.fault)
            if replaced is None:
                replaced = dict(meas.robots)
            replaced[name] = RobotMeasurement(good.q, good.base_wrench, m.tool, m.fault)
        if replaced is None:
            return meas
        return Measurement(meas.tick, meas.t, replaced)

    def _observe(self) -> tuple[Measurement, Observation]:
        meas = self._pending_meas if self._pending_meas is not None else self.backend.observe()
        self._pending_meas = None
        meas = self._sanitise(meas)
        robots = {}
        trusted = RobotObservation.trusted
        washout = self._washout
        for name, m in meas.robots.items():
            qd = washout[name].update_frozen(m.q)  # a fresh read-only array
            robots[name] = trusted(m.q, qd, m.base_wrench, m.tool)  # read-only arrays
        return meas, Observation.trusted(meas.tick, meas.t, robots, self.geometry)

    def _record_transitions(self, time_ns: int, records: list[Any]) -> None:
        if records and self._last_skill is not None:
            self._collect_metrics(self._last_skill)
        self._last_skill = self.automaton.active_skill
        for rec in records:
            self.recorder.transition(time_ns, rec)
            if rec.event == "fault" and rec.kind == "unpredictable":
                step = rec.source.removeprefix("autonomous/")
                self.last_fault = {"step": step, "reason": rec.reason, "t_s": time_ns * 1e-9}

    def _handle_operator(self, time_ns: int, obs: Observation) -> None:
        if self.operator_source is None:
            return
        a = self.automaton
        for ev in self.operator_source.poll(obs.t, a.state, a.step_name, a.mode.value):
            self.operator_events += 1
            if ev.action == "push":
                push = getattr(self.backend, "apply_operator_hand", None)
                if push is None or ev.robot is None or ev.velocity is None:
                    self.recorder.operator(time_ns, ev, False, "backend has no simulated hand")
                else:
                    push(ev.robot, ev.velocity, ev.stiffness, ev.duration)
                    self.recorder.operator(time_ns, ev, True, "")
                continue
            if ev.action == "force":
                apply = getattr(self.backend, "apply_external_force", None)
                if apply is None or ev.robot is None or ev.force is None:
                    self.recorder.operator(time_ns, ev, False, "backend applies no force")
                else:
                    apply(ev.robot, ev.force, ev.duration)
                    self.recorder.operator(time_ns, ev, True, "")
                continue
            if ev.robot is not None and ev.action in ("lock", "manual", "resume"):
                self._robot_operator(time_ns, ev)
                continue
            try:
                records = a.operator(ev.action, ev.step)
            except Exception as exc:  # a refused action is recorded, never fatal
                self.recorder.operator(time_ns, ev, False, str(exc))
                continue
            self.recorder.operator(time_ns, ev, True, "")
            self._record_transitions(time_ns, records)

    def _robot_operator(self, time_ns: int, ev: OperatorEvent) -> None:
        """Lock, take or give back ONE robot (Fig. 4.23 is per EndoBot).

        A robot the running step does not drive changes mode alone and the procedure
        goes on. Taking a robot the running step drives interrupts the procedure like
        an operator lock (NOT-BE, then the operator's mode for every robot).
        """
        a = self.automaton
        robot = ev.robot
        assert robot is not None
        if robot not in self.robots:
            self.recorder.operator(time_ns, ev, False, f"no robot {robot!r}")
            return
        if ev.action == "resume":
            if self.robot_modes.pop(robot, None) is None:
                self.recorder.operator(time_ns, ev, False, f"{robot} is not held")
                return
            self.recorder.operator(time_ns, ev, True, "")
            return
        mode = Mode.LOCK if ev.action == "lock" else Mode.MANUAL
        if a.mode is Mode.AUTONOMOUS and a.mode_of(robot) is Mode.AUTONOMOUS:
            self.robot_modes[robot] = mode
            self.recorder.operator(time_ns, ev, True, "the running step drives it")
            self._record_transitions(time_ns, a.unpredictable(f"operator-takes:{robot}", True))
            return
        self.robot_modes[robot] = mode
        self.recorder.operator(time_ns, ev, True, "")

    def _emergency_check(self, time_ns: int, obs: Observation) -> None:
        """The monitor's emergency lock, in every mode, whatever the step's invariant:
        tension a margin below the scene's limit, a non-finite measurement, a sensor
        stale too long (an unpredictable event; every robot locks and the operator is
        waited for). Recorded on /events as ``emergency`` with its reason."""
        if self.monitor.quiet(self.safety, self._tension, self._stale, self._non_finite):
            return  # the common tick: emergency() would return None and record nothing
        a = self.automaton
        manual_held = any(m is Mode.MANUAL for m in self.robot_modes.values())
        locked = a.mode in (Mode.LOCK, Mode.TERMINAL, Mode.IDLE) and not manual_held
        before = len(self.monitor.violations)
        tension = self._tension
        guided = self._operator_guided()
        if guided:
            tension = {r: v for r, v in tension.items() if r not in guided}
        v = self.monitor.emergency(
            self.safety,
            obs,
            a.state,
            tension,
            self._stale,
            self._non_finite,
            self.dt,
            locked,
        )
        for rec in self.monitor.violations[before:]:
            self.recorder.event(time_ns, "emergency", "unpredictable", a.state, rec.reason)
        if v is None:
            return
        self.robot_modes.clear()  # every robot follows the automaton's Lock
        self._record_transitions(time_ns, a.emergency_lock(v.reason))

    def _operator_guided(self) -> set[str]:
        """Robots the operator's hand moves now: Manual (the whole automaton or one robot),
        or a shared-control step (a skill with ``mode: shared``, 6.24, 6.33-6.37).

        The base sensor cannot tell the surgeon's hand from the thread, so the
        emergency tension lock leaves these robots to the surgeon (Manual's invariant
        is the workspace, 4.45); the non-finite and stale-sensor locks still act."""
        a = self.automaton
        mode = a.mode
        shared = self._shared_skill is not None and self._shared_skill is a.active_skill
        if not self.robot_modes and mode is not Mode.MANUAL and not shared:
            return set()  # the common tick
        out = {r for r, m in self.robot_modes.items() if m is Mode.MANUAL}
        if mode is Mode.MANUAL:
            out.update(self.robots)
        elif mode is Mode.AUTONOMOUS and shared and a.active_step is not None:
            out.update(a.active_step.robots or self.robots)
        return out

    def _held_robot_blocks(self, time_ns: int) -> None:
        """A step that needs a robot the operator holds cannot run: interrupt it."""
        if not self.robot_modes:  # the common tick (checked first: the cheaper test)
            return
        a = self.automaton
        if a.mode is not Mode.AUTONOMOUS:
            return
        for robot in self.robot_modes:
            if a.mode_of(robot) is Mode.AUTONOMOUS:
                reason = f"operator-holds:{robot}"
                self._record_transitions(time_ns, a.unpredictable(reason, True))
                return

    def _skill_tick(self, time_ns: int, obs: Observation, meas: Measurement) -> Command | None:
        a = self.automaton
        spec = a.active_step
        if a.mode is not _AUTONOMOUS or spec is None or a.active_skill is None:
            return None
        assert self.ctx is not None
        try:
            result = _normalise(a.active_skill.step(self.ctx, obs))
        except Exception as exc:
            records = a.unpredictable(f"skill-failure:{type(exc).__name__}: {exc}")
            self._record_transitions(time_ns, records)
            return None
        # None on Skill (its default); a duck-typed skill (a test's scripted one) may lack
        # it. The look-up costs ~10 ns a tick either way.
        if getattr(a.active_skill, "scene_request", None) is not None:
            failure = self._scene_request(time_ns, a.active_skill)
            if failure is not None:
                self._record_transitions(time_ns, a.unpredictable(f"skill-failure:{failure}"))
                return None
        self._qp_tick(time_ns, a.active_skill, spec)
        violation = self.monitor.check(
            spec.invariant,
            obs,
            a.state,
            self._tension,
            self._qp_failures,
            spec.robots,
            self.ctx.base_poses,
        )
        if violation is not None:
            self._record_transitions(time_ns, a.unpredictable(violation.reason))
            return None
        if spec.timeout_s is not None and obs.t - self.ctx.t0 >= spec.timeout_s - 0.5 * self.dt:
            self._record_transitions(time_ns, a.unpredictable("timeout", event="timeout"))
            return None
        if result.status is _FAILURE:
            reason = f"skill-failure:{result.message}" if result.message else "skill-failure"
            self._record_transitions(time_ns, a.unpredictable(reason, event=result.event))
            return result.command
        if result.status is _SUCCESS:
            self._apply_registration(a.active_skill)
            self._record_transitions(time_ns, a.planned())
        return result.command

    def _scene_request(self, time_ns: int, skill: Any) -> str | None:
        """Carry out a skill's request to change the world (``cut-suture``,
        ``load-suture``: :class:`skills.reload.SutureChange`) on the backend.

        A cut thread's last centerline goes to the trace (``/ground_truth/suture_cut``);
        each change is an event. Returns why it failed (the backend cannot, or refused),
        or None."""
        action, kwargs = skill.scene_request
        skill.scene_request = None
        method = getattr(self.backend, action, None)
        name = getattr(self.backend, "name", type(self.backend).__name__)
        if method is None:
            return f"the backend {name} cannot {action.replace('_', ' ')}"
        try:
            result = method(**kwargs)
        except SutureError as exc:
            return str(exc)
        state = self.automaton.state
        detail = json.dumps(kwargs, sort_keys=True, separators=(",", ":"))
        self.recorder.event(time_ns, action.replace("_", "-"), "backend", state, detail)
        centerline = getattr(result, "centerline", None)
        if centerline is not None:
            self.recorder.suture_cut(time_ns, centerline)
        return None

    def _apply_registration(self, skill: Any) -> None:
        """Add a finishing skill's base corrections (``register``) to the declared bases."""
        corrections = getattr(skill, "base_corrections", None)
        for robot, offset in (corrections or {}).items():
            old = self._base_offsets.get(robot, (0.0, 0.0, 0.0))
            self._base_offsets[robot] = tuple(  # type: ignore[assignment]
                float(a) + float(b) for a, b in zip(old, offset, strict=True)
            )

    def _qp_tick(self, time_ns: int, skill: Any, spec: StepSpec) -> None:
        """Trace the skill's QP status and count consecutive failed solves (for the monitor)."""
        res = getattr(skill, "last_qp", None)
        if res is None:
            return
        robot = spec.robots[0] if spec.robots else self.robots[0]
        self._qp_failures[robot] = 0 if res.solved else self._qp_failures[robot] + 1
        self.recorder.qp(time_ns, robot, res)

    def _collect_metrics(self, skill: Any) -> None:
        """Merge the finishing skill's metrics (e.g. chapter 6 stiffness) into the summary's."""
        metrics = getattr(skill, "metrics", None)
        if skill is None or metrics is None:
            return
        try:
            values = metrics()
        except Exception as exc:  # a metric must never end a run
            values = {"metrics_error": f"{type(exc).__name__}: {exc}"}
        self.metrics.update(values)

    def _manual_command(self, obs: Observation) -> Command | None:
        """Manual mode under the interrupted step's shared-control fixture, if it has one.

        A skill that offers ``manual_step(ctx, obs)`` (e.g. a virtual fixture, 6.24,
        6.33-6.37) gives the Manual law's joint torques; otherwise the controller applies
        gravity compensation alone (5.1).
        """
        skill = self.automaton.interrupted_skill
        manual_step = getattr(skill, "manual_step", None)
        if manual_step is None or self.ctx is None:
            return None
        try:
            result = _normalise(manual_step(self.ctx, obs))
        except Exception:  # a failing fixture must not take the arm from the surgeon
            return None
        return result.command

    def _record_backend_events(self, time_ns: int) -> None:
        """Record what the world did in the last step that no sensor measures
        (:class:`~suture_engine.runtime.observation.BackendEvent`): ``info`` events,
        which the automaton does not react to."""
        assert self._backend_events is not None
        for ev in self._backend_events():
            self.recorder.event(time_ns, ev.name, "info", self.automaton.state, ev.detail, ev.robot)

    def _manual_check(self, time_ns: int, obs: Observation) -> None:
        if self.manual_invariant is None:
            return
        a = self.automaton
        if a.mode is not Mode.MANUAL:
            return
        v = self.monitor.check(self.manual_invariant, obs, a.state, self._tension, {})
        if v is not None:
            self._record_transitions(time_ns, a.operator("lock"))
            self.recorder.event(time_ns, "manual-workspace", "unpredictable", a.state, v.reason)

    def tick(self) -> bool:
        """Run one control tick; return False once the run is over."""
        if self._pending_meas is None and getattr(self.backend, "exhausted", False):
            self.stop_reason = "end of recording"
            return False
        meas, obs = self._observe()
        self._obs = obs
        self._tension = tension = self.tension.estimate(obs)
        time_ns = self.tick_index * self.period_ns
        a = self.automaton
        if self.tick_index == 0:
            self._rest = obs
            self._record_transitions(time_ns, a.start())
        if self._backend_events is not None:
            self._record_backend_events(time_ns)
        self._emergency_check(time_ns, obs)
        self._handle_operator(time_ns, obs)
        self._held_robot_blocks(time_ns)
        command = self._skill_tick(time_ns, obs, meas)
        self._manual_check(time_ns, obs)
        torques: dict[str, Any] = {}
        modes: dict[str, str] = {}
        tools: dict[str, Any] = {}
        if command is None and a.mode is _MANUAL:
            command = self._manual_command(obs)
        for name in self.robots:
            mode = a.mode_of(name)
            held = self.robot_modes.get(name)
            if held is not None and mode is not Mode.TERMINAL:
                mode = held  # the operator holds this robot alone (Fig. 4.23)
            rc = command.robots.get(name) if command is not None else None
            if rc is not None and rc.tool is not None:
                tools[name] = rc.tool
            torques[name] = self.controller.torque(name, mode, obs.robots[name], rc)
            modes[name] = _MODE_VALUES[mode]
        self.monitor.max_tension_N = max(self.monitor.max_tension_N, *tension.values())
        truth = self.backend.ground_truth()
        true_tension = truth.get("tension_N")
        if true_tension is not None:
            self._true_tension[1] = true_tension
            if true_tension > self._true_tension[0]:  # a NaN is never the peak
                self._true_tension[0] = true_tension
                joint = truth.get("tension_joint")
                self._true_peak_at = {
                    "t_s": float(obs.t),
                    "state": a.state,
                    "joint": None if joint is None else int(joint),
                }
        self.recorder.tick(time_ns, obs, torques, modes, tension, truth)
        if self.on_tick is not None:
            self.on_tick(self)
        if a.finished:
            self.stop_reason = a.state
            return False
        if self._stuck():
            self.stop_reason = "locked, waiting for an operator who has no more events"
            return False
        if obs.t >= self.max_time_s:
            self.stop_reason = f"time limit {self.max_time_s:g} s reached"
            return False
        applied = {
            name: RobotCommand.trusted_torque(torques[name], tools.get(name))
            for name in self.robots
        }
        self.backend.apply(Command(applied))
        self.backend.step()
        self.tick_index += 1
        if self.progress is not None and self.tick_index % 100 == 0:
            self.progress(obs.t, self.max_time_s)
        return True

    def _evaluate(self) -> Any:
        """Knots and stitch metrics from the final ground truth and the tension figures
        (:mod:`suture_engine.runtime.evaluation`). Evaluation only: skills never see it."""
        from suture_engine.runtime.evaluation import evaluate

        truth = self.backend.ground_truth()
        centerline = truth.get("centerline")
        geometry = getattr(self.backend, "geometry", None)
        scene = geometry() if geometry is not None else None
        point = scene.entry_point if scene is not None else (0.0, 0.0, 0.0)
        normal = scene.tissue_normal if scene is not None else (0.0, 0.0, 1.0)
        tissue = getattr(self.scene, "tissue", None)
        declared = dict(getattr(tissue, "points", None) or {})
        cut = getattr(tissue, "wound", None)
        wound = (cut.start, cut.end) if cut is not None else None
        diameter = truth.get("contact_diameter")
        if diameter is None:  # the PyBullet thread's capsule contact radius
            params = getattr(
                getattr(getattr(self.backend, "scene", None), "suture", None), "params", None
            )
            radius = getattr(params, "collision_radius", None)
            diameter = 2.0 * float(radius) if radius is not None else None
        peak, last = self._true_tension
        true = (peak, last) if math.isfinite(last) else None
        final = max(self._tension.values()) if self._tension else None
        estimated = [self.monitor.max_tension_N] + ([final] if final is not None else [])
        try:
            cut = truth.get("cut_centerlines") or ()
            return evaluate(
                centerline,
                estimated,
                true,
                point,
                normal,
                declared,
                diameter,
                wound,
                cut,
                true_peak_at=self._true_peak_at if true is not None else None,
            )
        except (SutureError, ValueError) as exc:  # e.g. a degenerate centerline
            from suture_engine.runtime.evaluation import TraceEvaluation, tension_metrics

            knot = {"type": None, "error": str(exc)} if centerline is not None else None
            at = self._true_peak_at if true is not None else None
            return TraceEvaluation(knot, dict(tension_metrics(estimated, true, at)))

    def _stuck(self) -> bool:
        """Locked and waiting, for 10 ticks, with no timed operator event left."""
        a = self.automaton
        if not a.waiting_for_operator or a.mode is not Mode.LOCK:
            self._waiting_ticks = 0
            return False
        self._waiting_ticks += 1
        if self._waiting_ticks < 10:
            return False
        src = self.operator_source
        if src is None:
            return True
        exhausted = getattr(src, "exhausted", None)
        return bool(exhausted) if exhausted is not None else False

    # ----------------------------------------------------------------- the run
    def run(self, procedure: str, backend_name: str) -> RunSummary:
        """Tick until the run ends; return the summary (the recorder is closed)."""
        t0 = time.perf_counter()
        try:
            while self.tick():
                pass
        except KeyboardInterrupt:  # Ctrl-C: end like an operator abort, trace closed
            self.stop_reason = "interrupted (Ctrl-C)"
            self.interrupted = True
        finally:
            self.wall_time_s = time.perf_counter() - t0
            self.recorder.close()
        if not self.automaton.finished:
            self._collect_metrics(self.automaton.active_skill)
        return self.summary(procedure, backend_name)

    def summary(self, procedure: str, backend_name: str) -> RunSummary:
        """The run's summary so far."""
        a = self.automaton
        outcome = a.outcome.value if a.outcome is not None else "failed"
        if self.interrupted and a.outcome is None:
            outcome = "aborted"
        sim = self.tick_index * self.dt
        wall = self.wall_time_s
        metrics = dict(self.metrics)
        if self.stop_reason and not a.finished:
            metrics["stopped"] = self.stop_reason
        evaluation = self._evaluate()
        for key, value in evaluation.metrics.items():
            metrics.setdefault(key, value)
        run_metrics = getattr(self.backend, "run_metrics", None)
        if run_metrics is not None:
            for key, value in run_metrics().items():
                metrics.setdefault(key, value)
        return RunSummary(
            procedure=procedure,
            outcome=outcome,
            final_state=a.state,
            sim_time_s=sim,
            wall_time_s=wall,
            real_time_factor=sim / wall if wall > 0 else 0.0,
            control_rate_hz=self.rate,
            max_tension_N=self.monitor.max_tension_N,
            tension_limit_N=self.tension_limit_N,
            violations=[asdict(v) for v in self.monitor.violations],
            retries=a.retries_total,
            operator_events=self.operator_events,
            metrics=metrics,
            knot=evaluation.knot,
            seed=self.seed,
            backend=backend_name,
            ticks=self.tick_index + 1,
            last_fault=self.last_fault,
        )
