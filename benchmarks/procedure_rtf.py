"""Real-time factor of a bundled procedure, and how its wall time splits between physics
and engine.

Runs ``suture run procedures/square-knot.yaml`` in process (``run_procedure``, trace
and summary written as usual) on each backend asked for, and times, per call, what the
backend does: ``step`` (the simulator's integration: PyBullet's ``stepSimulation`` and
the backend's per-step work such as the thread's joints) and the measurement interface
(``observe``, ``apply``, ``ground_truth``). Everything else in the run's tick loop is
the engine: interpreter, skill, QP, monitor, controllers, trace writing.

Printed per backend: simulated time, wall time of the tick loop, real-time factor
(simulated / wall), and the shares of the wall time (and of the process's CPU time,
steadier when other jobs share the machine) spent in physics, in the measurement
interface and in the engine. Pin it to one core on a shared machine:

    taskset -c 1 python benchmarks/procedure_rtf.py [--backend pybullet ...]
        [--max-time 600] [--procedure procedures/square-knot.yaml] [--profile DIR]
        [--set stitch=true ...]

``--profile DIR`` also writes a pyinstrument text profile of each run to DIR.

``--simulator-steps N`` also records PyBullet's own timings (its Chrome-trace state log)
over the run's first N physics steps, and prints where a step's time goes inside
``stepSimulation``: the constraint solver, collision detection (AABB update, broadphase,
narrowphase), the multibody integration, and how many contact and friction constraints
a step sets up. PyBullet's log buffer holds about a million events, some 1200 steps of
the thread scene; a longer window is cut where the buffer ends.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

ROOT = Path(__file__).resolve().parent.parent


class Split(NamedTuple):
    """Where one run's time went.

    Attributes:
        backend: backend name.
        outcome: the run's outcome.
        sim_s: simulated time [s].
        wall_s: wall time of the tick loop [s].
        cpu_s: CPU time of the process over the tick loop [s].
        physics_wall_s: wall time in ``backend.step`` [s].
        physics_cpu_s: CPU time in ``backend.step`` [s].
        io_wall_s: wall time in ``observe``, ``apply`` and ``ground_truth`` [s].
        io_cpu_s: CPU time in them [s], ground-truth look-ups included.
        ticks: ticks run.
        simulator_wall_s: wall time in PyBullet's ``stepSimulation`` alone (part of
            ``physics_wall_s``; the rest is the backend's own per-step work) [s].
        simulator_cpu_s: CPU time in it [s].
        phases: inside ``stepSimulation`` over the first steps, from PyBullet's own
            timing log (``--simulator-steps``), or None.
    """

    backend: str
    outcome: str
    sim_s: float
    wall_s: float
    cpu_s: float
    physics_wall_s: float
    physics_cpu_s: float
    io_wall_s: float
    io_cpu_s: float
    ticks: int
    simulator_wall_s: float = 0.0
    simulator_cpu_s: float = 0.0
    phases: SimulatorPhases | None = None


SIMULATOR_PHASES: tuple[tuple[str, str], ...] = (
    ("internalSingleStepSimulation", "one physics step (all of it)"),
    ("processIslands", "  constraint solver (islands)"),
    ("solveGroupCacheFriendlySetup", "    set-up of the constraints"),
    ("solveGroupCacheFriendlyIterations", "    iterations"),
    ("performDiscreteCollisionDetection", "  collision detection"),
    ("updateAabbs", "    bounding boxes (AABB update)"),
    ("calculateOverlappingPairs", "    broadphase pairs"),
    ("dispatchAllCollisionPairs", "    narrowphase (contact points)"),
    ("btMultiBody stepVelocities", "  multibody velocities"),
    ("btMultiBody stepPositions", "  multibody positions"),
    ("calculateSimulationIslands", "  islands"),
)
"""PyBullet's timing scopes shown, in the order printed, with what each is."""

_COUNTED = {
    "setupMultiBodyContactConstraint": "contact constraints",
    "addMultiBodyFrictionConstraint": "friction constraints",
}


class SimulatorPhases(NamedTuple):
    """Where PyBullet's physics steps spent their time, from its timing log.

    Attributes:
        steps: physics steps in the log (``internalSingleStepSimulation`` scopes).
        us_per_step: per timing scope of :data:`SIMULATOR_PHASES`, its total time over
            the log per step [us].
        per_step: per counted scope (contact and friction constraints set up), its
            calls per step.
    """

    steps: int
    us_per_step: dict[str, float]
    per_step: dict[str, float]


def simulator_phases(path: Path) -> SimulatorPhases:
    """Read a PyBullet ``STATE_LOGGING_PROFILE_TIMINGS`` file (Chrome trace events).

    Every scope is written as a ``B`` event and its ``E`` event, its name suffixed with
    a running counter; a scope's time is its ``E`` minus its ``B`` timestamp [us]. When
    PyBullet's buffer fills, it writes the events it holds, a whole file.

    Args:
        path: the log file (PyBullet appends ``_0.json`` to the name it is given).

    Raises:
        ValueError: the file holds no physics step.
    """
    import json
    import re

    events = json.loads(path.read_text())["traceEvents"]
    suffix = re.compile(r"\d+$")
    totals: dict[str, float] = {}
    calls: dict[str, int] = {}
    begun: dict[str, float] = {}
    for e in events:
        name = suffix.sub("", str(e.get("name", "")))
        if e.get("ph") == "B":
            begun[name] = float(e["ts"])
        elif e.get("ph") == "E" and name in begun:
            totals[name] = totals.get(name, 0.0) + float(e["ts"]) - begun.pop(name)
            calls[name] = calls.get(name, 0) + 1
    steps = calls.get("internalSingleStepSimulation", 0)
    if steps == 0:
        raise ValueError(f"{path}: no physics step in the timing log")
    return SimulatorPhases(
        steps=steps,
        us_per_step={n: totals.get(n, 0.0) / steps for n, _ in SIMULATOR_PHASES},
        per_step={label: calls.get(n, 0) / steps for n, label in _COUNTED.items()},
    )


def phases_report(phases: SimulatorPhases) -> str:
    """The breakdown of a physics step, as printed."""
    whole = phases.us_per_step["internalSingleStepSimulation"] or float("nan")
    lines = [f"  inside stepSimulation, {phases.steps} physics steps (PyBullet's timing log):"]
    for name, label in SIMULATOR_PHASES:
        us = phases.us_per_step[name]
        lines.append(f"    {label:<36s}: {us:7.1f} us per step ({100 * us / whole:5.1f} %)")
    counts = ", ".join(f"{v:.1f} {k}" for k, v in phases.per_step.items())
    lines.append(f"    set up per step: {counts}")
    return "\n".join(lines)


class _TimedTruth(Mapping[str, Any]):
    """A backend's ground truth whose look-ups are timed by ``clock``."""

    def __init__(self, truth: Mapping[str, Any], clock: _Clock) -> None:
        self._truth = truth
        self._get = clock.wrap(truth.__getitem__)

    def __getitem__(self, key: str) -> Any:
        return self._get(key)

    def __iter__(self) -> Iterator[str]:
        return iter(self._truth)

    def __len__(self) -> int:
        return len(self._truth)


class _TimedSimulator:
    """The simulator module as the backend sees it, with ``stepSimulation`` timed."""

    def __init__(self, module: Any, clock: _Clock) -> None:
        self._module = module
        self.stepSimulation = clock.wrap(module.stepSimulation)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._module, name)


class _Clock:
    """Accumulates wall and CPU time of the wrapped calls."""

    def __init__(self) -> None:
        self.wall_ns = 0
        self.cpu_ns = 0

    def wrap(self, fn: Callable[..., Any]) -> Callable[..., Any]:
        wall, cpu = time.perf_counter_ns, time.thread_time_ns

        def timed(*args: Any, **kwargs: Any) -> Any:
            w0, c0 = wall(), cpu()
            try:
                return fn(*args, **kwargs)
            finally:
                self.cpu_ns += cpu() - c0
                self.wall_ns += wall() - w0

        return timed


def run(
    procedure: Path,
    backend: str,
    max_time_s: float,
    profile_dir: Path | None,
    sets: Sequence[str] = (),
    simulator_steps: int = 0,
) -> Split:
    """Run ``procedure`` on ``backend`` (parameters overridden by ``sets``) and split its
    time; with ``simulator_steps`` > 0, PyBullet's timing log over that many first ticks
    too (a backend with a PyBullet ``client``)."""
    from suture_engine.runtime.run import run_procedure

    physics, io, simulator = _Clock(), _Clock(), _Clock()
    state: dict[str, Any] = {"ticks": 0}
    log_dir = tempfile.TemporaryDirectory() if simulator_steps > 0 else None

    def stop_log(be: Any) -> None:
        if "log" in state:
            import pybullet

            pybullet.stopStateLogging(state.pop("log"), physicsClientId=be.client)

    def on_tick(interp: Any) -> None:
        # Called after each tick's trace record, before apply and step: the first call
        # wraps the backend (instance attributes shadow its methods).
        state["ticks"] += 1
        if state["ticks"] == simulator_steps + 1:
            stop_log(interp.backend)
        if "wrapped" in state:
            return
        if log_dir is not None and getattr(interp.backend, "client", None) is not None:
            import pybullet

            be = interp.backend
            state["log"] = pybullet.startStateLogging(
                pybullet.STATE_LOGGING_PROFILE_TIMINGS,
                str(Path(log_dir.name) / "timings"),
                physicsClientId=be.client,
            )
            # a run that ends inside the window: the log is written before the client goes
            close = be.close

            def close_after_log() -> None:
                stop_log(be)
                close()

            be.close = close_after_log
        be = interp.backend
        be.step = physics.wrap(be.step)
        for name in ("observe", "apply"):
            setattr(be, name, io.wrap(getattr(be, name)))
        truth = be.ground_truth
        # The ground truth is read when the trace looks a value up (lazily): time the
        # look-ups, not only the call that hands out the mapping.
        be.ground_truth = io.wrap(lambda: _TimedTruth(truth(), io))
        sim = getattr(be, "_p", None)
        if sim is not None:
            be._p = _TimedSimulator(sim, simulator)
        state["wrapped"] = True
        state["cpu0"] = time.process_time()
        state["interp"] = interp

    profiler = None
    if profile_dir is not None:
        from pyinstrument import Profiler

        profiler = Profiler(interval=0.0005)
        profiler.start()
    with tempfile.TemporaryDirectory() as tmp:
        result = run_procedure(
            procedure,
            backend=backend,
            out=Path(tmp) / "run",
            max_time_s=max_time_s,
            on_tick=on_tick,
            sets=sets,
        )
        cpu = time.process_time() - state["cpu0"]
    if profiler is not None and profile_dir is not None:
        profiler.stop()
        profile_dir.mkdir(parents=True, exist_ok=True)
        text = profiler.output_text(unicode=False, color=False)
        (profile_dir / f"procedure_rtf_{backend}.txt").write_text(text)
    phases = None
    if log_dir is not None:
        written = sorted(Path(log_dir.name).glob("timings*.json"))
        if written:
            phases = simulator_phases(written[0])
        log_dir.cleanup()
    s = result.summary
    return Split(
        backend=backend,
        outcome=s.outcome,
        sim_s=s.sim_time_s,
        wall_s=s.wall_time_s,
        cpu_s=cpu,
        physics_wall_s=physics.wall_ns / 1e9,
        physics_cpu_s=physics.cpu_ns / 1e9,
        io_wall_s=io.wall_ns / 1e9,
        io_cpu_s=io.cpu_ns / 1e9,
        ticks=s.ticks,
        simulator_wall_s=simulator.wall_ns / 1e9,
        simulator_cpu_s=simulator.cpu_ns / 1e9,
        phases=phases,
    )


def report(split: Split) -> str:
    """The figures of one run, as printed."""
    s = split
    engine_wall = s.wall_s - s.physics_wall_s - s.io_wall_s
    engine_cpu = s.cpu_s - s.physics_cpu_s - s.io_cpu_s
    lines = [
        f"backend {s.backend}: {s.outcome}, {s.sim_s:.1f} s simulated in {s.wall_s:.1f} s wall "
        f"({s.cpu_s:.1f} s CPU), {s.ticks} ticks",
        f"  real-time factor: {s.sim_s / s.wall_s:.2f}x wall, {s.sim_s / s.cpu_s:.2f}x CPU"
        "   (target >= 3x)",
        "  share of wall / CPU time:",
        f"    physics (backend.step)                 : {100 * s.physics_wall_s / s.wall_s:5.1f} %"
        f" / {100 * s.physics_cpu_s / s.cpu_s:5.1f} %",
        f"      of which PyBullet's stepSimulation   : {100 * s.simulator_wall_s / s.wall_s:5.1f} %"
        f" / {100 * s.simulator_cpu_s / s.cpu_s:5.1f} %",
        f"    measurement interface (observe, apply, : {100 * s.io_wall_s / s.wall_s:5.1f} %"
        f" / {100 * s.io_cpu_s / s.cpu_s:5.1f} %",
        "      ground-truth look-ups)",
        f"    engine (everything else)               : {100 * engine_wall / s.wall_s:5.1f} %"
        f" / {100 * engine_cpu / s.cpu_s:5.1f} %   (target <= 15 %)",
        f"  per tick, CPU: engine {1e6 * engine_cpu / max(s.ticks, 1):.0f} us;"
        f" physics {1e6 * s.physics_cpu_s / max(s.ticks, 1):.0f} us"
        f" (stepSimulation {1e6 * s.simulator_cpu_s / max(s.ticks, 1):.0f} us);"
        f" measurement interface {1e6 * s.io_cpu_s / max(s.ticks, 1):.0f} us",
    ]
    if s.phases is not None:
        lines.append(phases_report(s.phases))
    return "\n".join(lines)


def main() -> None:
    """Parse the options, run, print."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--procedure", type=Path, default=ROOT / "procedures" / "square-knot.yaml")
    ap.add_argument(
        "--backend",
        action="append",
        help="backend name (repeatable; default: pybullet and pybullet-surgical)",
    )
    ap.add_argument("--max-time", type=float, default=600.0, help="simulated time limit [s]")
    ap.add_argument("--profile", type=Path, default=None, help="write pyinstrument profiles here")
    ap.add_argument(
        "--simulator-steps",
        type=int,
        default=0,
        help="record PyBullet's own timings over this many first physics steps and print"
        " where a step's time goes (about 1200 fit its log on the thread scene; the"
        " logging slows those steps, so read the shares)",
    )
    ap.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        help="name=value parameter override (repeatable), as `suture run --set`",
    )
    args = ap.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{args.procedure.name}, max {args.max_time:g} s simulated; load average {load:.2f}")
    for backend in args.backend or ["pybullet", "pybullet-surgical"]:
        split = run(
            args.procedure, backend, args.max_time, args.profile, args.sets, args.simulator_steps
        )
        print(report(split))


if __name__ == "__main__":
    main()
