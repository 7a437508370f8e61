"""``FaultyBackend``: a backend wrapper that injects the run's faults.

It implements the backend protocol (:class:`backends.base.Backend`) around any
backend and changes what crosses the boundary:

- **sensor faults** change the measurement the wrapper returns, in this order:
  ``delay`` (an older sample of the sensor), ``bias``, ``noise``, ``dropout``
  (the sensor holds its last value and the tick is flagged ``fault``, which the
  monitor turns into an unpredictable event);
- **joint faults** change the command: ``joint-weak`` scales the joint's torque,
  ``joint-lock`` replaces it by a brake (a stiff, critically damped spring at
  the angle where the joint locked, natural frequency :data:`BRAKE_OMEGA`);
- **grasp-slip** and **snag** call the backend's hooks ``inject_grasp_slip(robot)``
  and ``inject_snag(extra_friction_N, duration_s)`` at their onset;
- **blow-up**: ``nan`` makes every measurement NaN from the onset on (the physics
  state is lost); ``energy`` pushes the tool tip with a force that grows
  exponentially (:data:`ENERGY_START_N`, :data:`ENERGY_GROWTH_S`, capped at
  :data:`ENERGY_CAP_N`, world +z) through ``apply_external_force``.

Every onset and end goes to ``sink(time_ns, message)`` (see
:mod:`~suture_engine.faults.record`); messages produced before a sink is attached
(at reset) are kept and handed over when it is. The same seed gives the same
faults: all randomness comes from :class:`~suture_engine.faults.schedule.FaultSchedule`.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from suture_engine.faults.model import JOINTS, Fault
from suture_engine.faults.record import fault_message
from suture_engine.faults.schedule import FaultSchedule, Onset
from suture_engine.faults.support import FaultNotSupported, refusal
from suture_engine.runtime.observation import (
    Command,
    CommandMode,
    Measurement,
    RobotCommand,
    RobotMeasurement,
    SceneGeometry,
)

__all__ = [
    "BRAKE_OMEGA",
    "ENERGY_CAP_N",
    "ENERGY_GROWTH_S",
    "ENERGY_START_N",
    "FaultyBackend",
]

BRAKE_OMEGA = 100.0
"""Natural frequency of a locked joint's brake [rad/s] (stiffness M_jj * omega^2)."""
ENERGY_START_N = 0.5
"""The exploding force's magnitude at the blow-up's onset [N]."""
ENERGY_GROWTH_S = 0.05
"""Its e-folding time [s]."""
ENERGY_CAP_N = 200.0
"""Its largest magnitude [N]."""

Sink = Callable[[int, dict[str, Any]], None]


class FaultyBackend:
    """Wraps ``inner`` and injects ``faults`` (see the module docstring).

    Args:
        inner: the backend to wrap (already created, not yet reset).
        faults: the faults, in order.
        backend_name: the name ``inner`` was created under (for refusals).
        sink: where fault messages go (may be attached later with :meth:`attach`).
        state_source: returns the running step's name (for ``when`` triggers).

    Raises:
        FaultNotSupported: a fault ``inner`` cannot simulate.
    """

    def __init__(
        self,
        inner: Any,
        faults: Sequence[Fault],
        *,
        backend_name: str | None = None,
        sink: Sink | None = None,
        state_source: Callable[[], str | None] | None = None,
    ) -> None:
        self.inner = inner
        self.name: str = str(getattr(inner, "name", "backend"))
        self.faults = tuple(faults)
        self.state_source = state_source
        self._sink = sink
        self._pending: list[tuple[int, dict[str, Any]]] = []
        label = backend_name or self.name
        for i, f in enumerate(self.faults):
            reason = refusal(f, label)
            if reason is None:
                reason = self._missing_hook(f, label)
            if reason is not None:
                raise FaultNotSupported(label, f.kind, i, reason)
        self.schedule: FaultSchedule | None = None
        self.dt = 1e-3
        self._period_ns = 1_000_000
        self._history: deque[Measurement] = deque(maxlen=1)
        self._held: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._locks: dict[tuple[str, int], float] = {}
        self._true_q: dict[str, np.ndarray] = {}
        self._prev_q: dict[str, np.ndarray] = {}
        self._nan = False
        self._robots: tuple[str, ...] = ()

    def _missing_hook(self, fault: Fault, label: str) -> str | None:
        hook = {
            "grasp-slip": "inject_grasp_slip",
            "snag": "inject_snag",
        }.get(fault.kind)
        if fault.kind == "blow-up" and fault.mode == "energy":
            hook = "apply_external_force"
        if hook is not None and not callable(getattr(self.inner, hook, None)):
            return f"the {label} backend cannot simulate a {fault.kind} fault: it has no {hook}()"
        return None

    # ------------------------------------------------------------------ sink
    def attach(self, sink: Sink, state_source: Callable[[], str | None] | None = None) -> None:
        """Send fault messages to ``sink`` (the ones kept so far first)."""
        self._sink = sink
        if state_source is not None:
            self.state_source = state_source
        pending, self._pending = self._pending, []
        for time_ns, msg in pending:
            sink(time_ns, msg)

    def _emit(
        self, tick: int, onset: Onset, phase: str, extra: Mapping[str, Any] | None = None
    ) -> None:
        msg = fault_message(onset, phase, extra)
        time_ns = tick * self._period_ns
        if self._sink is None:
            self._pending.append((time_ns, msg))
        else:
            self._sink(time_ns, msg)

    # ------------------------------------------------------------------ protocol
    def reset(self, scene: Any, seed: int) -> Measurement:
        """Reset ``inner`` and the fault schedule (same seed, same faults)."""
        physics = getattr(scene, "physics", None)
        dt: Any = getattr(physics, "timestep", None) or getattr(self.inner, "dt", 1e-3)
        self.dt = float(dt)
        self._period_ns = round(1e9 * self.dt)
        self.schedule = FaultSchedule(self.faults, seed, self.dt)
        delays = [f.value or 0.0 for f in self.faults if f.kind == "delay"]
        depth = max([round(d / self.dt) for d in delays], default=0) + 1
        self._history = deque(maxlen=depth)
        self._held = {}
        self._locks = {}
        self._true_q = {}
        self._prev_q = {}
        self._nan = False
        self._pending = []
        first = self.inner.reset(scene, seed)
        self._robots = tuple(first.robots)
        return self._measure(first)

    def observe(self) -> Measurement:
        """The inner measurement with this tick's sensor faults."""
        return self._measure(self.inner.observe())

    def apply(self, command: Command) -> None:
        """Apply ``command`` with the active joint faults (weak torque, brake)."""
        schedule = self.schedule
        if schedule is None or not any(
            o.fault.kind in ("joint-lock", "joint-weak") for o in schedule.active
        ):
            self.inner.apply(command)
            return
        robots = dict(command.robots)
        for onset in schedule.active:
            f = onset.fault
            if f.kind not in ("joint-lock", "joint-weak") or f.joint is None:
                continue
            j = JOINTS.index(f.joint)
            for name in self._targets(f):
                rc = robots.get(name)
                if rc is None or rc.mode is not CommandMode.TORQUE or rc.tau is None:
                    continue
                tau = np.array(rc.tau, dtype=np.float64)
                if f.kind == "joint-weak":
                    tau[j] *= float(f.value or 0.0)
                else:
                    tau[j] = self._brake(name, j)
                robots[name] = RobotCommand.torque(tau, rc.tool)
        self.inner.apply(Command(robots))

    def step(self) -> None:
        """Push with the energy blow-ups, then advance ``inner`` one period."""
        schedule = self.schedule
        if schedule is not None:
            for onset in schedule.active:
                f = onset.fault
                if f.kind == "blow-up" and f.mode == "energy":
                    age = (schedule.tick - onset.start) * self.dt
                    mag = min(ENERGY_CAP_N, ENERGY_START_N * math.exp(age / ENERGY_GROWTH_S))
                    for name in self._targets(f):
                        # held two periods, at half the magnitude: the backends apply it
                        # in both steps (about ``mag`` on the arm), and a model-only backend
                        # that reads its forces at the measurement also measures it
                        self.inner.apply_external_force(name, (0.0, 0.0, 0.5 * mag), 2 * self.dt)
        self.inner.step()

    def geometry(self) -> SceneGeometry:
        """The inner backend's declared geometry."""
        result: SceneGeometry = self.inner.geometry()
        return result

    def ground_truth(self) -> Mapping[str, Any]:
        """The inner backend's ground truth (faults do not change the truth)."""
        result: Mapping[str, Any] = self.inner.ground_truth()
        return result

    def close(self) -> None:
        """Close the inner backend; idempotent."""
        self.inner.close()

    def __getattr__(self, name: str) -> Any:
        # everything else (apply_external_force, apply_operator_hand, exhausted, hooks, ...)
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    # ------------------------------------------------------------------ internals
    def _targets(self, fault: Fault) -> tuple[str, ...]:
        if fault.robot is None:
            return self._robots
        return (fault.robot,) if fault.robot in self._robots else ()

    def _brake(self, name: str, j: int) -> float:
        """The locked joint's torque: M_jj (omega^2 (q_lock - q) - 2 omega q') (4 joints)."""
        from suture_engine.robot import endobot

        q = self._true_q[name]
        q_lock = self._locks.get((name, j), float(q[j]))
        prev = self._prev_q.get(name, q)
        qd = (float(q[j]) - float(prev[j])) / self.dt
        m_jj = float(np.asarray(endobot.mass_matrix(q))[j, j])
        w = BRAKE_OMEGA
        return m_jj * (w * w * (q_lock - float(q[j])) - 2.0 * w * qd)

    def _onsets(self, meas: Measurement) -> None:
        schedule = self.schedule
        assert schedule is not None
        needs_state = any(f.when is not None for f in self.faults)
        state = self.state_source() if needs_state and self.state_source is not None else None
        started, ended = schedule.update(meas.tick, state)
        for onset in ended:
            self._emit(meas.tick, onset, "end")
            f = onset.fault
            if f.kind == "joint-lock" and f.joint is not None:
                for name in self._targets(f):
                    self._locks.pop((name, JOINTS.index(f.joint)), None)
        for onset in started:
            f = onset.fault
            extra: dict[str, Any] = {}
            if f.kind == "joint-lock" and f.joint is not None:
                j = JOINTS.index(f.joint)
                for name in self._targets(f):
                    self._locks[(name, j)] = float(meas.robots[name].q[j])
                    extra[f"q_lock_{name}"] = self._locks[(name, j)]
            elif f.kind == "grasp-slip":
                for name in self._targets(f):
                    held = self.inner.inject_grasp_slip(name)
                    if isinstance(held, bool):  # the surgical backend says if it held anything
                        extra[f"lost_{name}"] = held
            elif f.kind == "snag":
                duration = f.default_duration or 0.2
                self.inner.inject_snag(float(f.value or 0.0), duration)
            elif f.kind == "blow-up" and f.mode == "nan":
                self._nan = True
            self._emit(meas.tick, onset, "start", extra)

    def _measure(self, meas: Measurement) -> Measurement:
        self._history.append(meas)
        for name, r in meas.robots.items():
            self._prev_q[name] = self._true_q.get(name, r.q)
            self._true_q[name] = r.q
        self._onsets(meas)
        schedule = self.schedule
        assert schedule is not None
        if not schedule.active and not self._nan:
            self._held = {n: (r.q, r.base_wrench) for n, r in meas.robots.items()}
            return meas
        robots: dict[str, RobotMeasurement] = {}
        for name, r in meas.robots.items():
            q = np.array(r.q, dtype=np.float64)
            wrench = np.array(r.base_wrench, dtype=np.float64)
            flagged = r.fault
            sensor_onsets = [
                o
                for o in schedule.active
                if o.fault.sensor is not None and name in self._targets(o.fault)
            ]
            for o in sensor_onsets:
                if o.fault.kind == "delay":
                    q, wrench = self._delayed(o.fault, name, q, wrench)
            for o in sensor_onsets:
                if o.fault.kind in ("bias", "noise"):
                    q, wrench = self._offset(o, q, wrench)
            for o in sensor_onsets:
                if o.fault.kind == "dropout":
                    held_q, held_w = self._held.get(name, (q, wrench))
                    if o.fault.sensor == "ft":
                        wrench = np.array(held_w, dtype=np.float64)
                    else:
                        q = np.array(held_q, dtype=np.float64)
                    flagged = True
            if self._nan:
                q = np.full(4, np.nan)
                wrench = np.full(6, np.nan)
            robots[name] = RobotMeasurement(q, wrench, r.tool, flagged)
            self._held[name] = (robots[name].q, robots[name].base_wrench)
        return Measurement(meas.tick, meas.t, robots)

    def _delayed(
        self, fault: Fault, name: str, q: np.ndarray, wrench: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        ticks = round((fault.value or 0.0) / self.dt)
        old = self._history[max(0, len(self._history) - 1 - ticks)].robots[name]
        if fault.sensor == "ft":
            return q, np.array(old.base_wrench, dtype=np.float64)
        return np.array(old.q, dtype=np.float64), wrench

    def _offset(
        self, onset: Onset, q: np.ndarray, wrench: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        f = onset.fault
        assert self.schedule is not None
        value = float(f.value or 0.0)
        if f.sensor == "ft":
            if f.kind == "bias":
                wrench[{"x": 0, "y": 1, "z": 2}[f.axis]] += value
            else:
                wrench[:3] += self.schedule.noise_rng(onset.index).normal(0.0, value, 3)
            return q, wrench
        joints = [JOINTS.index(f.joint)] if f.joint is not None else [0, 1, 2]
        if f.kind == "bias":
            q[joints] += value
        else:
            q[joints] += self.schedule.noise_rng(onset.index).normal(0.0, value, len(joints))
        return q, wrench
