"""The work behind ``suture run`` and ``suture replay`` (the CLI wrappers stay thin).

Both return the process exit code: 0 success, 1 invalid input or a run that
did not succeed (or a replay check that diverged), 2 usage or I/O errors.
Typed errors are printed as one located message, never as a traceback.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, cast

__all__ = ["replay_command", "run_command"]


def _error(message: str) -> None:
    """Print ``message`` on stderr as one unbroken line: a located error's
    ``file:line:col`` must stay whole to be copied, whatever the terminal's width."""
    from rich.console import Console

    Console(stderr=True, highlight=False, soft_wrap=True).print(
        f"[bold red]error:[/] {message}", markup=True
    )


def _knot_text(entry: Any) -> str:
    """A knot entry's type, flagged when its thread no longer passes through the tissue."""
    text = str(entry.get("type"))
    if entry.get("through_tissue") is False:
        text += " (thread out of the tissue: no stitch bound)"
    return text


def _true_peak_row(s: object) -> list[tuple[str, str]]:
    """The thread's true tension peak, when and where (ground truth), against the limit."""
    metrics = getattr(s, "metrics", None) or {}
    peak = metrics.get("peak_true_tension_N")
    if peak is None:
        return []
    text = f"{peak:.3f} N"
    at = metrics.get("peak_true_tension_at") or {}
    if at.get("t_s") is not None:
        text += f" at {at['t_s']:.3f} s"
    if at.get("state"):
        text += f" in {str(at['state']).rsplit('/', 1)[-1]}"
    if at.get("joint") is not None:
        text += f", thread joint {at['joint']}"
    limit = getattr(s, "tension_limit_N", None)
    if limit is not None:
        over = peak > limit
        text += f" ({'[red]over[/] ' if over else ''}limit {limit:.2f} N)"
    return [("true tension peak (ground truth)", text)]


def _span(values: list[float]) -> str:
    lo, hi = min(values), max(values)
    return f"{lo:.2f} mm" if hi - lo < 0.005 else f"{lo:.2f}-{hi:.2f} mm"


def _stitches_row(s: object) -> list[tuple[str, str]]:
    """The STAR-style stitch metrics (ground truth), each figure beside its resolution."""
    m = (getattr(s, "metrics", None) or {}).get("stitches")
    if not m or not m.get("count"):
        return []
    parts = [f"{m['count']} bite{'s' if m['count'] != 1 else ''}"]
    errors = [
        e for e in (m.get("entry_error_mm") or []) + (m.get("exit_error_mm") or []) if e is not None
    ]
    res = [
        r
        for r in (m.get("entry_resolution_mm") or []) + (m.get("exit_resolution_mm") or [])
        if r is not None
    ]
    if errors:
        text = f"entry/exit {_span(errors)} from their points"
        parts.append(text + (f" (resolution {max(res):.1f} mm)" if res else ""))
    if m.get("bite_depth_mm"):
        parts.append(f"depth {_span(m['bite_depth_mm'])}")
    if m.get("spacing_mean_mm") is not None:
        text = f"spacing {m['spacing_mean_mm']:.2f} ± {m['spacing_sd_mm']:.2f} mm"
        bound = m.get("spacing_resolution_mm")
        parts.append(text + (f" (resolution {bound:.1f} mm)" if bound is not None else ""))
    return [("stitches (ground truth)", "; ".join(parts))]


def _print_summary(summary: object, out_dir: Path | None) -> None:
    from rich.console import Console
    from rich.table import Table

    s = summary
    table = Table(show_header=False, box=None, pad_edge=False)
    colour = {"succeeded": "green", "failed": "red", "aborted": "yellow"}.get(
        getattr(s, "outcome", ""), "white"
    )
    rows = [
        ("procedure", str(getattr(s, "procedure", ""))),
        ("outcome", f"[{colour}]{getattr(s, 'outcome', '')}[/]"),
        ("final state", str(getattr(s, "final_state", ""))),
        ("sim time", f"{getattr(s, 'sim_time_s', 0.0):.3f} s"),
        ("wall time", f"{getattr(s, 'wall_time_s', 0.0):.3f} s"),
        ("real-time factor", f"{getattr(s, 'real_time_factor', 0.0):.2f}"),
        ("max tension", f"{getattr(s, 'max_tension_N', 0.0):.3f} N"),
        *_true_peak_row(s),
        ("violations", str(len(getattr(s, "violations", [])))),
        ("retries", str(getattr(s, "retries", 0))),
        ("operator events", str(getattr(s, "operator_events", 0))),
    ]
    knot = getattr(s, "knot", None)
    if knot is not None and hasattr(knot, "get") and knot.get("type"):
        rows.append(("knot (ground truth)", _knot_text(knot)))
    elif isinstance(knot, list) and knot:  # one entry per stitch
        types = ", ".join(_knot_text(k) for k in knot)
        rows.append(("knots (ground truth)", types))
    else:
        rows.append(("knot", "not checked: this backend simulates no thread"))
    rows.extend(_stitches_row(s))
    fault = getattr(s, "last_fault", None)
    if fault and getattr(s, "outcome", "") != "succeeded":
        rows.append(("last fault", f"{fault['step']} at {fault['t_s']:.3f} s: {fault['reason']}"))
    stopped = getattr(s, "metrics", {}).get("stopped")
    if stopped:
        rows.append(("stopped", str(stopped)))
    if out_dir is not None:
        rows.append(("output", str(out_dir)))
    for key, value in rows:
        table.add_row(f"[bold]{key}[/]", value)
    Console(highlight=False).print(table)


def run_command(
    file: Path,
    *,
    backend: str | None,
    seed: int,
    sets: Sequence[str],
    out: Path | None,
    operator: Path | None,
    interactive: bool,
    gui: bool,
    max_time: float,
    replay_trace: Path | None = None,
    video: Path | None = None,
    video_interval: float = 0.1,
    faults: Sequence[str] = (),
    calibration: Sequence[str] = (),
    thread_damping: str | None = None,
    thread_weight: str | None = None,
) -> int:
    """``suture run``: returns the exit code. ``backend`` None: the procedure's own
    ``backend:``, else ``pybullet``.

    A ``--calibration-error`` that is not ``ROBOT=X,Y,Z`` is a usage error (exit 2); one
    naming a robot the scene does not have is invalid input (exit 1).

    A ``--fault`` that does not parse, or that the backend cannot simulate, is a usage
    error (exit 2); one whose field the fault model refuses is invalid input (exit 1).

    ``--thread-damping`` and ``--thread-weight`` are read as the scene's ``suture.damping``
    and ``suture.weight`` are (``'20 1/s'``, ``'4 g/m'``; a bare number is SI): one that
    does not parse, has another dimension, or is out of the field's bounds (a rate >= 0,
    a mass per length > 0) is a usage error (exit 2). They go to the backend as
    ``thread_damping`` [1/s] and ``thread_weight`` [kg/m]. A backend that takes no such
    option (ideal, replay) refuses them (exit 1); the PyBullet backends take them and use
    them where they build the thread.
    """
    from backends.registry import UnknownBackend
    from suture_engine.errors import SutureError
    from suture_engine.faults.support import FaultNotSupported
    from suture_engine.faults.syntax import FaultSyntaxError, FaultValueError
    from suture_engine.runtime.operator import OperatorFileMissing
    from suture_engine.runtime.run import (
        ProcedureLoadError,
        SetOverrideError,
        declared_backend,
        run_procedure,
    )

    if not file.is_file():
        _error(f"{file}: no such file")
        return 2
    if backend is None:
        backend = declared_backend(file, sets)
    if not 0.0 < max_time < float("inf"):
        _error(f"--max-time must be a positive, finite number of seconds, found {max_time:g}")
        return 2
    from suture_engine.runtime.calibration import CalibrationSpecError, parse_calibration_spec

    calibration_error: dict[str, tuple[float, float, float]] = {}
    try:
        for spec in calibration:
            robot, vector = parse_calibration_spec(spec)
            calibration_error[robot] = vector
    except CalibrationSpecError as exc:
        _error(f"{exc.code}: {exc.message}")
        return 2
    if operator is not None and not operator.is_file():
        _error(f"--operator {operator}: {'a folder' if operator.is_dir() else 'no such file'}")
        return 2

    options: dict[str, Any] = {}
    for flag, text, field in (
        ("--thread-damping", thread_damping, "damping"),
        ("--thread-weight", thread_weight, "weight"),
    ):
        if text is None:
            continue
        value = _suture_field(flag, text, field)
        if value is None:
            return 2
        options[f"thread_{field}"] = value
    if backend == "replay":
        if replay_trace is None:
            _error("--backend replay needs --trace TRACE (the recording to serve)")
            return 2
        options["trace"] = replay_trace
    hooks, panel, capture = _live_hooks(file, backend, interactive, gui, video, video_interval)
    if hooks is None:
        return 2
    progress_cb = None
    progress_ctx = None
    if sys.stdout.isatty() and panel is None:
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        progress_ctx = Progress(
            TextColumn("[bold]running[/]"),
            BarColumn(),
            TextColumn("{task.fields[t]:.2f} s simulated"),
            TimeElapsedColumn(),
            transient=True,
        )
        task = progress_ctx.add_task("run", total=max_time, t=0.0)

        def progress_cb(t: float, limit: float) -> None:
            if int(t * 1000) % 500 == 0:
                progress_ctx.update(task, completed=t, t=t)

        progress_ctx.start()
    try:
        result = run_procedure(
            file,
            backend=backend,
            seed=seed,
            sets=sets,
            out=out,
            operator_file=operator,
            interactive=interactive,
            gui=gui,
            max_time_s=max_time,
            progress=progress_cb,
            backend_options=options,
            on_tick=_chain(hooks),
            faults=faults,
            calibration_error=calibration_error or None,
        )
    except ProcedureLoadError as exc:
        for problem in exc.problems:
            _error(problem)
        return 1
    except FaultValueError as exc:
        _error(f"{exc.code}: {exc.message}")
        return 1
    except (
        SetOverrideError,
        UnknownBackend,
        OperatorFileMissing,
        FaultSyntaxError,
        FaultNotSupported,
    ) as exc:
        _error(f"{exc.code}: {exc.message}")
        return 2
    except SutureError as exc:
        _error(f"{exc.code}: {exc.message}")
        return 1
    except OSError as exc:
        _error(f"{exc.filename or ''}: {exc.strerror}")
        return 2
    finally:
        if progress_ctx is not None:
            progress_ctx.stop()
        if panel is not None:
            panel.stop()
    _print_summary(result.summary, result.out_dir)
    if capture is not None and video is not None:
        from suture_engine.runtime.video import video_path

        try:
            written = capture.write(video_path(video, result.out_dir))
        except SutureError as exc:
            _error(f"{exc.code}: {exc.message}")
            return 2
        print(f"video: {written.path} ({written.frames} frames, every {written.interval_s:g} s)")
    return 0 if result.summary.outcome == "succeeded" else 1


def _suture_field(flag: str, text: str, field: str) -> float | None:
    """``text`` read as the scene's ``suture.<field>`` is (its unit and bounds) [SI], or
    None after printing why not."""
    from typing import Annotated

    from pydantic import TypeAdapter, ValidationError

    from suture_engine.language.scene import Suture

    info = Suture.model_fields[field]
    try:
        value: float | None = TypeAdapter(Annotated[info.annotation, info]).validate_python(text)
    except ValidationError as exc:
        _error(f"{flag} {text!r}: {exc.errors()[0]['msg']} (as the scene's suture.{field})")
        return None
    return None if value is None else float(value)


def _live_hooks(
    file: Path,
    backend: str,
    interactive: bool,
    gui: bool,
    video: Path | None,
    interval: float,
) -> tuple[list[Any] | None, Any, Any]:
    """The per-tick hooks of ``--interactive`` and ``--video`` (None hooks: a usage error)."""
    hooks: list[Any] = []
    panel = capture = None
    if video is not None:
        from suture_engine.runtime.video import VideoCapture, VideoError

        if video.suffix.lower() != ".gif":
            _error(f"--video {video}: the video is written as a GIF; name it FILE.gif")
            return None, None, None
        if backend in ("ideal", "replay"):
            _error(f"--video needs a pybullet backend (the {backend} backend renders no frames)")
            return None, None, None
        try:
            capture = VideoCapture(interval_s=interval)
        except VideoError as exc:
            _error(exc.message)
            return None, None, None
        hooks.append(capture)
    if interactive:
        from suture_engine.runtime.live import LivePanel

        panel = LivePanel(file.stem, gui=gui)
        hooks.append(panel)
        panel.start()
    return hooks, panel, capture


def _chain(hooks: list[Any]) -> Callable[[Any], None] | None:
    if not hooks:
        return None
    if len(hooks) == 1:
        return cast(Callable[[Any], None], hooks[0])

    def call_all(interp: Any) -> None:
        for hook in hooks:
            hook(interp)

    return call_all


def replay_command(
    trace: Path,
    *,
    check: bool,
    procedure: Path | None,
    sets: Sequence[str] | None,
) -> int:
    """``suture replay``: returns the exit code."""
    from rich.console import Console

    from suture_engine.errors import SutureError
    from suture_engine.runtime.run import ProcedureLoadError, SetOverrideError, replay_trace

    if not trace.is_file():
        _error(f"{trace}: no such file")
        return 2
    try:
        result = replay_trace(trace, check=check, procedure=procedure, sets=sets)
    except ProcedureLoadError as exc:
        for problem in exc.problems:
            _error(problem)
        return 1
    except SetOverrideError as exc:
        _error(f"{exc.code}: {exc.message}")
        return 2
    except SutureError as exc:
        _error(f"{exc.code}: {exc.message}")
        return 1
    console = Console(highlight=False)
    note = " (the recording ends early: replayed up to its last complete tick)"
    console.print(
        f"replayed {result.ticks} ticks of {trace}{note if result.truncated else ''}; "
        f"outcome {result.summary.outcome}, final state {result.summary.final_state}"
    )
    if check:
        if result.ok:
            console.print("[green]check passed[/]: " + result.diff)
        else:
            console.print("[red]check failed[/]")
            console.print(result.diff, markup=False)
            return 1
    return 0
