"""The work behind ``suture sweep`` (the CLI wrapper stays thin).

Exit codes: 0 the sweep finished (whatever the runs' outcomes: they are its data);
1 an invalid ``--vary`` spec or procedure; 2 usage or I/O errors (a missing file,
an unknown parameter, another sweep in ``--out``, Ray not installed).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

__all__ = ["sweep_command"]


def _error(err: TextIO, message: str) -> None:
    err.write(f"error: {message}\n")


def sweep_command(
    file: Path,
    *,
    runs: int,
    vary: Sequence[str],
    out: Path,
    workers: int = 1,
    ray: str | None = None,
    seed: int = 0,
    sets: Sequence[str] = (),
    max_time: float = 300.0,
    stdout: TextIO | None = None,
    err: TextIO | None = None,
) -> int:
    """``suture sweep``: returns the exit code."""
    from suture_engine.errors import SutureError
    from suture_engine.report.sweep import (
        SweepConfig,
        SweepError,
        VarySpecError,
        make_jobs,
        parse_vary,
        read_results,
        run_sweep,
    )
    from suture_engine.runtime.run import ProcedureLoadError, SetOverrideError, load_plan

    stdout = stdout or sys.stdout
    err = err or sys.stderr
    if not file.is_file():
        _error(err, f"{file}: no such file")
        return 2
    if runs < 1:
        _error(err, f"--runs must be at least 1, found {runs}")
        return 2
    if workers < 1:
        _error(err, f"--workers must be at least 1, found {workers}")
        return 2
    if not max_time > 0.0:
        _error(err, f"--max-time must be a positive number of seconds, found {max_time}")
        return 2
    try:
        specs = tuple(parse_vary(text) for text in vary)
    except VarySpecError as exc:
        _error(err, f"{exc.code}: {exc.message}")
        return 1
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        _error(err, f"a parameter is varied twice: {names}")
        return 2
    config = SweepConfig(file, runs, specs, seed, tuple(sets), max_time)
    # Check the procedure and the varied names once here, with run 0's values.
    first = make_jobs(SweepConfig(file, 1, specs, seed, tuple(sets), max_time), out)[0]
    try:
        load_plan(file, [*sets, *(f"{k}={v}" for k, v in first.values.items())])
    except ProcedureLoadError as exc:
        for problem in exc.problems:
            _error(err, problem)
        return 1
    except SetOverrideError as exc:
        spec = next((s for s in specs if exc.text.startswith(f"{s.name}=")), None)
        if spec is not None:
            known = ", ".join(exc.available) or "none"
            _error(
                err,
                f"bad-vary: --vary {spec.text!r}: no parameter named {spec.name!r} "
                f"(parameters: {known})",
            )
        else:
            _error(err, f"{exc.code}: {exc.message}")
        return 2
    except SutureError as exc:
        _error(err, f"{exc.code}: {exc.message}")
        return 1

    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    console = Console(file=err, highlight=False)
    progress = Progress(
        TextColumn("[bold]sweep[/]"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[last]}"),
        TimeElapsedColumn(),
        console=console,
    )
    try:
        already = sum(1 for i in read_results(out / "results.csv", specs) if i < runs)
    except (SweepError, OSError, ValueError, KeyError):
        already = 0  # run_sweep reports a foreign results.csv
    task = progress.add_task("sweep", total=runs, completed=already, last="")

    def on_row(row: object) -> None:
        progress.update(
            task, advance=1, last=f"run {getattr(row, 'run', '')}: {getattr(row, 'outcome', '')}"
        )

    try:
        with progress:
            result = run_sweep(config, out, workers=workers, ray_address=ray, on_row=on_row)
    except SweepError as exc:
        _error(err, f"{exc.code}: {exc.message}")
        return 2
    except KeyboardInterrupt:
        _error(err, f"interrupted; finished runs are in {out / 'results.csv'}: run again to resume")
        return 1
    except OSError as exc:
        _error(err, f"{exc.filename or out}: {exc.strerror}")
        return 2
    s = result.summary
    skipped = runs - len(result.ran)
    stdout.write(f"{s['runs']} runs ({len(result.ran)} run now, {skipped} already done)\n")
    for name, c in s["conditions"].items():
        stdout.write(
            f"  {name}: {c['succeeded']}/{c['runs']} succeeded, rate {c['success_rate']:.3f} "
            f"[{c['wilson_low']:.3f}, {c['wilson_high']:.3f}] ({s['confidence']:.0%} Wilson)\n"
        )
    t = s["max_tension_N"]
    if t["n"]:
        stdout.write(
            f"  max tension [N]: mean {t['mean']:.3f}, sd {t['std']:.3f}, "
            f"min {t['min']:.3f}, max {t['max']:.3f}\n"
        )
    if s["errors"]:
        stdout.write(f"  {s['errors']} runs ended in an error (see the error column)\n")
    for path in result.files.values():
        stdout.write(f"{path}\n")
    return 0
