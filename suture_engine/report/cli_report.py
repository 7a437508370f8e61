"""The work behind ``suture plot`` and ``suture report`` (the CLI wrappers stay thin).

Both return the exit code: 0 success; 1 a trace that is foreign or damaged; 2 usage
or I/O errors (a missing trace, an output that cannot be written). The output
location is checked first, before any figure is drawn; then the trace is read and
every figure drawn before anything is written, so a bad trace leaves no partial
output behind.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TextIO

__all__ = ["plot_command", "report_command"]


def _error(err: TextIO, message: str) -> None:
    err.write(f"error: {message}\n")


def _unwritable(target: Path, *, folder: bool) -> str | None:
    """Why ``target`` (a folder to fill, or a file) cannot be written, or None.

    Checked before any figure is drawn: the nearest existing ancestor must be a
    folder in which a file can be created (a probe file, removed at once).
    """
    import tempfile

    if folder and target.exists() and not target.is_dir():
        return f"{target}: not a folder; --out takes the folder to write the figures in"
    if not folder and target.is_dir():
        return f"{target}: is a folder; --out takes the HTML file to write"
    here = target if folder else target.parent
    here = here if str(here) else Path(".")
    while not here.exists() and here != here.parent:
        here = here.parent
    if not here.is_dir():
        return f"{target}: cannot write: {here} is not a folder"
    try:
        with tempfile.TemporaryFile(dir=here):
            pass
    except OSError as exc:
        return f"{target}: cannot write: {exc.strerror or exc}"
    return None


def _load(trace: Path, err: TextIO) -> tuple[int, object | None]:
    """``(exit code, TraceData or None)``."""
    from suture_engine.report.figures import load_trace
    from suture_engine.trace.errors import TraceError, TraceIOError

    if not trace.is_file():
        _error(err, f"{trace}: no such file")
        return 2, None
    try:
        data = load_trace(trace)
    except TraceIOError as exc:
        _error(err, f"{exc.code}: {exc.message}")
        return 2, None
    except TraceError as exc:
        _error(err, f"{exc.code}: {exc.message}")
        return 1, None
    if data.status.message_count == 0:
        _error(
            err,
            f"trace-empty: {trace}: no readable message ({data.status.reason} at byte "
            f"{data.status.stop_offset})",
        )
        return 1, None
    return 0, data


def plot_command(
    trace: Path, *, out: Path | None = None, stdout: TextIO | None = None, err: TextIO | None = None
) -> int:
    """``suture plot TRACE [--out DIR]``: write the figures as PNG (default: ``figures/``
    beside the trace). Returns the exit code."""
    from suture_engine.report.figures import TraceData, render_figures, write_figures

    stdout = stdout or sys.stdout
    err = err or sys.stderr
    target = out if out is not None else trace.parent / "figures"
    problem = _unwritable(target, folder=True) if trace.is_file() else None
    if problem is not None:
        _error(err, problem)
        return 2
    code, data = _load(trace, err)
    if not isinstance(data, TraceData):
        return code
    figures = render_figures(data)
    existed = target.exists()
    try:
        paths = write_figures(figures, target)
    except OSError as exc:
        if not existed and target.is_dir():
            for leftover in target.glob("*.png"):
                leftover.unlink(missing_ok=True)
            try:
                target.rmdir()
            except OSError:
                pass
        _error(err, f"{target}: cannot write: {exc.strerror}")
        return 2
    if data.status.truncated:
        stdout.write(f"note: the trace ends early ({data.status.reason})\n")
    for fig, path in zip(figures, paths, strict=True):
        missing = f"  (no data on {', '.join(fig.missing)})" if fig.missing else ""
        stdout.write(f"{path}{missing}\n")
    return 0


def report_command(
    trace: Path, *, out: Path | None = None, stdout: TextIO | None = None, err: TextIO | None = None
) -> int:
    """``suture report TRACE [--out FILE]``: write one self-contained HTML page (default:
    ``report.html`` beside the trace). Returns the exit code."""
    from suture_engine.report.figures import TraceData
    from suture_engine.report.html import build_report, write_report

    stdout = stdout or sys.stdout
    err = err or sys.stderr
    target = out if out is not None else trace.parent / "report.html"
    problem = _unwritable(target, folder=False) if trace.is_file() else None
    if problem is not None:
        _error(err, problem)
        return 2
    code, data = _load(trace, err)
    if not isinstance(data, TraceData):
        return code
    page = build_report(data)
    try:
        path = write_report(page, target)
    except OSError as exc:
        _error(err, f"{target}: cannot write: {exc.strerror}")
        return 2
    stdout.write(f"{path}\n")
    return 0
