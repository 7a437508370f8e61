"""The corpus of broken procedures: each gets its expected, located problem.

Each ``tests/corpus/*.yaml`` starts with ``# expect: CODE [FILE] [LINE:COL]``:
the problem code, the file it is reported in when not the corpus file itself
(relative to ``tests/corpus``), and its 1-based line and column. Every file is
checked in-process; a representative subset also through the real ``suture``
command in a subprocess (exit 1, located output, no traceback).
"""

from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import pytest

from suture_engine.validation.checks import validate_file
from suture_engine.validation.report import validate_command

ROOT = Path(__file__).resolve().parent.parent
CORPUS = ROOT / "tests" / "corpus"
FILES = sorted(CORPUS.glob("*.yaml"))
_EXPECT = re.compile(
    r"^# expect: (?P<code>[a-z-]+)(?: (?P<file>[\w./-]+\.yaml))?"
    r"(?: (?P<line>\d+):(?P<col>\d+))?\s*$"
)
CHECKS_COVERED = {
    "yaml-syntax", "duplicate-key", "yaml-tag", "yaml-too-large", "yaml-too-deep", "schema",
    "unknown-key", "missing-field", "unit-mismatch", "out-of-bounds", "bad-value",
    "undefined-state", "unreachable-state", "no-terminal", "unbounded-retry", "bad-expression",
    "missing-use", "cyclic-use", "include-outside", "unknown-param", "bad-param",
    "missing-param", "unknown-point", "unknown-role", "unknown-robot", "unknown-skill",
    "unreachable", "singularity", "tension-limit", "unstable-gains", "tool-mismatch",
    "missing-scene", "include-too-deep", "taut-within-without-guard", "unknown-event",
    "bad-event-target",
}  # fmt: skip


class Expect(NamedTuple):
    code: str
    file: Path
    line: int | None
    column: int | None


def _expect(path: Path) -> Expect:
    first = path.read_text(encoding="utf-8").splitlines()[0]
    match = _EXPECT.match(first)
    assert match, f"{path.name}: first line must be '# expect: CODE [FILE] [LINE:COL]'"
    file = CORPUS / match["file"] if match["file"] else path
    line = int(match["line"]) if match["line"] else None
    col = int(match["col"]) if match["col"] else None
    return Expect(match["code"], file, line, col)


def test_corpus_is_large_and_covers_every_check() -> None:
    assert len(FILES) >= 40
    assert {_expect(f).code for f in FILES} >= CHECKS_COVERED


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_broken_procedure_gets_its_located_problem(path: Path) -> None:
    expect = _expect(path)
    problems = validate_file(path)
    assert problems, f"{path.name}: no problem found"
    for p in problems:  # every problem is located
        assert p.file and p.line >= 1 and p.column >= 1, p
    matches = [
        p
        for p in problems
        if p.code == expect.code
        and Path(p.file).resolve() == expect.file.resolve()
        and (expect.line is None or (p.line, p.column) == (expect.line, expect.column))
    ]
    listing = "\n".join(p.format() for p in problems)
    assert matches, f"{path.name}: expected {expect}, found:\n{listing}"


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_cli_function_exits_1_with_located_lines(path: Path) -> None:
    out, err = io.StringIO(), io.StringIO()
    assert validate_command([path], out=out, err=err) == 1
    lines = out.getvalue().splitlines()
    assert lines and all(re.match(r"^.+:\d+:\d+: [a-z-]+: .+", line) for line in lines)
    assert "Traceback" not in out.getvalue() + err.getvalue()


SUBSET = [
    "python-tag",
    "alias-bomb",
    "misspelt-state-key",
    "speed-in-degrees",
    "failure-loop",
    "use-cycle",
    "expression-import",
    "target-out-of-reach",
    "gains-unstable-with-delay",
    "scene-misspelt-key",
]


def _suture(*args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    return subprocess.run(
        [sys.executable, "-m", "suture_engine.cli", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
        env=env,
    )


def test_real_cli_on_a_subset_text_and_json() -> None:
    paths = [str((CORPUS / f"{name}.yaml").relative_to(ROOT)) for name in SUBSET]
    text = _suture("validate", *paths)
    assert text.returncode == 1
    assert "Traceback" not in text.stdout + text.stderr
    for name in SUBSET:
        expect = _expect(CORPUS / f"{name}.yaml")
        assert f": {expect.code}: " in text.stdout
    as_json = _suture("validate", "--format", "json", *paths)
    assert as_json.returncode == 1
    records = json.loads(as_json.stdout)
    assert {r["code"] for r in records} >= {_expect(CORPUS / f"{n}.yaml").code for n in SUBSET}
    for r in records:
        assert set(r) == {"file", "line", "column", "path", "code", "message"}


_BRANCH = """\
procedure: branch
scene: scenes/bench.yaml
params:
  check: {type: bool, default: true}
roles: {stitcher: endobot_1, grasper: endobot_2}
initial: a
states:
  a:
    skill: hold
    with: {robot: stitcher, duration: 0.1 s}
    on: {done: end, failed: "${'give-up' if check else 'end'}"}
  give-up:
    when: ${WHEN}
    skill: hold
    with: {robot: grasper, duration: 0.1 s}
    on: {done: missed}
  missed: {outcome: failed}
  end: {outcome: succeeded}
"""


@pytest.mark.parametrize(("check", "when", "unreachable"), [
    (True, "check", []),
    # cut off by the `on:` expression and skipped by `when:`: neither it nor the terminal
    # only it leads to is a problem
    (False, "check", []),
    # cut off and still enabled: both are reported
    (False, "not check", ["give-up", "missed"]),
])  # fmt: skip
def test_a_state_skipped_by_when_and_cut_off_by_an_expression_is_not_unreachable(
    tmp_path: Path, check: bool, when: str, unreachable: list[str]
) -> None:
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "bench.yaml").write_text(
        (CORPUS / "scenes" / "bench.yaml").read_text(encoding="utf-8"), encoding="utf-8"
    )
    path = tmp_path / "branch.yaml"
    text = _BRANCH.replace("WHEN", when).replace("default: true", f"default: {str(check).lower()}")
    path.write_text(text, encoding="utf-8")
    problems = validate_file(path)
    found = sorted(p.message.split("'")[1] for p in problems if p.code == "unreachable-state")
    assert found == unreachable, [p.format() for p in problems]
    assert [p for p in problems if p.code != "unreachable-state"] == []
