"""``suture run`` and ``suture replay``: load, compile, run, write the trace and summary.

:func:`run_procedure` loads a procedure (with ``--set`` overrides of its
parameters), compiles it, resets the backend with the scene and the seed, runs
the interpreter and writes ``trace.mcap`` and ``summary.json`` into the output
folder. :func:`replay_trace` re-runs the engine against a recorded trace's
measurements (the replay backend) and, with ``check``, compares the new
commands and events with the recorded ones within explicit tolerances.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from suture_engine.errors import SutureError
from suture_engine.runtime.calibration import calibration_offsets
from suture_engine.runtime.summary import RunSummary, write_summary

__all__ = [
    "COMPARED_TOPICS",
    "OPERATOR_PARAM",
    "ProcedureLoadError",
    "ReplayResult",
    "RunResult",
    "SetOverrideError",
    "declared_operator_file",
    "load_plan",
    "replay_trace",
    "run_procedure",
]

COMPARED_TOPICS = (
    "/command/*",
    "/events",
    "/transitions",
    "/operator",
    "/joint_state/*",
    "/tension/estimated",
)
"""What ``replay --check`` compares: the engine's outputs and its velocity estimates."""


class ProcedureLoadError(SutureError):
    """The procedure does not load or compile; ``problems`` carry the located messages.

    Attributes:
        problems: located problems (``file:line:col: code: message`` strings).
    """

    code = "invalid-procedure"

    def __init__(self, problems: Sequence[str]) -> None:
        super().__init__("\n".join(problems))
        self.problems = list(problems)


class SetOverrideError(SutureError):
    """A ``--set`` that is a usage error: not ``name=value``, or a name the procedure lacks.

    A value the parameter's declaration refuses is not this error: it is a located
    :class:`ProcedureLoadError` (invalid input), as in ``suture validate --set``.

    Attributes:
        text: the option as given.
        available: the procedure's parameter names.
        where: ``file:line:col`` of the procedure's ``params`` ("" when unknown).
    """

    code = "bad-set"

    def __init__(
        self, text: str, message: str, available: Sequence[str] = (), where: str = ""
    ) -> None:
        hint = f" (parameters: {', '.join(available)})" if available else ""
        super().__init__(f"{where + ': ' if where else ''}--set {text}: {message}{hint}")
        self.text = text
        self.available = list(available)
        self.where = where


@dataclass(frozen=True)
class RunResult:
    """A finished run.

    Attributes:
        summary: the run's summary.
        out_dir: the output folder.
        trace: the trace file.
        summary_path: the summary file.
    """

    summary: RunSummary
    out_dir: Path
    trace: Path
    summary_path: Path


@dataclass(frozen=True)
class ReplayResult:
    """A replay.

    Attributes:
        summary: the replayed run's summary.
        trace: the trace the replay wrote.
        ok: True when the check passed (or no check was asked).
        diff: the readable comparison text ("" without a check).
        ticks: ticks replayed.
        truncated: the recording ended early (a killed run).
    """

    summary: RunSummary
    trace: Path
    ok: bool
    diff: str
    ticks: int
    truncated: bool


def _parse_sets(sets: Sequence[str]) -> dict[str, Any] | None:
    """``--set`` options as parameter values, read exactly as ``suture validate`` reads them."""
    from suture_engine.validation.report import parse_sets

    if not sets:
        return None
    for text in sets:
        name, sep, _ = text.partition("=")
        if not sep or not name.strip():
            raise SetOverrideError(text, "expected name=value")
    try:
        return parse_sets(sets)
    except ValueError as exc:  # pragma: no cover - the loop above refuses the same texts
        raise SetOverrideError(", ".join(sets), str(exc)) from None


def _unknown_set(result: Any, sets: Sequence[str]) -> SetOverrideError | None:
    """The first ``--set`` naming no parameter (the loader reports it at ``params``)."""
    for p in result.problems:
        if getattr(p, "code", "") != "unknown-param" or "(override)" not in p.message:
            continue
        name = str(p.path).removeprefix("params.")
        text = next((t for t in sets if t.partition("=")[0].strip() == name), name)
        names = list(result.procedure.params) if result.procedure is not None else []
        where = f"{p.file}:{p.line}:{p.column}"
        return SetOverrideError(text, f"no parameter named {name!r}", names, where)
    return None


def _compile_problems(file: Path, params: dict[str, Any] | None, message: str) -> list[str]:
    """Located problems for a procedure that loads but does not compile.

    The automaton's compiler knows state names, not lines: the validator's semantic
    checks locate the same faults in the file. When they find none, the compiler's
    message is given at the file.
    """
    from suture_engine.validation.checks import validate_file

    located = [p.format() for p in validate_file(file, params=params) if p.line]
    return located or [f"{file}: automaton-error: {message}"]


def load_plan(path: str | Path, sets: Sequence[str] = ()) -> tuple[Any, Any]:
    """Load and compile a procedure, with ``--set name=value`` overrides of its parameters.

    The overrides are checked by the language's loader, exactly as ``suture validate
    --set`` checks them: a value the declaration refuses is located at the parameter.

    Returns:
        (the loaded procedure, its :class:`~suture_engine.runtime.automaton.Plan`).

    Raises:
        ProcedureLoadError: loading problems or a compile error (located).
        SetOverrideError: a ``--set`` that is not ``name=value`` or names no parameter.
    """
    from suture_engine.language.loader import load
    from suture_engine.runtime.automaton import AutomatonError
    from suture_engine.runtime.plan import compile_procedure

    file = Path(path)
    if not file.is_file():
        raise ProcedureLoadError([f"{path}: no such file"])
    params = _parse_sets(sets)
    result = load(file, params=params)
    unknown = _unknown_set(result, sets)
    if unknown is not None:
        raise unknown
    if result.problems or result.procedure is None:
        raise ProcedureLoadError(
            [p.format() if hasattr(p, "format") else str(p) for p in result.problems]
            or [f"{path}: not a procedure"]
        )
    try:
        plan = compile_procedure(result.procedure)
    except AutomatonError as exc:
        raise ProcedureLoadError(_compile_problems(file, params, exc.message)) from None
    return result.procedure, plan


OPERATOR_PARAM = "operator_file"
"""A ``str`` procedure parameter that names the procedure's own simulated operator."""


DEFAULT_BACKEND = "pybullet"
"""The backend of a run that names none and whose procedure names none."""


def declared_backend(path: str | Path, sets: Sequence[str] = ()) -> str:
    """The backend ``suture run FILE`` uses without ``--backend``: the file's top-level
    ``backend:`` if it is a string, else :data:`DEFAULT_BACKEND`. A ``${...}`` in it is
    evaluated with the parameters (``sets`` overriding their defaults), which takes
    loading the procedure. A file that does not read or load is left to the loader,
    which reports it located."""
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return DEFAULT_BACKEND
    value = data.get("backend") if isinstance(data, dict) else None
    if not isinstance(value, str):
        return DEFAULT_BACKEND
    if "${" not in value:
        return value
    try:
        proc, _ = load_plan(path, sets)
    except (ProcedureLoadError, SetOverrideError):
        return DEFAULT_BACKEND
    return str(proc.backend or DEFAULT_BACKEND)


def declared_operator_file(path: str | Path, params: Mapping[str, Any]) -> Path | None:
    """The operator file a procedure brings with it, if any.

    A procedure declares its simulated operator (e.g. the chapter 6 experiments' hand,
    thesis 6.3.4) with a ``str`` parameter ``operator_file``, a path relative to the
    procedure's folder; ``--operator`` or ``--interactive`` replace it and
    ``--set operator_file=`` (empty) turns it off.

    Args:
        path: the procedure file.
        params: the procedure's resolved parameters.

    Returns:
        The operator file's path, or None.
    """
    value = params.get(OPERATOR_PARAM)
    if not isinstance(value, str) or not value.strip():
        return None
    file = Path(value)
    return file if file.is_absolute() else Path(path).parent / file


def _new_run_dir(root: Path, name: str, seed: int) -> Path:
    root.mkdir(parents=True, exist_ok=True)
    for n in range(1, 100000):
        candidate = root / f"{name}-seed{seed}-{n:03d}"
        try:
            candidate.mkdir()
            return candidate
        except FileExistsError:
            continue
    raise SutureError(f"no free run folder under {root}")


def run_procedure(
    path: str | Path,
    *,
    backend: str | None = None,
    seed: int = 0,
    sets: Sequence[str] = (),
    out: str | Path | None = None,
    operator_file: str | Path | None = None,
    interactive: bool = False,
    gui: bool = False,
    max_time_s: float = 300.0,
    progress: Callable[[float, float], None] | None = None,
    backend_options: dict[str, Any] | None = None,
    on_tick: Callable[[Any], None] | None = None,
    faults: Sequence[str] = (),
    calibration_error: Mapping[str, Sequence[float]] | None = None,
) -> RunResult:
    """Run a procedure file; write ``trace.mcap`` and ``summary.json``.

    Args:
        path: the procedure file.
        backend: backend name ("pybullet", "replay" needs ``backend_options['trace']``);
            None: the procedure's ``backend:``, else "pybullet".
        seed: random seed.
        sets: ``name=value`` overrides of the procedure's parameters.
        out: output folder (None: a new folder under ``runs/``).
        operator_file: a scripted operator file.
        interactive: take operator keys from the terminal.
        gui: open the simulator's window.
        max_time_s: simulated time after which the run stops as failed [s].
        progress: called with (t [s], max_time_s [s]) during the run.
        backend_options: extra keyword options for the backend's constructor.
        on_tick: called after every tick with the interpreter (live panel, video).
        faults: ``--fault`` specs (:mod:`suture_engine.faults.syntax`), injected with the
            scene's ``faults:`` by a :class:`~suture_engine.faults.backend.FaultyBackend`.
        calibration_error: robot -> its believed base position minus its actual one [m]:
            the robots stand where the scene declares them and the skills plan from bases
            off by this (:mod:`suture_engine.runtime.calibration`). Recorded in the
            trace's metadata, and applied again by a replay.

    Raises:
        ProcedureLoadError, SetOverrideError, OperatorFileError, UnknownBackend,
        FaultSpecError (a bad ``--fault``), FaultNotSupported (a ``--fault`` the backend
        cannot simulate; the scene's are a located ProcedureLoadError).
    """
    from backends import registry
    from suture_engine.runtime.interpreter import Interpreter
    from suture_engine.runtime.monitor import Invariant
    from suture_engine.runtime.operator import InteractiveOperator, ScriptedOperator
    from suture_engine.runtime.recorder import TraceRecorder

    proc, plan = load_plan(path, sets)
    calibration = calibration_offsets(calibration_error, proc.scene)
    if backend is None:
        backend = proc.backend or DEFAULT_BACKEND
    run_faults = _run_faults(proc, plan, backend, faults)
    operator: Any = None
    if operator_file is None and not interactive:
        operator_file = declared_operator_file(path, proc.params)
    if operator_file is not None:
        operator = ScriptedOperator(operator_file)
        robots = list(proc.scene.robots) if proc.scene is not None else None
        operator.check(list(plan.steps), list(plan.terminals), robots)
    options = dict(backend_options or {})
    if gui:
        options["gui"] = True
    try:
        be = registry.create(backend, **options)
    except TypeError as exc:  # an option this backend does not take (e.g. --gui)
        from backends.base import BackendError

        raise BackendError(backend, f"unsupported option: {exc}") from None
    if run_faults:
        from suture_engine.faults.backend import FaultyBackend

        try:
            be = FaultyBackend(be, run_faults, backend_name=backend)
        except SutureError:
            be.close()
            raise
    out_dir = Path(out) if out is not None else _new_run_dir(Path("runs"), proc.name, seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    trace = out_dir / "trace.mcap"
    scene = proc.scene
    rate = 1.0 / float(scene.physics.timestep) if scene is not None else 1000.0
    limit = float(scene.tension_limit) if scene is not None else None
    if interactive:
        operator = InteractiveOperator()
    manual_inv = None
    if scene is not None and scene.robots:
        lim = next(iter(scene.robots.values())).joint_limits
        manual_inv = Invariant(
            q_min=(lim.yaw[0], lim.pitch[0], lim.roll[0], lim.insertion[0]),
            q_max=(lim.yaw[1], lim.pitch[1], lim.roll[1], lim.insertion[1]),
        )
    try:
        first = be.reset(scene, seed)
        recorder = TraceRecorder(
            trace,
            procedure=proc.name,
            seed=seed,
            control_rate_hz=rate,
            robots=tuple(first.robots),
            backend=backend,
            params={k: _jsonable(v) for k, v in proc.params.items()},
            extra=_meta_extra(path, sets, run_faults, calibration, backend_options),
        )
        interp = Interpreter(
            plan,
            be,
            first,
            roles=proc.roles,
            params=proc.params,
            scene=scene,
            seed=seed,
            control_rate_hz=rate,
            operator=operator,
            recorder=recorder,
            max_time_s=max_time_s,
            tension_limit_N=limit,
            progress=progress,
            manual_invariant=manual_inv,
            on_tick=on_tick,
            calibration_error=calibration,
        )
        if run_faults:
            from suture_engine.faults.record import trace_sink

            be.attach(trace_sink(recorder.writer), _running_step(interp))
        summary = interp.run(proc.name, backend)
    finally:
        be.close()
        if isinstance(operator, InteractiveOperator):
            operator.close()
    summary_path = write_summary(out_dir / "summary.json", summary)
    return RunResult(summary, out_dir, trace, summary_path)


def _meta_extra(
    path: str | Path,
    sets: Sequence[str],
    faults: Sequence[Any],
    calibration: Mapping[str, Sequence[float]] | None = None,
    backend_options: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The trace's run metadata beyond the procedure's: its file, ``--set`` values and
    arithmetic, and when given the calibration error, the faults, and the options the
    backend was built with (a perturbation, the thread's model: a run names the model
    it ran on; the window option ``gui`` is left out)."""
    from suture_engine.arithmetic import arithmetic_record

    extra: dict[str, Any] = {
        "procedure_file": str(path),
        "sets": list(sets),
        "arithmetic": arithmetic_record(),
    }
    if calibration:
        extra["calibration_error"] = {r: list(v) for r, v in calibration.items()}
    if faults:
        from suture_engine.faults.syntax import format_fault

        extra["faults"] = [format_fault(f) for f in faults]
    options = {k: v for k, v in (backend_options or {}).items() if k != "gui"}
    if options:
        extra["backend_options"] = _jsonable(options)
    return extra


def _replay_extra(
    proc_file: str | Path, sets: Sequence[str], calibration: Mapping[str, Sequence[float]]
) -> dict[str, Any]:
    """A replay's own metadata: the procedure, its ``--set`` values, and the calibration
    error it applied again (when the recorded run had one)."""
    extra: dict[str, Any] = {"procedure_file": str(proc_file), "sets": list(sets)}
    if calibration:
        extra["calibration_error"] = {r: list(v) for r, v in calibration.items()}
    return extra


def _running_step(interp: Any) -> Callable[[], str | None]:
    """The step the automaton runs autonomously now (None in Lock, Manual, NOT-BE)."""
    from suture_engine.runtime.automaton import Mode

    def running() -> str | None:
        a = interp.automaton
        return a.step_name if a.mode is Mode.AUTONOMOUS else None

    return running


def _run_faults(proc: Any, plan: Any, backend: str, specs: Sequence[str]) -> list[Any]:
    """The run's faults: the scene's, then the ``--fault`` specs, checked against the
    procedure's steps and robots and against what ``backend`` simulates."""
    scene_faults = list(getattr(proc.scene, "faults", None) or [])
    if not scene_faults and not specs:
        return []
    from suture_engine.faults.schedule import state_matches
    from suture_engine.faults.support import (
        FaultNotSupported,
        fault_problems,
        fault_state_problems,
        refusal,
    )
    from suture_engine.faults.syntax import FaultValueError, parse_fault

    steps = list(plan.steps)
    problems = fault_problems(proc, backend) + fault_state_problems(proc, steps)
    if problems:
        raise ProcedureLoadError([p.format() for p in problems])
    robots = list(proc.scene.robots) if proc.scene is not None else []
    cli: list[Any] = []
    for spec in specs:
        fault = parse_fault(spec)
        if fault.robot is not None and robots and fault.robot not in robots:
            raise FaultValueError(
                spec, 0, "robot", f"no robot {fault.robot!r} in the scene ({', '.join(robots)})"
            )
        if fault.when is not None and not any(state_matches(s, fault.when) for s in steps):
            raise FaultValueError(
                spec,
                max(0, spec.find(fault.when)),
                "when",
                f"no step {fault.when!r} ({', '.join(steps)})",
            )
        reason = refusal(fault, backend)
        if reason is not None:
            raise FaultNotSupported(
                backend, fault.kind, len(scene_faults) + len(cli), reason, f"--fault {spec!r}"
            )
        cli.append(fault)
    return scene_faults + cli


def _arithmetic_note(recorded: Any) -> str:
    """A note when the trace was recorded under another BLAS kernel than this process has."""
    from suture_engine.arithmetic import arithmetic_record

    now = arithmetic_record()["blas_kernel"]
    was = recorded.get("blas_kernel", "auto") if isinstance(recorded, dict) else "unrecorded"
    if was == now and now != "auto":
        return ""
    return (
        f"note: recorded with OpenBLAS kernel {was}, replayed with {now}: commands may differ "
        "in the last bit (suture_engine.arithmetic)"
    )


def _jsonable(value: Any) -> Any:
    if isinstance(value, bool | int | float | str) or value is None:
        return value
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if hasattr(value, "tolist"):  # a numpy array or scalar
        return _jsonable(value.tolist())
    return str(value)


def _until(messages: Iterator[Any], last_ns: int) -> Iterator[Any]:
    for msg in messages:
        if msg.log_time_ns <= last_ns and not _fault_record(msg):
            yield msg


def _fault_record(msg: Any) -> bool:
    """A record of an injected fault (``/events`` ``fault:<kind>``, when the trace has no
    ``/faults`` channel) or a backend's event (``BACKEND_EVENTS``, e.g. ``grip-slip``):
    the replay does not re-inject faults nor simulate the world, so it is not compared."""
    from suture_engine.runtime.observation import BACKEND_EVENTS

    if msg.topic != "/events" or not isinstance(msg.data, dict):
        return False
    name = str(msg.data.get("name", ""))
    return name.startswith("fault:") or name in BACKEND_EVENTS


def replay_trace(
    trace: str | Path,
    *,
    check: bool = False,
    procedure: str | Path | None = None,
    sets: Sequence[str] | None = None,
    out: str | Path | None = None,
) -> ReplayResult:
    """Re-run the engine against a trace's recorded measurements.

    Args:
        trace: the recorded trace.
        check: compare the new commands and events with the recorded ones.
        procedure: the procedure file (default: the one named in the trace's metadata).
        sets: ``--set`` overrides (default: those of the recorded run).
        out: where to write the replay's own trace (default: a temporary file).

    Raises:
        TraceError: the trace cannot be read.
        ProcedureLoadError: the procedure does not load.
    """
    from backends.replay import ReplayBackend, recorded_operator_events
    from suture_engine.runtime.interpreter import Interpreter
    from suture_engine.runtime.recorder import TraceRecorder
    from suture_engine.trace.golden import DEFAULT_TOLERANCES, compare
    from suture_engine.trace.reader import TraceReader

    reader = TraceReader(trace)
    meta = reader.meta
    extra = meta.get("extra") if isinstance(meta.get("extra"), dict) else meta
    proc_file = procedure or (extra or {}).get("procedure_file")
    if not proc_file:
        raise ProcedureLoadError([f"{trace}: the trace names no procedure file; pass one"])
    run_sets = list(sets) if sets is not None else list((extra or {}).get("sets") or [])
    if not Path(proc_file).is_file():
        raise ProcedureLoadError(
            [
                f"{trace}: the recorded procedure {proc_file} is not found from "
                f"{Path.cwd()}; run from the folder the run started in, or pass --procedure FILE"
            ]
        )
    proc, plan = load_plan(proc_file, run_sets)
    calibration = calibration_offsets((extra or {}).get("calibration_error"), proc.scene)
    be = ReplayBackend(reader=reader)
    rate = be.rate
    tmp_dir = None
    if out is None:
        tmp_dir = tempfile.mkdtemp(prefix="suture-replay-")
        out_path = Path(tmp_dir) / "replay.mcap"
    else:
        out_path = Path(out)
    first = be.reset(proc.scene, int(meta.get("seed", 0)))
    recorder = TraceRecorder(
        out_path,
        procedure=proc.name,
        seed=int(meta.get("seed", 0)),
        control_rate_hz=rate,
        robots=be.robots,
        backend=str(meta.get("backend", "replay")),
        params={k: _jsonable(v) for k, v in proc.params.items()},
        extra=_replay_extra(proc_file, run_sets, calibration),
    )
    scene = proc.scene
    interp = Interpreter(
        plan,
        be,
        first,
        roles=proc.roles,
        params=proc.params,
        scene=scene,
        seed=int(meta.get("seed", 0)),
        control_rate_hz=rate,
        operator=recorded_operator_events(reader, rate),
        recorder=recorder,
        max_time_s=float("inf"),
        tension_limit_N=float(scene.tension_limit) if scene is not None else None,
        calibration_error=calibration,
    )
    summary = interp.run(proc.name, "replay")
    ok, diff = True, ""
    if check:
        last_ns = be.last_tick * be.period_ns
        result = compare(
            _until(reader.messages(), last_ns),
            _until(TraceReader(out_path).messages(), last_ns),
            DEFAULT_TOLERANCES,
            topics=COMPARED_TOPICS,
        )
        ok, diff = result.ok, result.text
        note = _arithmetic_note((extra or {}).get("arithmetic"))
        if note:
            diff = f"{diff.rstrip()}\n{note}" if diff else note
    if tmp_dir is not None:
        try:
            os.remove(out_path)
            os.rmdir(tmp_dir)
        except OSError:
            pass
    return ReplayResult(
        summary, out_path, ok, diff, be.last_tick + 1, bool(reader.status.truncated)
    )
