"""Safety of the process: the expression sandbox, hostile YAML, paths, atomic writes.

- Known Python sandbox escapes written as ``${...}`` in a procedure: each is a
  located ``bad-expression`` problem (file, line, column, field) and nothing runs.
- Resource exhaustion (``9**9**9``, ``'a'*10**10``, deep nesting) is refused
  before it allocates: the peak memory of the evaluation is measured with
  :mod:`tracemalloc`, not its time.
- YAML that constructs Python objects, alias bombs, huge and deeply nested files
  are located problems, and no object is constructed.
- ``scene:``/``use:`` paths that leave the procedure's tree (``..``, absolute,
  through a symbolic link) need the allowance.
- A run writes only under its ``--out`` folder; ``summary.json``, the HTML report
  and the figures are replaced atomically (temp file + rename): a failure between
  the write and the rename leaves neither a half file nor the temp file.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from suture_engine.language.expressions import ExpressionError, Namespace, evaluate
from suture_engine.language.units import Quantity
from suture_engine.validation.checks import validate_file
from suture_engine.validation.problem import Problem

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "bad_input"
PROC = (DATA / "steps.yaml").read_text(encoding="utf-8")
SCENE = (DATA / "scene.yaml").read_text(encoding="utf-8")
_FIELD = "duration: 300 ms"
LINE = next(n for n, line in enumerate(PROC.splitlines(), 1) if _FIELD in line)
COLUMN = PROC.splitlines()[LINE - 1].index(_FIELD) + len("duration: ") + 1

ESCAPES = [
    "().__class__.__mro__[1].__subclasses__()",
    "''.__class__.__mro__",
    "hold_time.__class__",
    "params.__class__",
    "params._values",
    "params.__dict__",
    "scene.tension_limit.__class__",
    "min.__self__",
    "sqrt.__globals__",
    "(lambda: 0).__globals__",
    "(lambda: 0)()",
    "__builtins__",
    "__import__('os').system('touch pwned')",
    "getattr(params, '_values')",
    "vars(params)",
    "type(params)",
    "exec('import os')",
    "eval('1')",
    "compile('1', 'x', 'eval')",
    "open('/etc/passwd').read()",
    "globals()",
    "breakpoint()",
    "f'{hold_time}'",
    "f'{().__class__}'",
    "'{0.__class__}'.format(hold_time)",
    "'%s' % hold_time",
    "'abc'.upper()",
    "'abc'[0]",
    "[x for x in (1, 2)]",
    "[c for c in ().__class__.__bases__]",
    "{x: 1 for x in (1,)}",
    "(x for x in (1,))",
    "{x for x in (1,)}",
    "import os",
    "(y := 3)",
    "min(*[1, 2])",
    "max(key=abs)",
    "1 if True else __import__('os')",
    "hold_time and __import__('os')",
    "min.__call__(1)",
    "lambda: 1",
    "9**9**9",
    "'a'*10**10",
    "10**10*'a'",
    "2**1000",
    "1 << 100000",
    "1e308 * 10",
    "9" * 400 + " * 1",
    "(-8) ** (1 / 3)",
    "1 % 0",
    "1 / 0",
    "sqrt(-1)",
    "(" * 300 + "1" + ")" * 300,
    "not " * 200 + "1",
    "params",
    "scene",
    "\uff48old_time",  # fullwidth h: Python folds it to hold_time (NFKC)
    "\u210eold_time",  # planck constant h, also folded
    "hold_t\u0456me",  # cyrillic i: a different name
    "\uff3f\uff3fimport\uff3f\uff3f('os')",  # fullwidth underscores fold to __import__
    "params.\uff48old_time",
    "...",
    "b'x'",
    "1j",
    "hold_time @ hold_time",
    "hold_time is None",
    "1 in (1,)",
    "x = 1",
    "1; 2",
]


def _names() -> dict[str, Any]:
    return {
        "hold_time": 0.2,
        "params": Namespace("params", {"hold_time": 0.2}),
        "scene": Namespace("scene", {"tension_limit": 3.0}),
    }


@pytest.mark.parametrize("expression", ESCAPES)
def test_escape_is_a_located_problem(expression: str, tmp_path: Path) -> None:
    (tmp_path / "scene.yaml").write_text(SCENE, encoding="utf-8")
    text = PROC.replace(_FIELD, f"duration: {json.dumps('${' + expression + '}')}", 1)
    (tmp_path / "p.yaml").write_text(text, encoding="utf-8")
    cwd = Path.cwd()
    os.chdir(tmp_path)
    try:
        problems = validate_file(tmp_path / "p.yaml")
    finally:
        os.chdir(cwd)
    assert not (tmp_path / "pwned").exists()
    hits = [p for p in problems if p.code == "bad-expression"]
    assert hits, "\n".join(p.format() for p in problems) or "accepted"
    p = hits[0]
    assert Path(p.file).name == "p.yaml" and (p.line, p.column) == (LINE, COLUMN), p.format()
    assert "states.tighten.with.duration" in p.format()


@pytest.mark.parametrize("expression", ESCAPES)
def test_escape_is_refused_before_it_allocates(expression: str) -> None:
    tracemalloc.start()
    try:
        with pytest.raises(ExpressionError):
            evaluate(expression, _names())
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2_000_000, f"{peak} bytes"


@pytest.mark.parametrize(
    ("expression", "expected"),
    [("hold_time * 2", 0.4), ("max(1, 2) + abs(-1)", 3), ("params.hold_time", 0.2)],
)
def test_ordinary_expressions_still_work(expression: str, expected: float) -> None:
    assert evaluate(expression, _names()) == pytest.approx(expected)


_TOKENS = [
    "hold_time", "params", ".", "hold_time", "_values", "__class__", "(", ")", "[", "]", ",",
    "+", "-", "*", "**", "/", "%", " if ", " else ", " and ", " not ", "==", "<", "1", "0",
    "9", "1e308", "'a'", "mm", " N", "min", "sqrt", "lambda", ":", "for", " in ", "f'", "{",
    "}", "\uff48", "import", "__import__", "=", ":=", "@",
]  # fmt: skip


@given(st.lists(st.sampled_from(_TOKENS), max_size=30))
def test_random_token_soup_gives_a_value_or_an_expression_error(tokens: list[str]) -> None:
    text = "".join(tokens)
    try:
        value = evaluate(text, _names())
    except ExpressionError:
        return
    assert value is None or isinstance(value, bool | int | float | str | Quantity), value


# --------------------------------------------------------------------------- YAML


def _problems(tmp_path: Path, text: str) -> list[Problem]:
    (tmp_path / "scene.yaml").write_text(SCENE, encoding="utf-8")
    path = tmp_path / "p.yaml"
    path.write_text(text, encoding="utf-8")
    return validate_file(path)


@pytest.mark.parametrize(
    "tag",
    [
        "!!python/object/apply:os.system ['touch pwned']",
        "!!python/object/new:os.system ['touch pwned']",
        "!!python/name:os.system",
        "!!python/module:os",
        "!!python/object:builtins.object {}",
        "!<tag:yaml.org,2002:python/object/apply:os.system> ['touch pwned']",
        "!include /etc/passwd",
    ],
)
def test_python_tags_construct_nothing(tag: str, tmp_path: Path) -> None:
    cwd = Path.cwd()
    os.chdir(tmp_path)
    try:
        problems = _problems(tmp_path, PROC.replace("description: Three", f"description: {tag} #"))
    finally:
        os.chdir(cwd)
    assert not (tmp_path / "pwned").exists()
    line = next(n for n, s in enumerate(PROC.splitlines(), 1) if s.startswith("description"))
    assert [(p.code, p.line) for p in problems] == [("yaml-tag", line)], problems


_YAML_TOKENS = [
    "[", "]", "{", "}", "&a ", "*a", "&b ", "*b", "!!python/object/apply:os.system ", "- ",
    "\n", "  ", "k: ", "procedure: ", ", ", "<<: ", "!!binary ", "!!set ", "!!omap ", "? ",
    "'", '"', "|\n", ">\n", "%YAML 1.1\n", "---\n", "...\n", "#", "\t", "1e999", ".nan",
    "${", "}", "\ufeff", "\x00", "\\u0000", "~",
]  # fmt: skip


@given(st.lists(st.sampled_from(_YAML_TOKENS), max_size=60))
def test_hostile_yaml_soup_gives_a_document_or_located_problems(tokens: list[str]) -> None:
    from suture_engine.language.source import load_yaml_text
    from suture_engine.validation.problem import ProblemError

    try:
        load_yaml_text("".join(tokens), "soup.yaml")
    except ProblemError as exc:
        assert exc.problems and all(p.file == "soup.yaml" and p.line >= 1 for p in exc.problems)


def _measured(fn: Callable[[], list[Problem]]) -> tuple[list[Problem], int]:
    tracemalloc.start()
    try:
        out = fn()
        return out, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_billion_laughs_is_refused_with_bounded_memory(tmp_path: Path) -> None:
    lines = ["a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for i in range(1, 10):
        refs = ", ".join([f"*a{i - 1}"] * 10)
        lines.append(f"a{i}: &a{i} [{refs}]")
    lines.append("procedure: *a9")
    problems, peak = _measured(lambda: _problems(tmp_path, "\n".join(lines) + "\n"))
    assert [p.code for p in problems] == ["yaml-too-large"], problems
    assert problems[0].line >= 1
    assert peak < 200_000_000, peak  # 10**10 nodes if expanded


def test_huge_file_is_refused_before_parsing(tmp_path: Path) -> None:
    text = PROC + "# " + "x" * 2_000_000 + "\n"
    problems, peak = _measured(lambda: _problems(tmp_path, text))
    assert [(p.code, p.line) for p in problems] == [("yaml-too-large", 1)], problems
    assert peak < 20_000_000, peak


@pytest.mark.parametrize("depth", [100, 5000, 200_000])
def test_deep_nesting_is_a_located_problem(depth: int, tmp_path: Path) -> None:
    text = PROC.replace("description: Three", "description: " + "[" * depth + "]" * depth + " #")
    problems = _problems(tmp_path, text)
    assert problems and problems[0].code in ("yaml-too-deep", "yaml-too-large"), problems
    assert all(p.line >= 1 for p in problems)


def test_deep_block_nesting_is_a_located_problem(tmp_path: Path) -> None:
    body = "".join("  " * i + f"k{i}:\n" for i in range(200)) + "  " * 200 + "v: 1\n"
    problems = _problems(
        tmp_path, PROC + "extra:\n" + "".join("  " + s for s in body.splitlines(True))
    )
    assert [p.code for p in problems] == ["yaml-too-deep"], problems
    assert problems[0].line > PROC.count("\n")


# --------------------------------------------------------------------------- paths


def _tree(tmp_path: Path) -> Path:
    """tmp/outside/scene.yaml and tmp/tree/{scene.yaml,p.yaml}; returns the tree."""
    outside = tmp_path / "outside"
    tree = tmp_path / "tree"
    outside.mkdir()
    tree.mkdir()
    (outside / "scene.yaml").write_text(SCENE, encoding="utf-8")
    (outside / "sub.yaml").write_text(
        PROC.replace("scene: scene.yaml", "scene: ../tree/scene.yaml")
    )
    (tree / "scene.yaml").write_text(SCENE, encoding="utf-8")
    return tree


@pytest.mark.parametrize("how", ["dotdot", "absolute", "symlink-file", "symlink-dir"])
def test_scene_outside_the_tree_needs_the_allowance(how: str, tmp_path: Path) -> None:
    tree = _tree(tmp_path)
    target = {
        "dotdot": "../outside/scene.yaml",
        "absolute": str(tmp_path / "outside" / "scene.yaml"),
        "symlink-file": "link.yaml",
        "symlink-dir": "linked/scene.yaml",
    }[how]
    (tree / "link.yaml").symlink_to(tmp_path / "outside" / "scene.yaml")
    (tree / "linked").symlink_to(tmp_path / "outside", target_is_directory=True)
    path = tree / "p.yaml"
    path.write_text(PROC.replace("scene: scene.yaml", f"scene: {target}"), encoding="utf-8")
    problems = validate_file(path)
    line = next(n for n, s in enumerate(PROC.splitlines(), 1) if s.startswith("scene:"))
    assert [(p.code, p.line) for p in problems] == [("include-outside", line)], problems
    assert validate_file(path, allow_outside=True) == []


def test_use_outside_the_tree_needs_the_allowance(tmp_path: Path) -> None:
    tree = _tree(tmp_path)
    text = PROC.replace(
        "  release:\n    skill: hold\n    with: {robot: grasper, duration: 100 ms}",
        "  release:\n    use: ../outside/sub.yaml",
    )
    path = tree / "p.yaml"
    path.write_text(text, encoding="utf-8")
    problems = validate_file(path)
    line = next(n for n, s in enumerate(text.splitlines(), 1) if "use: ../outside" in s)
    assert ("include-outside", line) in [(p.code, p.line) for p in problems], problems


def _files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*")}


def test_run_writes_only_under_its_out_folder(tmp_path: Path) -> None:
    work = tmp_path / "work"
    work.mkdir()
    shutil.copy(DATA / "steps.yaml", work)
    shutil.copy(DATA / "scene.yaml", work)
    before = _files(tmp_path)
    proc = subprocess.run(
        [sys.executable, "-m", "suture_engine.cli", "run", "steps.yaml", "--out", "../out/r1"],
        cwd=work,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    new = _files(tmp_path) - before
    out = tmp_path / "out" / "r1"
    assert new, "nothing written"
    assert all(p == out.parent or p.is_relative_to(out) for p in new), sorted(new)
    assert {p.name for p in out.iterdir()} == {"trace.mcap", "summary.json"}
    json.loads((out / "summary.json").read_text(encoding="utf-8"))


def _fail_rename(monkeypatch: pytest.MonkeyPatch, module: Any) -> None:
    def boom(src: Any, dst: Any) -> None:
        assert Path(src).exists()  # the temp file was complete when the rename came
        raise OSError(28, "No space left on device", str(dst))

    monkeypatch.setattr(module.os, "replace", boom)


def test_summary_failure_between_write_and_rename_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from suture_engine.runtime import summary as summary_module
    from suture_engine.runtime.run import run_procedure

    _fail_rename(monkeypatch, summary_module)
    out = tmp_path / "out"
    with pytest.raises(OSError, match="No space"):
        run_procedure(DATA / "steps.yaml", out=out, max_time_s=5.0)
    assert sorted(p.name for p in out.iterdir()) == ["trace.mcap"]  # no summary, no temp file


def test_summary_replaces_an_old_one_whole(tmp_path: Path) -> None:
    from suture_engine.runtime.run import run_procedure

    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text('{"old": true}', encoding="utf-8")
    run_procedure(DATA / "steps.yaml", out=out, max_time_s=5.0)
    data = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert "old" not in data and data["procedure"] == "steps"
    assert sorted(p.name for p in out.iterdir()) == ["summary.json", "trace.mcap"]


def test_report_failure_between_write_and_rename_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from suture_engine.report import html

    _fail_rename(monkeypatch, html)
    with pytest.raises(OSError, match="No space"):
        html.write_report("<html></html>", tmp_path / "report.html")
    assert list(tmp_path.iterdir()) == []


def test_figures_failure_between_write_and_rename_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from suture_engine.report import figures
    from suture_engine.report.figures import load_trace, render_figures

    _fail_rename(monkeypatch, figures)
    rendered = render_figures(
        load_trace(ROOT / "tests" / "golden" / "steps-snag.mcap"), ["tension"]
    )
    out = tmp_path / "figs"
    with pytest.raises(OSError, match="No space"):
        figures.write_figures(rendered, out)
    assert not out.exists() or list(out.iterdir()) == []
