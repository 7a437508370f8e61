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
        [--max-time 300] [--procedure procedures/square-knot.yaml] [--profile DIR]
        [--set stitch=true ...]

``--profile DIR`` also writes a pyinstrument text profile of each run to DIR.
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
) -> Split:
    """Run ``procedure`` on ``backend`` (parameters overridden by ``sets``) and split its
    time."""
    from suture_engine.runtime.run import run_procedure

    physics, io, simulator = _Clock(), _Clock(), _Clock()
    state: dict[str, Any] = {}

    def on_tick(interp: Any) -> None:
        # Called after each tick's trace record, before apply and step: the first call
        # wraps the backend (instance attributes shadow its methods).
        if "wrapped" in state:
            return
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
    ap.add_argument("--max-time", type=float, default=300.0, help="simulated time limit [s]")
    ap.add_argument("--profile", type=Path, default=None, help="write pyinstrument profiles here")
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
        print(report(run(args.procedure, backend, args.max_time, args.profile, args.sets)))


if __name__ == "__main__":
    main()
