"""The tutorial (``docs/tutorial.md``) works as written.

Its fenced blocks are of two kinds the test understands:

- a block right after a ``<!-- file: NAME -->`` line is a file the reader writes;
- a ``console`` block holds commands, each on a line starting with ``$ ``; a trailing
  ``# exits N`` says the command is meant to fail with exit code N (default 0).

Both are replayed in a temporary folder, in document order, with the ``suture`` of this
checkout. The fast test runs everything but the physics runs and what reads their output;
the slow test runs every command.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import pytest

ROOT = Path(__file__).resolve().parent.parent
TUTORIAL = ROOT / "docs" / "tutorial.md"
FENCE = re.compile(r"^```(\w*)\s*$")
FILE_MARK = re.compile(r"^<!--\s*file:\s*(\S+)\s*-->\s*$")
EXITS = re.compile(r"\s+#\s*exits\s+(\d+)\s*$")
NEEDS_A_RUN = ("run", "plot", "report", "trace", "replay", "diff", "sweep", "steps")


class Step(NamedTuple):
    """One thing the reader does: write a file, or run a command."""

    kind: str  # "file" or "command"
    text: str  # the file's content or the command line
    name: str = ""  # the file's name
    exit_code: int = 0
    line: int = 0


def tutorial_steps(text: str) -> list[Step]:
    """The files and commands of the tutorial, in order."""
    steps: list[Step] = []
    lines = text.splitlines()
    i, pending_file = 0, ""
    while i < len(lines):
        mark = FILE_MARK.match(lines[i])
        if mark:
            pending_file = mark.group(1)
            i += 1
            continue
        fence = FENCE.match(lines[i])
        if not fence:
            if lines[i].strip():
                pending_file = ""
            i += 1
            continue
        start, lang = i + 1, fence.group(1)
        j = start
        while not lines[j].startswith("```"):
            j += 1
        body = lines[start:j]
        if pending_file:
            steps.append(Step("file", "\n".join(body) + "\n", pending_file, line=start + 1))
        elif lang == "console":
            for k, cmd in enumerate(body):
                if cmd.startswith("$ "):
                    m = EXITS.search(cmd)
                    code = int(m.group(1)) if m else 0
                    cmd = cmd[2:] if m is None else cmd[2 : m.start()]
                    steps.append(Step("command", cmd.strip(), exit_code=code, line=start + k + 1))
        pending_file = ""
        i = j + 1
    return steps


def _needs_a_run(command: str) -> bool:
    words = shlex.split(command)
    return len(words) > 1 and words[0] == "suture" and words[1] in NEEDS_A_RUN


def _replay(tmp_path: Path, *, physics: bool) -> int:
    """Write the files and run the commands; return how many commands ran."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    shim = bin_dir / "suture"
    shim.write_text(
        f"#!/bin/sh\nexec {shlex.quote(sys.executable)} -c "
        "'from suture_engine.cli import main; main()' \"$@\"\n"
    )
    shim.chmod(0o755)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}")
    env["COLUMNS"] = "120"
    work = tmp_path / "work"
    work.mkdir()
    ran = 0
    for step in tutorial_steps(TUTORIAL.read_text(encoding="utf-8")):
        if step.kind == "file":
            target = work / step.name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(step.text, encoding="utf-8")
            continue
        if not physics and _needs_a_run(step.text):
            continue
        res = subprocess.run(
            step.text,
            shell=True,
            cwd=work,
            env=env,
            capture_output=True,
            text=True,
            timeout=900,
            check=False,
        )
        where = f"docs/tutorial.md:{step.line}: $ {step.text}"
        assert res.returncode == step.exit_code, f"{where}\n{res.stdout}\n{res.stderr}"
        assert "Traceback" not in res.stderr, f"{where}\n{res.stderr}"
        ran += 1
    return ran


def test_the_parser_reads_files_commands_and_exit_codes() -> None:
    text = (
        "Write it:\n\n<!-- file: a.yaml -->\n```yaml\nx: 1\n```\n\n"
        "```console\n$ suture validate a.yaml\nsome output\n"
        "$ suture validate b.yaml  # exits 1\n```\n"
        "```yaml\nnot: a file\n```\n"
    )
    assert tutorial_steps(text) == [
        Step("file", "x: 1\n", "a.yaml", line=5),
        Step("command", "suture validate a.yaml", line=9),
        Step("command", "suture validate b.yaml", exit_code=1, line=11),
    ]


def test_the_tutorial_writes_a_procedure_and_validates_it(tmp_path: Path) -> None:
    steps = tutorial_steps(TUTORIAL.read_text(encoding="utf-8"))
    assert sum(s.kind == "file" for s in steps) >= 2
    assert any(_needs_a_run(s.text) for s in steps if s.kind == "command")
    assert _replay(tmp_path, physics=False) >= 3


@pytest.mark.slow
def test_every_tutorial_command_succeeds(tmp_path: Path) -> None:
    _replay(tmp_path, physics=True)
    work = tmp_path / "work"
    assert (work / "runs" / "first" / "trace.mcap").is_file()
    assert (work / "runs" / "first" / "running.gif").is_file()
