"""The ``suture`` command.

Each sub-command is a thin wrapper: it parses arguments with typer and hands
over to a function in the module that owns the work, imported lazily so that
start-up stays fast. Exit codes: 0 success, 1 the input is invalid or the run
failed, 2 usage or I/O errors. No command ever prints a traceback for bad
input.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

__all__ = ["app", "main"]

app = typer.Typer(
    name="suture",
    help="Run robotic suturing procedures written in YAML on simulated EndoBots.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


@app.command()
def run(
    file: Annotated[Path, typer.Argument(help="The procedure file (YAML).")],
    backend: Annotated[
        str | None,
        typer.Option(
            help="pybullet (robots only), pybullet-surgical (with the thread, tissue and "
            "tools), pybullet-surgical-stitched (the stitch already made), replay (with "
            "--trace) or ideal (model only, for tests). Default: the procedure's `backend:`, "
            "else pybullet.",
            show_default=False,
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    set_: Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            help="Override a procedure parameter: name=value (repeatable). Not name=value or "
            "no such parameter: usage error (exit 2); a value the parameter refuses: "
            "invalid (exit 1).",
        ),
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="Output folder (default: a new folder under runs/).")
    ] = None,
    operator: Annotated[Path | None, typer.Option(help="Scripted operator file.")] = None,
    interactive: Annotated[
        bool, typer.Option(help="Operator keys: l lock, m manual, r resume, a abort.")
    ] = False,
    gui: Annotated[bool, typer.Option(help="Open the simulator window.")] = False,
    max_time: Annotated[
        float, typer.Option(help="Simulated time limit, in seconds (positive).")
    ] = 600.0,
    trace: Annotated[
        Path | None, typer.Option(help="With --backend replay: the recorded trace to serve.")
    ] = None,
    video: Annotated[
        Path | None,
        typer.Option(help="Write a GIF of the run (a relative FILE.gif goes in the output dir)."),
    ] = None,
    video_interval: Annotated[
        float, typer.Option(help="With --video: simulated seconds between frames.")
    ] = 0.1,
    fault: Annotated[
        list[str] | None,
        typer.Option(
            "--fault",
            help="Inject a fault (repeatable), e.g. 'ft.bias=0.5 N@2 s', "
            "'endobot_1:enc.dropout@3 s for 20 ms', 'snag=2 N@state bite', "
            "'endobot_1:pitch.joint-lock@1 s', 'blow-up@5 s;mode=energy' "
            "(grammar and kinds: docs/faults.md).",
        ),
    ] = None,
    calibration_error: Annotated[
        list[str] | None,
        typer.Option(
            "--calibration-error",
            help="Simulate a calibration error (repeatable): ROBOT=X,Y,Z, the believed base "
            "minus the actual one in mm, e.g. endobot_2=1,0,-0.5. The robot stands where "
            "the scene puts it; the skills plan from the base off by this.",
        ),
    ] = None,
    thread_damping: Annotated[
        str | None,
        typer.Option(
            help="The thread's damping rate, e.g. '20 1/s' (surgical backends; default: the "
            "scene's suture.damping, else 0.5 1/s). Recorded in the trace.",
            show_default=False,
        ),
    ] = None,
    thread_weight: Annotated[
        str | None,
        typer.Option(
            help="The mass per length whose weight the thread keeps, e.g. '4 g/m' (surgical "
            "backends; default: the scene's suture.weight, else 0.1 g/m). Recorded in the "
            "trace.",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Run a procedure; write DIR/trace.mcap and DIR/summary.json."""
    from suture_engine.runtime.cli_run import run_command

    raise typer.Exit(
        run_command(
            file,
            backend=backend,
            seed=seed,
            sets=set_ or [],
            out=out,
            operator=operator,
            interactive=interactive,
            gui=gui,
            max_time=max_time,
            replay_trace=trace,
            video=video,
            video_interval=video_interval,
            faults=fault or [],
            calibration=calibration_error or [],
            thread_damping=thread_damping,
            thread_weight=thread_weight,
        )
    )


@app.command()
def replay(
    trace: Annotated[Path, typer.Argument(help="A recorded trace (trace.mcap).")],
    check: Annotated[
        bool, typer.Option(help="Compare the engine's commands and events with the recorded ones.")
    ] = False,
    procedure: Annotated[
        Path | None, typer.Option(help="The procedure file (default: the one the trace names).")
    ] = None,
    set_: Annotated[
        list[str] | None,
        typer.Option(
            "--set", help="Override a parameter: name=value (default: the recorded ones)."
        ),
    ] = None,
) -> None:
    """Re-run the engine against a recorded trace's measurements."""
    from suture_engine.runtime.cli_run import replay_command

    raise typer.Exit(replay_command(trace, check=check, procedure=procedure, sets=set_ or None))


@app.command()
def validate(
    files: Annotated[list[Path], typer.Argument(help="Procedure files (YAML).")],
    format_: Annotated[
        str, typer.Option("--format", help="text (file:line:col: code: message) or json.")
    ] = "text",
    allow_outside: Annotated[
        bool, typer.Option(help="Allow use:/scene paths outside each procedure's folder tree.")
    ] = False,
    set_: Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            help="Override a procedure parameter: name=value (repeatable). Not name=value or "
            "no such parameter: usage error (exit 2); a value the parameter refuses: "
            "invalid (exit 1).",
        ),
    ] = None,
) -> None:
    """Check procedures without running them; report every problem."""
    from suture_engine.validation.report import validate_command

    raise typer.Exit(
        validate_command(files, fmt=format_, allow_outside=allow_outside, sets=set_ or [])
    )


@app.command()
def schema() -> None:
    """Print the JSON Schema of the procedure language (for editors)."""
    from suture_engine.validation.report import schema_command

    raise typer.Exit(schema_command())


@app.command()
def graph(
    file: Annotated[Path, typer.Argument(help="The procedure file (YAML).")],
    format_: Annotated[str, typer.Option("--format", help="mermaid or dot.")] = "mermaid",
    allow_outside: Annotated[
        bool, typer.Option(help="Allow use:/scene paths outside the procedure's folder tree.")
    ] = False,
    engine: Annotated[
        str, typer.Option(help="text, or transitions (its GraphMachine; mermaid only).")
    ] = "text",
) -> None:
    """Draw the procedure's state machine (each state with its skill and invariant)."""
    from suture_engine.validation.report import graph_command

    raise typer.Exit(graph_command(file, fmt=format_, allow_outside=allow_outside, engine=engine))


@app.command()
def identify(
    robot: Annotated[str, typer.Option(help="E1 or E2: the simulated robot's parameters.")] = "E1",
    signal: Annotated[
        str, typer.Option(help="Excitation: schroeder, multisine, chirp or prbs.")
    ] = "schroeder",
    method: Annotated[str, typer.Option(help="differential or energy model.")] = "differential",
    duration: Annotated[float, typer.Option(help="Excitation length per joint [s].")] = 10.0,
    encoder_noise: Annotated[
        float, typer.Option(help="Encoder noise standard deviation [rad and m].")
    ] = 0.0,
    quantised: Annotated[
        bool, typer.Option(help="Quantise encoders (2000 counts per motor revolution).")
    ] = False,
    seed: Annotated[int, typer.Option(help="Noise seed.")] = 0,
    joint: Annotated[
        list[int] | None, typer.Option(help="Joint to identify, 1-4 (repeatable; default all).")
    ] = None,
) -> None:
    """Excite the simulated EndoBot, identify it (thesis 3.5), print estimate vs truth."""
    from suture_engine.robot.identification_report import identify_command

    raise typer.Exit(
        identify_command(
            robot=robot,
            signal=signal,
            method=method,
            duration=duration,
            encoder_noise=encoder_noise,
            quantised=quantised,
            seed=seed,
            joints=joint,
        )
    )


@app.command("trace")
def trace_info(
    file: Annotated[Path, typer.Argument(help="A trace file (trace.mcap).")],
    json_: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Show a trace: complete or where it stops, metadata, channels and counts."""
    from suture_engine.trace.cli_trace import trace_command

    raise typer.Exit(trace_command(file, as_json=json_))


@app.command()
def diff(
    expected: Annotated[Path, typer.Argument(help="The reference (golden) trace.")],
    actual: Annotated[Path, typer.Argument(help="The trace to check.")],
    topic: Annotated[
        list[str] | None,
        typer.Option(help="Compare only these topics or globs (repeatable)."),
    ] = None,
) -> None:
    """Compare two traces with the golden tolerances; print the first divergence."""
    from suture_engine.trace.cli_trace import diff_command

    raise typer.Exit(diff_command(expected, actual, topics=topic))


@app.command()
def knot(
    file: Annotated[
        Path,
        typer.Argument(
            help="Centerline: .npy, .json or text (N x 3); or a run's trace.mcap: the knot "
            "at the end of each state."
        ),
    ],
    json_: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    seed: Annotated[int, typer.Option(help="Seed of the projection directions.")] = 0,
    tissue_point: Annotated[
        tuple[float, float, float] | None,
        typer.Option(help="A point of the tissue plane [m] (adds seated/post straight)."),
    ] = None,
    tissue_normal: Annotated[
        tuple[float, float, float] | None, typer.Option(help="Tissue normal.")
    ] = None,
) -> None:
    """Classify the knot held by a suture centerline, or by a run's thread state by state."""
    from suture_engine.suture.cli_knot import knot_command

    raise typer.Exit(
        knot_command(
            file,
            as_json=json_,
            seed=seed,
            tissue_point=list(tissue_point) if tissue_point else None,
            tissue_normal=list(tissue_normal) if tissue_normal else None,
        )
    )


@app.command()
def steps(
    traces: Annotated[list[Path], typer.Argument(help="Trace files (trace.mcap).")],
    state: Annotated[
        list[str] | None,
        typer.Option(help="Only states whose name matches this glob (repeatable)."),
    ] = None,
    json_: Annotated[bool, typer.Option("--json", help="Print one JSON array of rows.")] = False,
    csv_: Annotated[
        Path | None,
        typer.Option(
            "--csv",
            help="Write one row per state and run here, labelled with each run's outcome and knot.",
        ),
    ] = None,
) -> None:
    """What the robots measured in each state: tool-tip travel and base-sensor tension estimates."""
    from suture_engine.report.cli_steps import steps_command

    raise typer.Exit(steps_command(traces, states=state or [], as_json=json_, csv_path=csv_))


@app.command()
def plot(
    trace: Annotated[Path, typer.Argument(help="A recorded trace (trace.mcap).")],
    out: Annotated[
        Path | None, typer.Option(help="Output folder (default: figures/ beside the trace).")
    ] = None,
) -> None:
    """Draw a run's thesis-style figures as PNG (force, joints, path, tension, states, QP)."""
    from suture_engine.report.cli_report import plot_command

    raise typer.Exit(plot_command(trace, out=out))


@app.command()
def report(
    trace: Annotated[Path, typer.Argument(help="A recorded trace (trace.mcap).")],
    out: Annotated[
        Path | None, typer.Option(help="HTML file (default: report.html beside the trace).")
    ] = None,
) -> None:
    """Write one self-contained HTML page of a run: figures, summary, knot, graph."""
    from suture_engine.report.cli_report import report_command

    raise typer.Exit(report_command(trace, out=out))


@app.command()
def sweep(
    file: Annotated[Path, typer.Argument(help="The procedure file (YAML).")],
    runs: Annotated[int, typer.Option(help="Number of runs.")],
    out: Annotated[Path, typer.Option(help="Output folder (a resume uses the same one).")],
    vary: Annotated[
        list[str] | None,
        typer.Option(help="name=normal(mu,sigma) | uniform(a,b) | choice(a,b,...) (repeatable)."),
    ] = None,
    workers: Annotated[int, typer.Option(help="Worker processes.")] = 1,
    ray: Annotated[
        str | None, typer.Option(help="Run on Ray: local, auto or a cluster address.")
    ] = None,
    seed: Annotated[int, typer.Option(help="Base seed (each run's seed derives from it).")] = 0,
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="Fixed override for every run: name=value (repeatable)."),
    ] = None,
    max_time: Annotated[
        float, typer.Option(help="Simulated time limit per run, in seconds.")
    ] = 600.0,
) -> None:
    """Run a procedure N times with varied parameters; results.csv, summary, plot."""
    from suture_engine.report.cli_sweep import sweep_command

    raise typer.Exit(
        sweep_command(
            file,
            runs=runs,
            vary=vary or [],
            out=out,
            workers=workers,
            ray=ray,
            seed=seed,
            sets=set_ or [],
            max_time=max_time,
        )
    )


def main() -> None:
    """Entry point of the ``suture`` console script."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
