"""Tests of the golden-trace pytest plugin, run in a scratch project with pytester."""

from __future__ import annotations

import importlib.metadata
import os
from pathlib import Path

import pytest

pytest_plugins = ["pytester"]

_TEST_FILE = """
import os
from suture_engine.trace.writer import TraceMeta, TraceWriter

def produce(out):
    gain = float(os.environ.get("DEMO_GAIN", "1.0"))
    with TraceWriter(out / "trace.mcap", TraceMeta("demo", 3, 1000.0)) as w:
        for k in range(20):
            t = k * 1_000_000
            w.write("/command/left", t, {"kind": "velocity", "values": [gain * k, 0.5]})
            if k == 10:
                w.write("/events", t, {"name": "reached", "kind": "planned"})

def test_demo(golden_trace):
    golden_trace("demo", produce)
"""


def _plugin_args() -> list[str]:
    """Load the plugin explicitly only when entry points are not autoloaded."""
    names = {e.name for e in importlib.metadata.entry_points(group="pytest11")}
    if "suture_engine" in names and not os.environ.get("PYTEST_DISABLE_PLUGIN_AUTOLOAD"):
        return []
    return ["-p", "suture_engine.trace.pytest_plugin"]


@pytest.fixture
def project(pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch) -> pytest.Pytester:
    monkeypatch.delenv("DEMO_GAIN", raising=False)
    pytester.makeini("[pytest]\n")
    pytester.makepyfile(test_demo=_TEST_FILE)
    return pytester


def _run(p: pytest.Pytester, *args: str, subprocess: bool = False) -> pytest.RunResult:
    run = p.runpytest_subprocess if subprocess else p.runpytest
    return run("-p", "no:cacheprovider", *_plugin_args(), *args)


def test_missing_golden_fails_and_says_how_to_record(project: pytest.Pytester) -> None:
    result = _run(project)
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*no golden trace at*demo.mcap*--update-golden*"])


def test_record_then_match_then_diverge(
    project: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    _run(project, "--update-golden").assert_outcomes(passed=1)
    golden = project.path / "tests" / "golden" / "demo.mcap"
    assert golden.is_file() and golden.stat().st_size < 2 * 1024 * 1024
    recorded = golden.read_bytes()
    _run(project).assert_outcomes(passed=1)
    # a changed parameter: commands differ from tick 1 on (0 * gain is still 0)
    monkeypatch.setenv("DEMO_GAIN", "1.5")
    result = _run(project)
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        [
            "*traces diverge: first at tick 1 *",
            "*channel*/command/left*",
            "*field*values?0?*",
            "*expected*1.0*",
            "*actual*1.5*",
        ]
    )
    assert golden.read_bytes() == recorded  # a failing comparison never rewrites the golden
    _run(project, "--update-golden").assert_outcomes(passed=1)
    assert golden.read_bytes() != recorded
    _run(project).assert_outcomes(passed=1)


def test_golden_size_limit(pytester: pytest.Pytester) -> None:
    pytester.makeini("[pytest]\ngolden_max_bytes = 200\n")
    pytester.makepyfile(test_demo=_TEST_FILE)
    result = _run(pytester, "--update-golden")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*over the 200-byte limit*"])
    assert not (pytester.path / "tests" / "golden" / "demo.mcap").exists()


def test_golden_dir_option(pytester: pytest.Pytester) -> None:
    pytester.makeini("[pytest]\ngolden_dir = goldens/here\n")
    pytester.makepyfile(test_demo=_TEST_FILE)
    _run(pytester, "--update-golden").assert_outcomes(passed=1)
    assert (pytester.path / "goldens" / "here" / "demo.mcap").is_file()


def test_producer_without_trace_and_bad_name(pytester: pytest.Pytester) -> None:
    pytester.makeini("[pytest]\n")
    pytester.makepyfile(
        test_bad="""
import pytest

def test_nothing(golden_trace):
    golden_trace("empty", lambda out: None)

def test_name(golden_trace):
    with pytest.raises(ValueError):
        golden_trace("../escape", lambda out: None)
"""
    )
    result = _run(pytester, "--update-golden")
    result.assert_outcomes(failed=1, passed=1)
    result.stdout.fnmatch_lines(["*the producer wrote no trace*"])


def test_update_option_is_in_the_help(pytester: pytest.Pytester) -> None:
    result = _run(pytester, "--help")
    result.stdout.fnmatch_lines(["*--update-golden*"])


@pytest.mark.slow
def test_procedure_run_through_the_runtime(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch, procedures_dir: Path
) -> None:
    """golden_trace.procedure runs a real procedure headless; a parameter change is caught."""
    reach = procedures_dir.parent / "tests" / "procedures" / "reach.yaml"
    if not reach.is_file():
        pytest.skip("the runtime's test procedure is not there")
    monkeypatch.delenv("REACH_SPEED", raising=False)
    pytester.makeini("[pytest]\n")
    pytester.makepyfile(
        test_reach=f"""
import os

def test_reach(golden_trace):
    speed = os.environ.get("REACH_SPEED")
    sets = [f"speed={{speed}} mm/s"] if speed else []
    golden_trace.procedure("reach", {str(reach)!r}, seed=0, sets=sets)
"""
    )
    _run(pytester, "--update-golden", subprocess=True).assert_outcomes(passed=1)
    golden = pytester.path / "tests" / "golden" / "reach.mcap"
    assert 0 < golden.stat().st_size <= 2 * 1024 * 1024
    _run(pytester, subprocess=True).assert_outcomes(passed=1)
    monkeypatch.setenv("REACH_SPEED", "45")
    result = _run(pytester, subprocess=True)
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*traces diverge: first at tick *", "*channel*"])
