"""suture sweep: spec parser, seeds, Wilson intervals, process pool, resume, Ray."""

from __future__ import annotations

import csv
import importlib.util
import io
import math
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binomtest

from suture_engine.report.cli_sweep import sweep_command
from suture_engine.report.sweep import (
    RunJob,
    RunRow,
    SweepConfig,
    SweepError,
    VarySpecError,
    make_jobs,
    parse_vary,
    run_job,
    run_sweep,
    summarise,
    wilson_interval,
)

STEPS = Path(__file__).parent / "procedures" / "steps.yaml"
VARY = "hold_time=uniform(20 ms, 60 ms)"


# -- spec parser ----------------------------------------------------------------------------


def test_parse_good_specs() -> None:
    n = parse_vary("offset=normal(0 mm, 2 mm)")
    assert (n.name, n.kind, n.numbers, n.unit) == ("offset", "normal", (0.0, 2.0), "mm")
    u = parse_vary("k = uniform(-1.5e-1, 3)")
    assert (u.name, u.kind, u.numbers, u.unit) == ("k", "uniform", (-0.15, 3.0), "")
    c = parse_vary("algo=choice(1, 2, three)")
    assert (c.kind, c.choices) == ("choice", ("1", "2", "three"))


@pytest.mark.parametrize(
    ("spec", "position", "expected"),
    [
        ("hold_time", 9, "'='"),
        ("9x=normal(0,1)", 0, "a parameter name"),
        ("x=gauss(0,1)", 2, "one of normal"),
        ("x=normal 0,1", 9, "'(' after normal"),
        ("x=normal(0,1", 12, "')' closing"),
        ("x=normal(0,1)z", 13, "nothing after"),
        ("x=normal(0)", 10, "exactly two numbers"),
        ("x=uniform(0,1,2)", 14, "exactly two numbers"),
        ("x=normal(0, abc)", 12, "a number"),
        ("x=normal(0,-1)", 11, "sigma >= 0"),
        ("x=uniform(3,1)", 12, "b >= a"),
        ("x=uniform(1 mm,2 s)", 15, "the same unit"),
        ("x=choice(a,,b)", 11, "a value"),
    ],
)
def test_bad_specs_are_located(spec: str, position: int, expected: str) -> None:
    with pytest.raises(VarySpecError) as info:
        parse_vary(spec)
    assert info.value.position == position
    assert expected in info.value.expected
    assert spec in info.value.message


def test_sampled_values_follow_the_distribution() -> None:
    rng = np.random.default_rng(0)
    spec = parse_vary("x=normal(5 mm, 2 mm)")
    values = [float(spec.sample(rng).split()[0]) for _ in range(4000)]
    assert abs(np.mean(values) - 5.0) < 0.15
    assert abs(np.std(values) - 2.0) < 0.15
    spec = parse_vary("x=uniform(1, 3)")
    values = [float(spec.sample(rng)) for _ in range(2000)]
    assert 1.0 <= min(values) and max(values) <= 3.0


# -- seeds ----------------------------------------------------------------------------------


def _config(runs: int, seed: int = 0, vary: Sequence[str] = (VARY,)) -> SweepConfig:
    return SweepConfig(STEPS, runs, tuple(parse_vary(v) for v in vary), seed, (), 5.0)


def test_run_inputs_depend_only_on_base_seed_and_index(tmp_path: Path) -> None:
    short = make_jobs(_config(3), tmp_path)
    long = make_jobs(_config(6), tmp_path)
    assert [(j.seed, dict(j.values)) for j in short] == [(j.seed, dict(j.values)) for j in long[:3]]
    other = make_jobs(_config(3, seed=1), tmp_path)
    assert [j.seed for j in other] != [j.seed for j in short]
    assert len({j.seed for j in long}) == len(long)
    # the seed is SeedSequence([base, i])'s first word (independent recomputation)
    expected = int(np.random.SeedSequence([0, 4]).generate_state(1)[0]) & 0x7FFFFFFF
    assert long[4].seed == expected


# -- statistics -----------------------------------------------------------------------------


@pytest.mark.parametrize(("k", "n"), [(0, 5), (1, 5), (3, 7), (7, 7), (12, 40), (50, 100)])
@pytest.mark.parametrize("confidence", [0.9, 0.95, 0.99])
def test_wilson_matches_scipy(k: int, n: int, confidence: float) -> None:
    ci = binomtest(k, n).proportion_ci(confidence_level=confidence, method="wilson")
    lo, hi = wilson_interval(k, n, confidence)
    assert lo == pytest.approx(ci.low, abs=1e-12)
    assert hi == pytest.approx(ci.high, abs=1e-12)


def test_wilson_closed_form_at_zero_successes() -> None:
    z = 1.959963984540054
    n = 10
    lo, hi = wilson_interval(0, n)
    assert lo == pytest.approx(0.0, abs=1e-15)
    assert hi == pytest.approx(z * z / (n + z * z), rel=1e-12)


def test_wilson_rejects_bad_counts() -> None:
    with pytest.raises(ValueError):
        wilson_interval(6, 5)
    assert wilson_interval(0, 0) == (0.0, 1.0)


def _row(i: int, outcome: str, condition: str, tension: float) -> RunRow:
    return RunRow(i, i, {}, condition, outcome, "", "", tension, 1.0, 1.0, 0, 0, "")


def test_summary_per_condition() -> None:
    rows = [_row(0, "succeeded", "a=1", 1.0), _row(1, "failed", "a=1", 2.0)]
    rows += [_row(2, "succeeded", "a=2", 3.0), _row(3, "error", "a=2", math.nan)]
    s = summarise(rows)
    assert s["conditions"]["a=1"]["succeeded"] == 1
    assert s["conditions"]["a=1"]["wilson_low"] == pytest.approx(wilson_interval(1, 2)[0])
    assert s["conditions"]["a=2"]["outcomes"] == {"error": 1, "succeeded": 1}
    assert s["max_tension_N"]["n"] == 3
    assert s["max_tension_N"]["mean"] == pytest.approx(2.0)
    assert s["max_tension_N"]["std"] == pytest.approx(1.0)
    assert s["errors"] == 1


# -- real sweeps ----------------------------------------------------------------------------


def _read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def pool_sweep(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("sweep")
    stdout, err = io.StringIO(), io.StringIO()
    code = sweep_command(
        STEPS, runs=3, vary=[VARY], out=out, workers=2,
        max_time=5.0, stdout=stdout, err=err,
    )  # fmt: skip
    assert code == 0, err.getvalue()
    return out


def test_process_pool_sweep_writes_results(pool_sweep: Path) -> None:
    rows = _read_csv(pool_sweep / "results.csv")
    assert sorted(int(r["run"]) for r in rows) == [0, 1, 2]
    jobs = {j.run: j for j in make_jobs(_config(3), pool_sweep)}
    for r in rows:
        job = jobs[int(r["run"])]
        assert int(r["seed"]) == job.seed
        assert r["vary:hold_time"] == job.values["hold_time"]
        assert r["outcome"] == "succeeded"  # steps.yaml: three holds, no contact
        held = float(r["vary:hold_time"].split()[0]) / 1000.0
        # prepare holds hold_time, then 300 ms + 100 ms: the simulated time says it ran
        assert float(r["sim_time_s"]) == pytest.approx(held + 0.4, abs=2e-3)
    assert (pool_sweep / "summary.json").is_file()
    assert (pool_sweep / "sweep.png").read_bytes().startswith(b"\x89PNG")
    assert (pool_sweep / "runs" / "run-00002" / "trace.mcap").is_file()


def test_resume_does_not_redo_finished_runs(pool_sweep: Path, tmp_path: Path) -> None:
    # An interrupted sweep: run 1's row is missing and a torn line ends the file.
    out = tmp_path / "resume"
    out.mkdir()
    (out / "sweep.json").write_bytes((pool_sweep / "sweep.json").read_bytes())
    lines = (pool_sweep / "results.csv").read_text(encoding="utf-8").splitlines(keepends=True)
    kept = [lines[0], *(ln for ln in lines[1:] if not ln.startswith("1,"))]
    (out / "results.csv").write_text("".join(kept) + "1,12345,torn", encoding="utf-8")
    asked: list[int] = []

    def runner(jobs: Sequence[RunJob]) -> Iterator[RunRow]:
        for job in jobs:
            asked.append(job.run)
            yield run_job(job)

    result = run_sweep(_config(3), out, runner=runner)
    assert asked == [1]
    assert result.ran == [1]
    rows = _read_csv(out / "results.csv")
    assert sorted(int(r["run"]) for r in rows) == [0, 1, 2]
    assert all(r["outcome"] == "succeeded" for r in rows)
    # a second call finds nothing to do
    again = run_sweep(_config(3), out, runner=runner)
    assert again.ran == [] and asked == [1]


def test_resume_refuses_another_sweep(pool_sweep: Path, tmp_path: Path) -> None:
    out = tmp_path / "other"
    out.mkdir()
    (out / "sweep.json").write_bytes((pool_sweep / "sweep.json").read_bytes())
    with pytest.raises(SweepError, match="another sweep"):
        run_sweep(_config(3, seed=7), out, runner=lambda jobs: iter(()))


def test_choice_conditions_each_get_an_interval(tmp_path: Path) -> None:
    config = _config(4, vary=["hold_time=choice(20 ms, 40 ms)"])
    result = run_sweep(config, tmp_path)
    conditions = result.summary["conditions"]
    assert set(conditions) <= {"hold_time=20 ms", "hold_time=40 ms"}
    assert sum(c["runs"] for c in conditions.values()) == 4


def test_cli_errors_are_located_and_exit_codes(tmp_path: Path) -> None:
    err = io.StringIO()
    code = sweep_command(STEPS, runs=2, vary=["hold_time=normal(1 ms"], out=tmp_path / "a", err=err)
    assert code == 1
    assert "column" in err.getvalue() and "')' closing" in err.getvalue()
    err = io.StringIO()
    code = sweep_command(STEPS, runs=2, vary=["nope=choice(1)"], out=tmp_path / "b", err=err)
    assert code == 2
    assert "no parameter named 'nope'" in err.getvalue()
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


@pytest.mark.skipif(importlib.util.find_spec("ray") is not None, reason="ray is installed")
def test_missing_ray_is_a_clear_error(tmp_path: Path) -> None:
    err = io.StringIO()
    code = sweep_command(STEPS, runs=1, vary=[VARY], out=tmp_path, ray="local", err=err)
    assert code == 2
    assert "suture-engine[ray]" in err.getvalue()


@pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="ray is not installed")
def test_ray_local_sweep(tmp_path: Path) -> None:
    import ray

    try:
        result = run_sweep(_config(1), tmp_path, ray_address="local")
    finally:
        ray.shutdown()
    assert [r.run for r in result.rows] == [0]
    assert all(r.outcome == "succeeded" for r in result.rows)


@pytest.mark.slow
def test_sigint_stops_the_sweep_and_resume_runs_only_the_rest(tmp_path: Path) -> None:
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "killed"
    # runs of 4.4 s simulated (about a second of wall time or more each), so the signal
    # lands while the second run is under way: with 0.8 s runs a fast machine finished
    # the whole sweep between the first row and the signal
    vary = "hold_time=uniform(4 s, 4 s)"
    cmd = [sys.executable, "-m", "suture_engine.cli", "sweep", str(STEPS), "--runs", "3"]
    cmd += ["--vary", vary, "--out", str(out), "--max-time", "5"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    results = out / "results.csv"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if results.is_file() and len(results.read_text(encoding="utf-8").splitlines()) >= 2:
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the sweep ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err
    assert "run again to resume" in err
    assert "Traceback" not in err
    rows = _read_csv(results)
    finished = sorted(int(r["run"]) for r in rows)
    assert 1 <= len(finished) < 3
    assert all(r["outcome"] == "succeeded" for r in rows)  # the interrupted run is not a row
    asked: list[int] = []

    def runner(jobs: Sequence[RunJob]) -> Iterator[RunRow]:
        for job in jobs:
            asked.append(job.run)
            yield run_job(job)

    result = run_sweep(_config(3, vary=[vary]), out, runner=runner)
    assert sorted(asked) == sorted(set(range(3)) - set(finished))
    assert sorted(r.run for r in result.rows) == [0, 1, 2]


def test_knot_type_of_one_knot_and_of_one_per_stitch() -> None:
    from suture_engine.report.sweep import _knot_type

    assert _knot_type({"type": "square"}) == "square"
    assert _knot_type([{"type": "square"}, {"type": "unknot"}, {}]) == "square+unknot+?"
    assert _knot_type(None) == ""
