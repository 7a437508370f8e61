"""A pytest plugin for golden-trace tests of procedures.

Installed with suture-engine (entry point ``pytest11``), it adds:

- the ``golden_trace`` fixture: call it with a name and a function that runs a
  procedure and writes a trace; it asserts that the trace matches
  ``tests/golden/<name>.mcap`` within explicit tolerances, and fails with a
  readable diff that names the first diverging tick and signal;
- the ``--update-golden`` option, which re-records the golden traces instead;
- the ``golden_dir`` ini option (default ``tests/golden``, relative to the rootdir)
  and ``golden_max_bytes`` (default 2 MB: golden traces stay small).

Example:
    >>> def test_reach_matches_golden(golden_trace):
    ...     golden_trace.procedure("reach", "procedures/reach.yaml", seed=0)
    >>> def test_custom_producer(golden_trace):
    ...     golden_trace("mine", lambda out: my_run(out / "trace.mcap"))

The plugin imports nothing heavy until the fixture is used.
"""

from __future__ import annotations

import os
import re
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Union

import pytest

if TYPE_CHECKING:
    from suture_engine.trace.golden import GoldenResult, ToleranceSpec

__all__ = ["GoldenTrace", "golden_trace", "pytest_addoption"]

_NAME = re.compile(r"^[A-Za-z0-9_.\-]+$")
_DEFAULT_MAX_BYTES = 2 * 1024 * 1024

Producer = Callable[[Path], Union[str, "os.PathLike[str]", None]]
"""Runs a procedure given an output folder; returns the trace path, or ``None`` for
``<folder>/trace.mcap``."""


def pytest_addoption(parser: pytest.Parser) -> None:
    """Adds ``--update-golden`` and the ``golden_dir`` / ``golden_max_bytes`` ini options."""
    group = parser.getgroup("suture-engine", "suture-engine golden traces")
    group.addoption(
        "--update-golden",
        action="store_true",
        default=False,
        help="re-record golden traces instead of comparing against them",
    )
    parser.addini(
        "golden_dir", "folder of golden traces, relative to the rootdir", default="tests/golden"
    )
    parser.addini(
        "golden_max_bytes", "largest golden trace allowed [byte]", default=str(_DEFAULT_MAX_BYTES)
    )


class GoldenTrace:
    """Runs a producer and checks its trace against a golden one (the fixture's value).

    Args:
        golden_dir: the folder of golden traces.
        work_dir: a fresh folder for the producer's output.
        update: re-record instead of comparing.
        max_bytes: the largest golden trace allowed [byte].
    """

    def __init__(self, golden_dir: Path, work_dir: Path, update: bool, max_bytes: int) -> None:
        self.golden_dir = golden_dir
        self.work_dir = work_dir
        self.update = update
        self.max_bytes = max_bytes
        self._runs = 0

    def path(self, name: str) -> Path:
        """The golden trace file of ``name``."""
        return self.golden_dir / f"{name}.mcap"

    def __call__(
        self,
        name: str,
        produce: Producer,
        *,
        tolerances: ToleranceSpec | None = None,
        topics: Sequence[str] | None = None,
    ) -> GoldenResult | None:
        """Runs ``produce`` and asserts its trace matches the golden trace ``name``.

        Args:
            name: the golden trace's name (letters, digits, ``_.-``).
            produce: runs the procedure; gets an empty output folder and returns the
                trace path (``None`` means ``<folder>/trace.mcap``).
            tolerances: the tolerances (default: ``DEFAULT_TOLERANCES``).
            topics: topics or globs to compare (default: all).

        Returns:
            The comparison result, or ``None`` when the golden trace was re-recorded.
        """
        from suture_engine.trace.errors import TraceError
        from suture_engine.trace.golden import DEFAULT_TOLERANCES, compare
        from suture_engine.trace.reader import TraceReader

        if not _NAME.match(name):
            raise ValueError(f"golden trace name {name!r} must match {_NAME.pattern}")
        self._runs += 1
        out = self.work_dir / f"golden-{self._runs}-{name}"
        out.mkdir(parents=True, exist_ok=True)
        produced = produce(out)
        trace = Path(produced) if produced is not None else out / "trace.mcap"
        if not trace.is_file():
            pytest.fail(f"golden {name}: the producer wrote no trace at {trace}", pytrace=False)
        try:
            actual = TraceReader(trace, allow_truncated=False)
        except TraceError as exc:
            pytest.fail(f"golden {name}: the produced trace is unusable: {exc}", pytrace=False)
        golden = self.path(name)
        if self.update:
            size = trace.stat().st_size
            if size > self.max_bytes:
                pytest.fail(
                    f"golden {name}: trace is {size} bytes, over the {self.max_bytes}-byte limit;"
                    " record a shorter run or fewer channels",
                    pytrace=False,
                )
            golden.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(trace, golden)
            return None
        if not golden.is_file():
            pytest.fail(
                f"golden {name}: no golden trace at {golden}; record it with --update-golden",
                pytrace=False,
            )
        try:
            expected = TraceReader(golden, allow_truncated=False)
        except TraceError as exc:
            pytest.fail(f"golden {name}: the golden trace is unusable: {exc}", pytrace=False)
        result = compare(expected, actual, tolerances or DEFAULT_TOLERANCES, topics=topics)
        if not result.ok:
            pytest.fail(
                f"golden {name}: {golden} does not match {trace}\n{result.text}\n"
                "(re-record with --update-golden if the change is intended)",
                pytrace=False,
            )
        return result

    def procedure(
        self,
        name: str,
        procedure_file: str | os.PathLike[str],
        *,
        seed: int = 0,
        sets: Sequence[str] = (),
        operator_file: str | os.PathLike[str] | None = None,
        max_time_s: float = 300.0,
        tolerances: ToleranceSpec | None = None,
        topics: Sequence[str] | None = None,
    ) -> GoldenResult | None:
        """Runs a procedure file headless and checks its trace against the golden ``name``.

        Args:
            name: the golden trace's name.
            procedure_file: the procedure (YAML).
            seed: the random seed.
            sets: ``name=value`` parameter overrides.
            operator_file: a scripted operator file.
            max_time_s: simulated time limit [s].
            tolerances: the tolerances (default: ``DEFAULT_TOLERANCES``).
            topics: topics or globs to compare (default: all).

        Returns:
            The comparison result, or ``None`` when the golden trace was re-recorded.
        """
        from suture_engine.runtime.run import run_procedure

        def produce(out: Path) -> Path:
            result = run_procedure(
                Path(procedure_file),
                seed=seed,
                sets=sets,
                out=out,
                operator_file=None if operator_file is None else Path(operator_file),
                max_time_s=max_time_s,
            )
            return result.trace

        return self(name, produce, tolerances=tolerances, topics=topics)


@pytest.fixture
def golden_trace(request: pytest.FixtureRequest, tmp_path: Path) -> GoldenTrace:
    """Asserts that a procedure's trace matches ``<golden_dir>/<name>.mcap``.

    See :class:`GoldenTrace`; ``--update-golden`` re-records instead.
    """
    config = request.config
    golden_dir = Path(str(config.getini("golden_dir")))
    if not golden_dir.is_absolute():
        golden_dir = Path(config.rootpath) / golden_dir
    max_bytes = int(str(config.getini("golden_max_bytes")))
    update = bool(config.getoption("--update-golden"))
    return GoldenTrace(golden_dir, tmp_path, update, max_bytes)
