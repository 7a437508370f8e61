"""What one engine tick costs on the replay backend, with move-constrained active.

1. Records ``tests/procedures/constrained.yaml`` (an insertion along a line fixture
   with the suture extension-rate row, on OSQP) on the PyBullet backend.
2. Replays it (no physics) and times every tick of the interpreter while the
   move-constrained step runs: observe (recorded measurements + washout filter)
   -> skill (one warm-started OSQP solve) -> monitor -> mode controller (PD with
   gravity and friction compensation) -> apply -> trace. Twice: writing the trace,
   and with the trace off (engine alone).
3. Solves the same per-tick QP (the skill's own P, q, A, l, u of that tick) with a
   parametrised cvxpy problem compiled once, and compares.

Prints median and p99 [us]. Usage (pinned to one core on a shared machine):

    taskset -c 1 python benchmarks/tick_overhead.py [--repeats 3] [--profile DIR]

``--profile DIR`` also writes a pyinstrument profile of one replay pass with the trace
on (``DIR/tick_overhead.txt``).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

import suture_engine  # noqa: F401 (first: it pins OpenBLAS' kernel before numpy loads)

# isort: split
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
PROCEDURE = ROOT / "tests" / "procedures" / "constrained.yaml"


SKILL_NS: list[int] = []
"""CPU time of the skill's step (move-constrained, its QP included) in the last replay [ns]."""


def _stats(ns: list[int]) -> tuple[float, float]:
    us = np.asarray(ns, dtype=float) / 1e3
    return float(np.median(us)), float(np.percentile(us, 99))


REPEATS = 3
"""Interleaved passes with and without the trace; the best (lowest CPU median) is shown."""

STAGES: dict[str, list[int]] = {}
"""CPU time per stage of the tick in the last replay with ``stages=True`` [ns]."""


def _timed(fn: Any, bucket: list[int]) -> Any:
    clock = time.thread_time_ns

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = clock()
        try:
            return fn(*args, **kwargs)
        finally:
            bucket.append(clock() - t0)

    return wrapper


def _instrument(interp: Any, skill: Any) -> None:
    """Time the tick's stages (instance attributes shadow the methods; a separate pass)."""
    targets = [
        ("observe (backend + washout filter)", interp, "_observe"),
        ("tension estimate", interp.tension, "estimate"),
        ("controller (PD + gravity + friction)", interp.controller, "torque"),
        ("monitor", interp.monitor, "check"),
        ("trace: per-tick channels", interp.recorder, "tick"),
        ("trace: /qp channel", interp.recorder, "qp"),
        ("skill: whole step", skill, "step"),
        ("skill: QP solve (assembly + OSQP + result)", skill._qp, "solve"),
        ("skill: QP assembly in Python", skill._qp, "_assemble"),
        ("skill: QP result (clip, active rows)", skill._qp, "_finish"),
    ]
    for label, obj, name in targets:
        STAGES[label] = []
        setattr(obj, name, _timed(getattr(obj, name), STAGES[label]))


def _replay(
    trace: Path,
    out: Path | None,
    cvx: Any = None,
    stages: bool = False,
    fast: bool = True,
    recorder_factory: Any = None,
) -> tuple[list[int], list[int], list[int]]:
    from backends.replay import ReplayBackend
    from suture_engine.runtime.interpreter import Interpreter
    from suture_engine.runtime.recorder import Recorder, TraceRecorder
    from suture_engine.runtime.run import load_plan

    proc, plan = load_plan(PROCEDURE)
    be = ReplayBackend(trace)
    first = be.reset(proc.scene, 0)
    recorder: Recorder = Recorder()
    if recorder_factory is not None:
        recorder = recorder_factory(
            procedure=proc.name,
            seed=0,
            control_rate_hz=be.rate,
            robots=be.robots,
            backend="replay",
            params={},
        )
    elif out is not None:
        recorder = TraceRecorder(
            out,
            procedure=proc.name,
            seed=0,
            control_rate_hz=be.rate,
            robots=be.robots,
            backend="replay",
            params={},
            fast=fast,
        )
    interp = Interpreter(
        plan,
        be,
        first,
        roles=proc.roles,
        params=proc.params,
        scene=proc.scene,
        control_rate_hz=be.rate,
        recorder=recorder,
        max_time_s=float("inf"),
    )
    ticks: list[int] = []
    cpu: list[int] = []
    cvx_ns: list[int] = []
    clock = time.perf_counter_ns
    cpu_clock = time.thread_time_ns
    skill_ns: list[int] = []

    def timed(step: Any) -> Any:
        def wrapper(ctx: Any, obs: Any) -> Any:
            s0 = cpu_clock()
            out = step(ctx, obs)
            skill_ns.append(cpu_clock() - s0)
            return out

        return wrapper

    while True:
        active = interp.automaton.step_name == "insert"
        skill = interp.automaton.active_skill
        if skill is not None and not hasattr(skill, "_timed"):
            if stages and active:
                _instrument(interp, skill)
            else:
                skill.step = timed(skill.step)
            skill._timed = True
        c0 = cpu_clock()
        t0 = clock()
        going = interp.tick()
        dt = clock() - t0
        dc = cpu_clock() - c0
        if active and interp.automaton.step_name == "insert":
            ticks.append(dt)
            cpu.append(dc)
            if cvx is not None:
                qp = interp.automaton.active_skill._qp
                cvx_ns.append(cvx(qp))
        if not going:
            break
    recorder.close()
    SKILL_NS[:] = skill_ns
    return ticks, cpu, cvx_ns


def _paired_recorders(trace: Path, tmp: Path) -> tuple[list[int], list[int]]:
    """CPU time per tick of the recorder's fast and generic paths, paired: each tick's
    calls go to both recorders (alternating which goes first), so both see the same
    machine load. Returns (fast, generic) [ns per tick, /qp message included]."""
    from suture_engine.runtime.recorder import Recorder, TraceRecorder

    clock = time.thread_time_ns
    made: list[Any] = []

    class Paired(Recorder):
        def __init__(self, **kwargs: Any) -> None:
            self.fast = TraceRecorder(tmp / "paired-fast.mcap", fast=True, **kwargs)
            self.slow = TraceRecorder(tmp / "paired-generic.mcap", fast=False, **kwargs)
            self.ns: tuple[list[int], list[int]] = ([], [])
            self.acc = [0, 0]
            self.k = 0
            made.append(self)

        def _both(self, name: str, *args: Any) -> None:
            order = (0, 1) if self.k % 2 else (1, 0)
            for i in order:
                rec = self.fast if i == 0 else self.slow
                t0 = clock()
                getattr(rec, name)(*args)
                self.acc[i] += clock() - t0

        def qp(self, *args: Any) -> None:
            self._both("qp", *args)

        def transition(self, *args: Any) -> None:
            self._both("transition", *args)

        def event(self, *args: Any) -> None:
            self._both("event", *args)

        def operator(self, *args: Any) -> None:
            self._both("operator", *args)

        def tick(self, *args: Any) -> None:
            self._both("tick", *args)
            self.k += 1
            for i in (0, 1):
                self.ns[i].append(self.acc[i])
            self.acc = [0, 0]

        def close(self) -> None:
            self.fast.close()
            self.slow.close()

    _replay(trace, None, recorder_factory=Paired)
    pair = made[-1]
    same = (tmp / "paired-fast.mcap").read_bytes() == (tmp / "paired-generic.mcap").read_bytes()
    if not same:
        raise SystemExit("the recorder's fast and generic paths wrote different files")
    return pair.ns[0][5:], pair.ns[1][5:]


def _cvxpy_twin() -> Any:
    """A cvxpy QP with the skill's shape, compiled on first use, re-solved per tick."""
    import cvxpy as cp

    state: dict[str, Any] = {}

    def solve(qp: Any) -> int:
        P, q, A, lo, hi = qp.matrices()
        if not state:
            n, m = P.shape[0], A.shape[0]
            z = cp.Variable(n)
            L, qq, AA = cp.Parameter((n, n)), cp.Parameter(n), cp.Parameter((m, n))
            lp, up = cp.Parameter(m), cp.Parameter(m)
            cost = 0.5 * cp.sum_squares(L @ z) + qq @ z
            prob = cp.Problem(cp.Minimize(cost), [AA @ z >= lp, AA @ z <= up])
            state.update(prob=prob, L=L, q=qq, A=AA, l=lp, u=up)
        t0 = time.perf_counter_ns()
        state["L"].value = np.linalg.cholesky(P + 1e-12 * np.eye(P.shape[0])).T
        state["q"].value = q
        state["A"].value = A
        state["l"].value = np.maximum(lo, -1e4)
        state["u"].value = np.minimum(hi, 1e4)
        state["prob"].solve(solver=cp.OSQP, warm_start=True)
        return time.perf_counter_ns() - t0

    return solve


def _profile(trace: Path, out: Path, profile_dir: Path) -> None:
    """A pyinstrument profile of one replay pass with the trace on."""
    from pyinstrument import Profiler

    profiler = Profiler(interval=0.0002)
    profiler.start()
    _replay(trace, out)
    profiler.stop()
    profile_dir.mkdir(parents=True, exist_ok=True)
    text = profiler.output_text(unicode=False, color=False)
    (profile_dir / "tick_overhead.txt").write_text(text)


def main() -> None:
    """Record, replay twice, compare with cvxpy; print the figures."""
    import argparse
    import os

    from suture_engine.runtime.run import run_procedure

    global REPEATS
    ap = argparse.ArgumentParser(description="engine tick cost on the replay backend")
    ap.add_argument("--repeats", type=int, default=REPEATS, help="interleaved pass pairs")
    ap.add_argument("--profile", type=Path, default=None, help="write a pyinstrument profile")
    args = ap.parse_args()
    if args.profile is not None:
        try:
            import pyinstrument  # noqa: F401
        except ImportError:
            ap.error("--profile needs pyinstrument: pip install -e '.[bench]'")
    REPEATS = max(1, args.repeats)
    load0 = os.getloadavg()[0]

    with tempfile.TemporaryDirectory() as tmp:
        rec = run_procedure(PROCEDURE, backend="pybullet", out=Path(tmp) / "rec")
        trace = rec.trace
        _replay(trace, None)  # warm-up: imports, first-call costs
        # The pair of passes is repeated (interleaved) and the pass with the lowest CPU
        # median kept: on a shared machine one pass can run at half speed throughout.
        runs_tr, runs_en, runs_gen = [], [], []
        for _ in range(REPEATS):
            runs_tr.append(_replay(trace, Path(tmp) / "replay.mcap"))
            runs_en.append((*_replay(trace, None)[:2], list(SKILL_NS)))
            runs_gen.append(_replay(trace, Path(tmp) / "generic.mcap", fast=False))
        with_trace, with_trace_cpu, _ = min(runs_tr, key=lambda r: _stats(r[1])[0])
        engine, engine_cpu, skill_cpu = min(runs_en, key=lambda r: _stats(r[1])[0])
        generic_cpu = min(runs_gen, key=lambda r: _stats(r[1])[0])[1]
        spread = [_stats(r[1])[0] for r in runs_tr], [_stats(r[1])[0] for r in runs_en]
        paired_fast, paired_generic = _paired_recorders(trace, Path(tmp))
        _replay(trace, Path(tmp) / "stages.mcap", stages=True)
        if args.profile is not None:
            _profile(trace, Path(tmp) / "profile.mcap", args.profile)
        try:
            _, _, cvx = _replay(trace, None, _cvxpy_twin())
        except ImportError:
            cvx = []
    m_tr, p_tr = _stats(with_trace)
    m_en, p_en = _stats(engine)
    print(f"engine tick on the replay backend, move-constrained active ({len(engine)} ticks)")
    load1 = os.getloadavg()[0]
    print(f"load average {load0:.2f} at the start, {load1:.2f} at the end (2 CPUs)")
    print(f"best of {REPEATS} interleaved passes; CPU medians of every pass [us]:")
    print("  with trace: " + ", ".join(f"{v:.1f}" for v in spread[0]))
    print("  trace off : " + ", ".join(f"{v:.1f}" for v in spread[1]))
    print("wall clock:")
    print(f"  with trace writing : median {m_tr:7.1f} us   p99 {p_tr:7.1f} us")
    print(f"  trace off          : median {m_en:7.1f} us   p99 {p_en:7.1f} us")
    print("CPU time of the thread (insensitive to other processes on a loaded machine):")
    for label, ns in (("with trace writing", with_trace_cpu), ("trace off", engine_cpu)):
        m, p = _stats(ns)
        print(f"  {label:19s}: median {m:7.1f} us   p99 {p:7.1f} us")
    m, p = _stats(generic_cpu)
    print(f"  trace, generic path: median {m:7.1f} us   p99 {p:7.1f} us (the recorder's fast")
    print("                       path off: a dict per message through the json module)")
    m_f, p_f = _stats(paired_fast)
    m_g, p_g = _stats(paired_generic)
    print("trace writing alone, both recorder paths on the same ticks (paired, CPU):")
    print(f"  fast path   : median {m_f:7.1f} us   p99 {p_f:7.1f} us per tick (same file)")
    print(f"  generic path: median {m_g:7.1f} us   p99 {p_g:7.1f} us per tick")
    m, p = _stats(skill_cpu)
    print(f"  of which skill.step: median {m:7.1f} us   p99 {p:7.1f} us (move-constrained + QP)")
    print("CPU time per stage, a separate instrumented pass with the trace on (sums of")
    print("the calls in one tick are not shown; each line is per call):")
    for label, ns in STAGES.items():
        if ns:
            m, p = _stats(ns)
            print(f"  {label:44s}: median {m:7.1f} us   p99 {p:7.1f} us   ({len(ns)} calls)")
    if cvx:
        m_cv, p_cv = _stats(cvx)
        print(f"  cvxpy QP alone     : median {m_cv:7.1f} us   p99 {p_cv:7.1f} us")
        print(f"  cvxpy QP / engine tick with trace: {m_cv / m_tr:.1f}x (median)")
    else:
        print("  cvxpy not installed (pip install -e '.[bench]'): no comparison")
    print("targets: median <= 60 us, p99 <= 250 us, >= 25x faster than the cvxpy tick")


if __name__ == "__main__":
    main()
