"""``suture run`` and ``suture replay``: outputs, exit codes, determinism, crash safety, goldens."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from suture_engine.runtime.run import run_procedure

ROOT = Path(__file__).resolve().parent.parent
PROCS = ROOT / "tests" / "procedures"
GOLDEN = ROOT / "tests" / "golden"
SUTURE = [sys.executable, "-c", "from suture_engine.cli import main; main()"]

SUMMARY_KEYS = {
    "procedure",
    "outcome",
    "final_state",
    "sim_time_s",
    "wall_time_s",
    "real_time_factor",
    "control_rate_hz",
    "max_tension_N",
    "tension_limit_N",
    "violations",
    "retries",
    "operator_events",
    "metrics",
    "knot",
}


def _suture(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*SUTURE, *args], cwd=cwd, capture_output=True, text=True, timeout=240, check=False
    )


def test_run_writes_trace_and_summary(tmp_path: Path) -> None:
    out = tmp_path / "d"
    res = _suture("run", str(PROCS / "steps.yaml"), "--backend", "ideal", "--out", str(out))
    assert res.returncode == 0, res.stdout + res.stderr
    assert "succeeded" in res.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary)
    assert summary["outcome"] == "succeeded" and summary["knot"] is None
    assert summary["control_rate_hz"] == 1000.0
    assert summary["tension_limit_N"] == pytest.approx(4.707, abs=1e-3)
    assert (out / "trace.mcap").stat().st_size > 0


def test_run_without_out_makes_a_folder_under_runs(tmp_path: Path) -> None:
    res = _suture("run", str(PROCS / "steps.yaml"), "--backend", "ideal", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    [folder] = list((tmp_path / "runs").iterdir())
    assert (folder / "trace.mcap").is_file() and (folder / "summary.json").is_file()


def test_aborted_run_exits_1_without_traceback(tmp_path: Path) -> None:
    res = _suture(
        "run",
        str(PROCS / "steps.yaml"),
        "--backend",
        "ideal",
        "--operator",
        str(PROCS / "ops-abort.yaml"),
        "--out",
        str(tmp_path / "d"),
    )
    assert res.returncode == 1
    assert "aborted" in res.stdout and "Traceback" not in res.stderr
    assert json.loads((tmp_path / "d" / "summary.json").read_text())["outcome"] == "aborted"


@pytest.mark.parametrize(
    ("args", "code", "words"),
    [
        (["run", "no/such/file.yaml"], 2, "no such file"),
        (["run", str(PROCS / "steps.yaml"), "--set", "nope=1"], 2, "hold_time"),
        (["run", str(PROCS / "steps.yaml"), "--set", "justtext"], 2, "name=value"),
        (["run", str(PROCS / "steps.yaml"), "--backend", "pybulet"], 2, "pybullet"),
        (["run", str(PROCS / "scene.yaml")], 1, "procedure"),
        (["run", str(PROCS / "steps.yaml"), "--operator", str(PROCS / "scene.yaml")], 1, ""),
        (["replay", "no/such/trace.mcap"], 2, "no such file"),
        (["replay", str(PROCS / "steps.yaml")], 1, "trace"),
    ],
)
def test_bad_input_is_a_clear_error(args: list[str], code: int, words: str) -> None:
    res = _suture(*args)
    assert res.returncode == code, res.stdout + res.stderr
    assert "Traceback" not in res.stderr + res.stdout
    assert "error" in res.stderr
    assert words in res.stderr


def test_same_seed_gives_a_byte_identical_trace(tmp_path: Path) -> None:
    traces = []
    for name in ("a", "b"):
        result = run_procedure(
            PROCS / "steps.yaml",
            backend="pybullet",
            seed=7,
            operator_file=PROCS / "ops-snag.yaml",
            out=tmp_path / name,
        )
        traces.append(result.trace.read_bytes())
    assert traces[0] == traces[1]
    other = run_procedure(PROCS / "steps.yaml", backend="pybullet", seed=7, out=tmp_path / "c")
    assert other.trace.read_bytes() != traces[0]  # the operator's pull changed the run


def test_same_seed_gives_a_byte_identical_trace_with_move_constrained(tmp_path: Path) -> None:
    # The OSQP solve adapts rho on an iteration count, never on the clock.
    traces = [
        run_procedure(PROCS / "constrained.yaml", backend="pybullet", seed=3, out=tmp_path / n)
        for n in ("a", "b")
    ]
    assert [r.summary.outcome for r in traces] == ["succeeded", "succeeded"]
    data = [r.trace.read_bytes() for r in traces]
    assert data[0] == data[1]
    from suture_engine.trace.reader import TraceReader

    qp = [m.data for m in TraceReader(traces[0].trace).messages(["/qp/endobot_1"])]
    assert len(qp) > 1000 and all(d["status"] == "solved" for d in qp)
    assert "solve_time_us" not in qp[0]  # wall clock is not in the trace


def test_changing_a_move_constrained_parameter_fails_its_golden_check() -> None:
    res = _suture("replay", "tests/golden/constrained.mcap", "--check", "--set", "depth=12 mm")
    assert res.returncode == 1
    assert "check failed" in res.stdout and "first at tick" in res.stdout
    assert "Traceback" not in res.stderr


@pytest.mark.parametrize("golden", sorted(p.name for p in GOLDEN.glob("*.mcap")))
def test_golden_traces_replay_and_check(golden: str) -> None:
    path = GOLDEN / golden
    assert path.stat().st_size <= 2 * 1024 * 1024
    res = _suture("replay", str(path.relative_to(ROOT)), "--check")
    assert res.returncode == 0, res.stdout + res.stderr
    assert "check passed" in res.stdout


def test_changing_a_parameter_fails_the_check_at_the_first_diverging_tick() -> None:
    res = _suture("replay", "tests/golden/reach.mcap", "--check", "--set", "height=30 mm")
    assert res.returncode == 1
    assert "check failed" in res.stdout
    assert "first at tick 1 " in res.stdout
    assert "/command/endobot_1" in res.stdout
    assert "Traceback" not in res.stderr


def test_a_killed_run_leaves_a_trace_that_replays(tmp_path: Path) -> None:
    out = tmp_path / "killed"
    proc = subprocess.Popen(
        [*SUTURE, "run", "tests/procedures/reach.yaml", "--out", str(out)],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    trace = out / "trace.mcap"
    deadline = time.monotonic() + 60
    # wait for at least two flushed chunks (the writer flushes every simulated second)
    while time.monotonic() < deadline and proc.poll() is None:
        if trace.exists() and trace.stat().st_size > 200_000:
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the run ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not (out / "summary.json").exists()
    res = _suture("replay", str(trace), "--check")
    assert "Traceback" not in res.stderr + res.stdout
    assert res.returncode == 0, res.stdout + res.stderr
    assert "ends early" in res.stdout and "check passed" in res.stdout


def _shared_metrics(procedure: str, out: Path, *sets: str) -> dict:
    extra = [a for s in sets for a in ("--set", s)]
    res = _suture("run", procedure, "--out", str(out), *extra)
    assert res.returncode == 0, res.stdout + res.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "succeeded"
    assert summary["operator_events"] > 0  # the procedure's declared operator pushed
    return dict(summary["metrics"])


def test_shared_control_with_a_declared_operator_meets_the_desired_stiffness(
    tmp_path: Path,
) -> None:
    # One ramped push normal to the line; Kp = 1000 N/m.
    m = _shared_metrics("tests/procedures/shared-short.yaml", tmp_path / "d")
    assert m["desired_stiffness_N_per_m"] == 1000.0
    assert m["max_deviation_m"] > 1e-3  # the push moved the tool off the line
    assert abs(m["constraint_stiffness_N_per_m"] / 1000.0 - 1.0) < 0.05
    for row in (1, 2):
        ratio = m[f"row{row}_max_force_N"] / m[f"row{row}_max_deviation_m"]
        assert ratio == pytest.approx(m[f"row{row}_stiffness_N_per_m"])
    # Without the operator nothing pushes: the deviation stays at numerical noise.
    quiet = run_procedure(
        PROCS / "shared-short.yaml", sets=["operator_file=", "duration=1.2 s"], out=tmp_path / "q"
    )
    assert quiet.summary.operator_events == 0
    assert quiet.summary.metrics["max_deviation_m"] < 1e-5


@pytest.mark.slow
def test_bundled_shared_control_line_meets_table_6_2(tmp_path: Path) -> None:
    m = _shared_metrics("procedures/shared-control-line.yaml", tmp_path / "d")
    desired = m["desired_stiffness_N_per_m"]
    assert desired == 1000.0
    assert abs(m["constraint_stiffness_N_per_m"] / desired - 1.0) < 0.05  # thesis: 1003
    assert m["max_deviation_m"] > 5e-4 and m["max_force_N"] > 0.5


@pytest.mark.slow
def test_bundled_shared_control_circle_reports_table_6_4_rows(tmp_path: Path) -> None:
    m = _shared_metrics("procedures/shared-control-circle.yaml", tmp_path / "d")
    for row in (1, 2):
        e, f = m[f"row{row}_max_deviation_m"], m[f"row{row}_max_force_N"]
        assert e > 1e-4 and f > 0.1
        assert m[f"row{row}_stiffness_N_per_m"] == pytest.approx(f / e)


def test_a_procedure_names_the_backend_a_plain_run_uses(tmp_path: Path) -> None:
    """``backend:`` in the file is what ``suture run FILE`` uses; ``--backend`` overrides it."""
    from suture_engine.trace.reader import TraceReader

    text = (PROCS / "steps.yaml").read_text()
    proc = tmp_path / "steps.yaml"
    proc.write_text(text.replace("scene: scene.yaml", "backend: ideal\nscene: scene.yaml"))
    (tmp_path / "scene.yaml").write_text((PROCS / "scene.yaml").read_text())
    res = _suture("run", str(proc), "--out", str(tmp_path / "own"))
    assert res.returncode == 0, res.stdout + res.stderr
    assert TraceReader(tmp_path / "own" / "trace.mcap").meta["backend"] == "ideal"
    direct = run_procedure(proc, out=tmp_path / "api", max_time_s=5.0)
    assert TraceReader(direct.trace).meta["backend"] == "ideal"
    res = _suture("run", str(proc), "--backend", "pybullet", "--out", str(tmp_path / "given"))
    assert res.returncode == 0, res.stdout + res.stderr
    assert TraceReader(tmp_path / "given" / "trace.mcap").meta["backend"] == "pybullet"
    # without `backend:` the default stays pybullet
    res = _suture("run", str(PROCS / "steps.yaml"), "--out", str(tmp_path / "plain"))
    assert res.returncode == 0, res.stdout + res.stderr
    assert TraceReader(tmp_path / "plain" / "trace.mcap").meta["backend"] == "pybullet"


def test_an_unknown_backend_in_the_file_is_a_located_error(tmp_path: Path) -> None:
    # a folder deep enough that the error line is longer than a terminal's 80 columns:
    # the location must still come out whole (not wrapped), to be copied
    home = tmp_path / "a-procedure-folder-with-a-long-name" / "and-another-one-below-it"
    home.mkdir(parents=True)
    text = (PROCS / "steps.yaml").read_text()
    proc = home / "steps.yaml"
    proc.write_text(text.replace("scene: scene.yaml", "backend: pybulet\nscene: scene.yaml"))
    (home / "scene.yaml").write_text((PROCS / "scene.yaml").read_text())
    for args in (["validate", str(proc)], ["run", str(proc), "--out", str(tmp_path / "x")]):
        res = _suture(*args)
        assert res.returncode != 0
        out = res.stdout + res.stderr
        assert f"{proc}:4" in out and "unknown-backend" in out and "pybullet" in out, out
        assert "Traceback" not in out
    assert not (tmp_path / "x" / "summary.json").exists()


def test_the_declared_backend_is_read_from_the_file_head_only(tmp_path: Path) -> None:
    from suture_engine.runtime.run import DEFAULT_BACKEND, declared_backend

    cases = {
        "named.yaml": ("procedure: p\nbackend: pybullet-surgical\n", "pybullet-surgical"),
        "none.yaml": ("procedure: p\n", DEFAULT_BACKEND),
        "not-a-string.yaml": ("procedure: p\nbackend: [a, b]\n", DEFAULT_BACKEND),
        "not-a-mapping.yaml": ("- a\n- b\n", DEFAULT_BACKEND),
        "broken.yaml": ("procedure: [\n", DEFAULT_BACKEND),
        "binary.yaml": (b"\xff\xfe\x00".decode("latin-1"), DEFAULT_BACKEND),
    }
    for name, (text, expected) in cases.items():
        (tmp_path / name).write_text(text, encoding="latin-1")
        assert declared_backend(tmp_path / name) == expected, name
    assert declared_backend(tmp_path / "missing.yaml") == DEFAULT_BACKEND
    assert DEFAULT_BACKEND == "pybullet"


def test_a_declared_backend_may_depend_on_the_parameters(tmp_path: Path) -> None:
    """``backend: "${...}"`` is evaluated with the parameters, ``--set`` included; a bad
    expression or a value that names no backend is a located error."""
    from suture_engine.runtime.run import DEFAULT_BACKEND, declared_backend
    from suture_engine.trace.reader import TraceReader

    text = (PROCS / "steps.yaml").read_text()
    (tmp_path / "scene.yaml").write_text((PROCS / "scene.yaml").read_text())
    proc = tmp_path / "steps.yaml"
    head = (
        "backend: \"${'ideal' if light else 'pybullet'}\"\nscene: scene.yaml\n"
        "params:\n  light: {type: bool, default: true}\n"
    )
    proc.write_text(text.replace("scene: scene.yaml\nparams:\n", head))
    assert declared_backend(proc) == "ideal"
    assert declared_backend(proc, ["light=false"]) == "pybullet"
    assert declared_backend(proc, ["light=maybe"]) == DEFAULT_BACKEND  # left to the loader
    res = _suture("run", str(proc), "--set", "light=false", "--out", str(tmp_path / "heavy"))
    assert res.returncode == 0, res.stdout + res.stderr
    assert TraceReader(tmp_path / "heavy" / "trace.mcap").meta["backend"] == "pybullet"
    direct = run_procedure(proc, out=tmp_path / "api", max_time_s=5.0)
    assert TraceReader(direct.trace).meta["backend"] == "ideal"
    for bad, code in (("${'ideal' if light else}", "bad-expression"), ("${3}", "unknown-backend")):
        proc.write_text(text.replace("scene: scene.yaml\nparams:\n", head.replace(
            "${'ideal' if light else 'pybullet'}", bad)))  # fmt: skip
        res = _suture("validate", str(proc))
        out = res.stdout + res.stderr
        assert res.returncode != 0 and f"{proc}:4" in out and code in out, out
        assert "Traceback" not in out


def test_a_calibration_error_is_read_from_the_command_line_and_checked(tmp_path: Path) -> None:
    out = tmp_path / "run"
    steps = str(PROCS / "steps.yaml")
    res = _suture("run", steps, "--backend", "ideal", "--out", str(out),
                  "--calibration-error", "endobot_1=1,0,-0.5")  # fmt: skip
    assert res.returncode == 0, res.stderr
    from suture_engine.trace.reader import TraceReader

    meta = TraceReader(out / "trace.mcap").meta
    assert meta.get("extra", meta)["calibration_error"] == {"endobot_1": [1e-3, 0.0, -0.5e-3]}
    bad = _suture("run", steps, "--backend", "ideal", "--calibration-error", "endobot_1=1,0",
                  cwd=tmp_path)  # fmt: skip
    assert bad.returncode == 2
    assert "--calibration-error 'endobot_1=1,0': expected ROBOT=X,Y,Z in mm" in bad.stderr
    unknown = _suture("run", steps, "--backend", "ideal", "--calibration-error", "arm=1,0,0",
                      cwd=tmp_path)  # fmt: skip
    assert unknown.returncode == 1
    assert "calibration_error must be a robot of the scene" in unknown.stderr
    assert not (tmp_path / "runs").exists()  # refused before any output is written


def test_the_printed_summary_gives_the_true_peak_with_when_and_where(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from types import SimpleNamespace

    from suture_engine.runtime.cli_run import _print_summary

    at = {"t_s": 188.5, "state": "autonomous/mirrored-knot.tighten", "joint": 16}
    summary = SimpleNamespace(
        outcome="failed",
        tension_limit_N=7.06,
        metrics={"peak_true_tension_N": 14.62, "peak_true_tension_at": at},
    )
    _print_summary(summary, None)
    out = " ".join(capsys.readouterr().out.split())
    assert "true tension peak (ground truth) 14.620 N at 188.500 s in" in out
    assert "mirrored-knot.tighten, thread joint 16 (over limit 7.06 N)" in out
    _print_summary(SimpleNamespace(outcome="succeeded", metrics={}), None)
    assert "true tension peak" not in capsys.readouterr().out  # no thread simulated


def test_the_printed_summary_gives_the_stitch_metrics_with_their_resolution(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from types import SimpleNamespace

    from suture_engine.runtime.cli_run import _print_summary

    stitches = {
        "count": 2,
        "entry_error_mm": [2.52, 0.4],
        "exit_error_mm": [None, 0.12],
        "entry_resolution_mm": [3.49, 3.5],
        "exit_resolution_mm": [3.5, 3.5],
        "bite_depth_mm": [0.56, 0.81],
        "spacing_mean_mm": 5.294,
        "spacing_sd_mm": 0.282,
        "spacing_resolution_mm": 6.9977,
    }
    _print_summary(SimpleNamespace(outcome="succeeded", metrics={"stitches": stitches}), None)
    out = " ".join(capsys.readouterr().out.split())
    assert (
        "stitches (ground truth) 2 bites; entry/exit 0.12-2.52 mm from their points "
        "(resolution 3.5 mm); depth 0.56-0.81 mm; spacing 5.29 ± 0.28 mm (resolution 7.0 mm)"
    ) in out
    one = {"count": 1, "entry_error_mm": [None], "exit_error_mm": [None], "bite_depth_mm": [0.5],
           "spacing_mean_mm": None}  # fmt: skip
    _print_summary(SimpleNamespace(outcome="succeeded", metrics={"stitches": one}), None)
    assert "stitches (ground truth) 1 bite; depth 0.50 mm" in " ".join(
        capsys.readouterr().out.split()
    )
    _print_summary(SimpleNamespace(outcome="succeeded", metrics={"stitches": {"count": 0}}), None)
    assert "stitches" not in capsys.readouterr().out  # no bite: no row


def test_the_threads_model_is_read_from_the_command_line_and_recorded(tmp_path: Path) -> None:
    from suture_engine.trace.reader import TraceReader

    out = tmp_path / "run"
    res = _suture("run", "procedures/square-knot.yaml", "--out", str(out), "--max-time", "0.05",
                  "--thread-damping", "20 1/s", "--thread-weight", "4 g/m")  # fmt: skip
    assert res.returncode == 1, res.stderr  # stopped by the time limit
    meta = TraceReader(out / "trace.mcap").meta
    options = meta.get("extra", meta)["backend_options"]
    assert options == {"thread_damping": 20.0, "thread_weight": pytest.approx(4e-3)}
    shown = _suture("trace", str(out / "trace.mcap"))
    assert '"thread_damping": 20.0' in shown.stdout
    steps = str(PROCS / "steps.yaml")
    for flag, value, message in (
        ("--thread-damping", "20 mm", "expected 1/time (unit 1/s), found length"),
        ("--thread-damping", "-2 1/s", "greater than or equal to 0"),
        ("--thread-weight", "0 g/m", "greater than 0"),
        ("--thread-weight", "4 gx/m", "unknown unit 'gx/m'"),
    ):
        bad = _suture("run", steps, "--backend", "ideal", flag, value, cwd=tmp_path)
        assert bad.returncode == 2 and f"{flag} {value!r}: " in bad.stderr, bad.stderr
        assert message in bad.stderr, bad.stderr
        assert "Traceback" not in bad.stderr
    thread_free = _suture("run", steps, "--backend", "ideal", "--thread-damping", "20",
                          cwd=tmp_path)  # fmt: skip
    assert thread_free.returncode == 1 and "unsupported option" in thread_free.stderr
    assert not (tmp_path / "runs").exists()  # refused before any output is written


def test_the_backend_options_are_recorded_as_json_without_the_window() -> None:
    import numpy as np

    from suture_engine.runtime.run import _meta_extra

    options = {"base_error": {"endobot_1": np.array([1e-3, 0.0, -2e-3])}, "gui": True,
               "friction_scale": np.float64(1.3), "thread_weight": 4e-3}  # fmt: skip
    extra = _meta_extra("p.yaml", [], [], None, options)
    recorded = extra["backend_options"]
    assert recorded == {"base_error": {"endobot_1": [1e-3, 0.0, -2e-3]},
                        "friction_scale": 1.3, "thread_weight": 4e-3}  # fmt: skip
    json.dumps(recorded, allow_nan=False)  # the trace's metadata is JSON
    assert "backend_options" not in _meta_extra("p.yaml", [], [], None, {"gui": True})
