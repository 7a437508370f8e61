"""Bad input everywhere a user types: each case gets a located, human error.

Every case is one command line of the real ``suture`` CLI, run in a fresh folder
that holds a valid procedure (``tests/bad_input/steps.yaml``), its scene, a valid
operator file and a valid recorded trace, plus the case's own broken files. Each
case asserts:

- the exit code (1 invalid input or a failed run, 2 usage or I/O error);
- the words that locate the error: the file name and, for a file, the line
  (``name.yaml:LINE:``), and the field or argument that is wrong;
- no "Traceback" anywhere in the output;
- no output left behind as if it were complete (``summary.json``, figures, an
  HTML report, the ``--out`` folder itself).

All cases run in-process through ``typer.testing.CliRunner`` (the same ``app``
the console script calls); the cases marked ``sub`` also run as a real
``python -m suture_engine.cli`` subprocess with separate stdout and stderr.
The procedure corpus of ``tests/corpus`` is checked by ``test_validation_corpus``;
these cases are other kinds.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import NamedTuple

import pytest
from typer.testing import CliRunner

from suture_engine.cli import app

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "bad_input"
GOLDEN = ROOT / "tests" / "golden" / "steps-snag.mcap"
PROC = (DATA / "steps.yaml").read_text(encoding="utf-8")
SCENE = (DATA / "scene.yaml").read_text(encoding="utf-8")
OPS = (DATA / "ops-good.yaml").read_text(encoding="utf-8")
GOOD_TRACE = GOLDEN.read_bytes()
ENV = {**os.environ, "COLUMNS": "400", "NO_COLOR": "1", "TERM": "dumb"}


def _sub(text: str, old: str, new: str) -> str:
    """``text`` with ``old`` replaced once (which must be there)."""
    assert old in text, old
    return text.replace(old, new, 1)


def _line(text: str, fragment: str) -> int:
    """1-based line of the first line of ``text`` that contains ``fragment``."""
    for number, line in enumerate(text.splitlines(), 1):
        if fragment in line:
            return number
    raise AssertionError(fragment)


def _scene_case(new_scene: str) -> dict[str, str | bytes]:
    """A procedure ``p.yaml`` on the broken scene ``s.yaml``."""
    return {"s.yaml": new_scene, "p.yaml": _sub(PROC, "scene: scene.yaml", "scene: s.yaml")}


def _mcap(profile: str) -> bytes:
    """A well-formed MCAP file that is not a suture trace (another profile, no schema)."""
    import io

    from mcap.writer import Writer

    buf = io.BytesIO()
    w = Writer(buf)
    w.start(profile=profile, library="someone-else")
    sid = w.register_schema(name="Other", encoding="jsonschema", data=b"{}")
    cid = w.register_channel(topic="/other", message_encoding="json", schema_id=sid)
    w.add_message(cid, log_time=1, data=b"{}", publish_time=1)
    w.finish()
    return buf.getvalue()


class Case(NamedTuple):
    """One bad command line.

    Attributes:
        id: the test id.
        args: the arguments after ``suture`` (paths relative to the case folder).
        files: files written in the case folder before the run (name -> content).
        code: the expected exit code.
        needles: words the output must contain (whitespace-normalised).
        absent: paths (relative) that must not exist after the run.
        sub: also run as a real subprocess.
    """

    id: str
    args: tuple[str, ...]
    files: Mapping[str, str | bytes]
    code: int
    needles: tuple[str, ...]
    absent: tuple[str, ...] = ()
    sub: bool = False


def _proc(
    id_: str, old: str, new: str, needles: tuple[str, ...], at: str | None = None, code: int = 1
) -> Case:
    """``suture validate`` on the base procedure with one edit; the error is on the line of
    ``at`` (default: the edit's first line)."""
    text = _sub(PROC, old, new)
    line = _line(text, at or new.splitlines()[0])
    return Case(id_, ("validate", "p.yaml"), {"p.yaml": text}, code, (f"p.yaml:{line}:", *needles))


def _scene(
    id_: str,
    old: str,
    new: str,
    needles: tuple[str, ...],
    sub: bool = False,
    at: str | None = None,
) -> Case:
    """``suture validate`` of the base procedure on its scene with one edit; the error is on
    the line of ``at`` (default: the edit's first line)."""
    text = _sub(SCENE, old, new)
    line = _line(text, at or new.splitlines()[0])
    return Case(
        id_, ("validate", "p.yaml"), _scene_case(text), 1, (f"s.yaml:{line}:", *needles), sub=sub
    )


def _ops(id_: str, text: str | bytes, needles: tuple[str, ...], sub: bool = False) -> Case:
    """``suture run --operator o.yaml --out out``: the run must not start."""
    return Case(
        id_,
        ("run", "steps.yaml", "--operator", "o.yaml", "--out", "out"),
        {"o.yaml": text},
        1,
        ("o.yaml", *needles),
        ("out",),
        sub,
    )


def _set(cmd: str, value: str, code: int, needles: tuple[str, ...], sub: bool = False) -> Case:
    """``--set VALUE`` given to ``run`` or ``validate``."""
    args: tuple[str, ...] = (cmd, "steps.yaml", "--set", value)
    if cmd == "run":
        args = (*args, "--out", "out")
    return Case(f"set-{cmd}-{value}", args, {}, code, needles, ("out",), sub)


PARAMS_LINE = _line(PROC, "params:")
"""The base procedure's ``params:`` line, where an unknown ``--set`` name is reported."""

_BAD_MAGIC = b"\x89MCAP0\r\n" + b"\x00" * 64
_TRACES: dict[str, bytes] = {
    "empty": b"",
    "truncated-header": GOOD_TRACE[:5],
    "not-mcap-text": b"procedure: steps\nthis is not a trace\n",
    "png": b"\x89PNG\r\n\x1a\n" + b"\x00" * 200,
    "magic-then-garbage": _BAD_MAGIC,
    "corrupt-middle": (
        GOOD_TRACE[:200] + bytes(b ^ 0xFF for b in GOOD_TRACE[200:2200]) + GOOD_TRACE[2200:]
    ),
}


def _trace_cases() -> list[Case]:
    cases: list[Case] = []
    for kind, data in _TRACES.items():
        files: dict[str, str | bytes] = {"t.mcap": data}
        cases.append(Case(f"trace-{kind}", ("trace", "t.mcap"), files, 1, ("t.mcap",)))
        cases.append(
            Case(f"replay-{kind}", ("replay", "t.mcap"), files, 1, ("t.mcap",), sub=kind == "png")
        )
        cases.append(
            Case(
                f"plot-{kind}",
                ("plot", "t.mcap", "--out", "figs"),
                files,
                1,
                ("t.mcap",),
                ("figs",),
            )
        )
        cases.append(
            Case(
                f"report-{kind}",
                ("report", "t.mcap", "--out", "r.html"),
                files,
                1,
                ("t.mcap",),
                ("r.html",),
            )
        )
    foreign = {"f.mcap": _mcap("ros2")}
    cases += [
        Case(
            "trace-foreign-mcap",
            ("trace", "f.mcap"),
            foreign,
            1,
            ("f.mcap", "suture-engine"),
            sub=True,
        ),
        Case("replay-foreign-mcap", ("replay", "f.mcap"), foreign, 1, ("f.mcap",)),
        Case("diff-foreign-mcap", ("diff", "good.mcap", "f.mcap"), foreign, 1, ("f.mcap",)),
        Case(
            "plot-foreign-mcap",
            ("plot", "f.mcap", "--out", "figs"),
            foreign,
            1,
            ("f.mcap",),
            ("figs",),
        ),
        Case(
            "report-foreign-mcap",
            ("report", "f.mcap", "--out", "r.html"),
            foreign,
            1,
            ("f.mcap",),
            ("r.html",),
        ),
        Case(
            "diff-empty-actual",
            ("diff", "good.mcap", "t.mcap"),
            {"t.mcap": b""},
            1,
            ("t.mcap: TRUNCATED",),
        ),
        Case(
            "diff-png-expected",
            ("diff", "t.mcap", "good.mcap"),
            {"t.mcap": _TRACES["png"]},
            1,
            ("t.mcap",),
            sub=True,
        ),
        Case("trace-missing", ("trace", "nope.mcap"), {}, 2, ("nope.mcap",)),
        Case("replay-missing", ("replay", "nope.mcap"), {}, 2, ("nope.mcap",)),
        Case(
            "replay-set-unknown",
            ("replay", "good.mcap", "--procedure", "steps.yaml", "--set", "nope=1"),
            {},
            2,
            (f"steps.yaml:{PARAMS_LINE}:", "nope", "hold_time"),
        ),
        Case(
            "plot-missing", ("plot", "nope.mcap", "--out", "figs"), {}, 2, ("nope.mcap",), ("figs",)
        ),
        Case(
            "report-missing",
            ("report", "nope.mcap", "--out", "r.html"),
            {},
            2,
            ("nope.mcap",),
            ("r.html",),
        ),
        Case("trace-a-folder", ("trace", "."), {}, 2, ("Is a directory",)),
        Case(
            "replay-backend-corrupt-trace",
            ("run", "steps.yaml", "--backend", "replay", "--trace", "t.mcap", "--out", "out"),
            {"t.mcap": _TRACES["not-mcap-text"]},
            1,
            ("t.mcap",),
            ("out/summary.json",),
        ),
    ]
    return cases


CASES: list[Case] = [
    # --- procedures (kinds beyond tests/corpus) ---
    Case("proc-empty-file", ("validate", "p.yaml"), {"p.yaml": ""}, 1, ("p.yaml:1:",), sub=True),
    Case("proc-only-comment", ("validate", "p.yaml"), {"p.yaml": "# nothing\n"}, 1, ("p.yaml:",)),
    Case(
        "proc-not-utf8",
        ("validate", "p.yaml"),
        {"p.yaml": b"procedure: \xff\xfe\xfa\n"},
        1,
        ("p.yaml:1:",),
    ),
    Case(
        "proc-nul-bytes",
        ("validate", "p.yaml"),
        {"p.yaml": b"procedure: a\x00b\n"},
        1,
        ("p.yaml:1:",),
    ),
    _proc(
        "proc-tab-indent",
        "    skill: hold\n    with: {robot: stitcher, duration: 300 ms}",
        "    skill: hold\n\twith: {robot: stitcher, duration: 300 ms}",
        (),
        at="\twith",
    ),
    _proc(
        "proc-timeout-negative",
        '    "on": {done: tighten}',
        '    timeout: -2 s\n    "on": {done: tighten}',
        ("timeout",),
    ),
    _proc(
        "proc-timeout-not-a-time",
        '    "on": {done: tighten}',
        '    timeout: soon\n    "on": {done: tighten}',
        ("timeout",),
    ),
    _proc("proc-on-is-a-list", '    "on": {done: finished}', '    "on": [done, finished]', ("on",)),
    _proc("proc-retry-not-int", "{retry: 2, then: lock}", "{retry: two, then: lock}", ("retry",)),
    _proc(
        "proc-roles-a-list",
        "roles: {stitcher: endobot_1, grasper: endobot_2}",
        "roles: [endobot_1, endobot_2]",
        ("roles",),
    ),
    _proc(
        "proc-param-unknown-type",
        "hold_time: {type: quantity,",
        "hold_time: {type: complex,",
        ("hold_time",),
    ),
    _proc(
        "proc-param-min-above-max", "min: 10 ms, max: 5 s", "min: 10 s, max: 5 s", ("hold_time",)
    ),
    _proc("proc-duration-in-newtons", "duration: 300 ms", "duration: 300 N", ("duration",)),
    _proc("proc-duration-string", "duration: 100 ms", "duration: [1, 2]", ("duration",)),
    _proc(
        "proc-invariant-unknown-key",
        "invariant: {max_tension: 2 N}",
        "invariant: {max_tensoin: 2 N}",
        ("max_tensoin",),
    ),
    _proc(
        "proc-outcome-and-skill",
        "    outcome: succeeded",
        "    outcome: succeeded\n    skill: hold",
        ("finished",),
        at="  finished:",
    ),
    _proc("proc-huge-number", "duration: 300 ms", "duration: 1e400 ms", ("duration",)),
    _proc("proc-nan-duration", "duration: 300 ms", "duration: .nan ms", ("duration",)),
    Case("proc-is-a-folder", ("validate", "d"), {"d/x": ""}, 2, ("d",)),
    Case("proc-missing", ("validate", "nope.yaml"), {}, 2, ("nope.yaml",)),
    Case(
        "run-proc-missing",
        ("run", "nope.yaml", "--out", "out"),
        {},
        2,
        ("nope.yaml",),
        ("out",),
        sub=True,
    ),
    Case(
        "run-proc-invalid",
        ("run", "p.yaml", "--out", "out"),
        {"p.yaml": _sub(PROC, "initial: prepare", "initial: nowhere")},
        1,
        (f"p.yaml:{_line(PROC, 'initial: prepare')}:", "nowhere"),
        ("out",),
        sub=True,
    ),
    Case(
        "proc-deep-flow-nesting",
        ("validate", "p.yaml"),
        {"p.yaml": PROC + "extra: " + "[" * 200_000 + "]" * 200_000 + "\n"},
        1,
        (f"p.yaml:{PROC.count(chr(10)) + 1}:", "yaml-too-deep"),
        sub=True,
    ),
    Case(
        "proc-name-traversal",
        ("run", "p.yaml"),
        {"p.yaml": _sub(PROC, "procedure: steps", "procedure: ../../escaped")},
        1,
        ("p.yaml:2:", "procedure name", "at procedure"),
        ("runs", "../escaped-seed0-001"),
    ),
    # --- scenes ---
    _scene("scene-usp-unknown", "usp: 3-0", "usp: 12-0", ("usp", "12-0")),
    _scene("scene-usp-number", "usp: 3-0", "usp: 3.5", ("usp",)),
    _scene("scene-tissue-unknown", "type: skin", "type: liver", ("tissue.type", "liver"), sub=True),
    _scene(
        "scene-normal-not-unit",
        "type: skin",
        "type: skin\n  normal: [0, 0, 2]",
        ("tissue.normal", "unit"),
        at="normal:",
    ),
    _scene(
        "scene-normal-zero",
        "type: skin",
        "type: skin\n  normal: [0, 0, 0]",
        ("normal",),
        at="normal:",
    ),
    _scene(
        "scene-normal-two-numbers",
        "type: skin",
        "type: skin\n  normal: [0, 1]",
        ("normal",),
        at="normal:",
    ),
    _scene(
        "scene-wound-off-surface",
        "end: [0 mm, 10 mm, 0 mm]",
        "end: [0 mm, 10 mm, 5 mm]",
        ("tissue.wound", "off the tissue surface"),
    ),
    _scene(
        "scene-one-robot",
        "  endobot_2:\n    base: {position: [50 mm, 0 mm, 120 mm], "
        "rpy: [180 deg, 0 deg, 0 deg]}\n    tool: grasper\n",
        "",
        ("robots", "two EndoBots"),
        at="robots:",
    ),
    _scene("scene-length-in-newtons", "length: 300 mm", "length: 300 N", ("suture.length",)),
    _scene("scene-length-negative", "length: 300 mm", "length: -300 mm", ("suture.length",)),
    _scene(
        "scene-position-text", "position: [50 mm, 0 mm, 120 mm]", "position: here", ("position",)
    ),
    _scene("scene-tool-unknown", "tool: grasper", "tool: scalpel", ("tool", "scalpel")),
    _scene(
        "scene-unknown-key",
        "suture: {usp: 3-0, length: 300 mm}",
        "suture: {usp: 3-0, length: 300 mm, colour: blue}",
        ("colour",),
    ),
    _scene(
        "scene-timestep-negative",
        "suture: {usp: 3-0, length: 300 mm}",
        "suture: {usp: 3-0, length: 300 mm}\nphysics: {timestep: -1 ms}",
        ("timestep",),
        at="physics:",
    ),
    Case(
        "scene-robots-renamed",
        ("validate", "p.yaml"),
        _scene_case(_sub(SCENE, "  endobot_2:\n", "  endobot_7:\n")),
        1,
        (f"p.yaml:{_line(PROC, 'roles:')}:", "endobot_2", "roles.grasper"),
    ),
    Case(
        "scene-entry-off-tissue",
        ("validate", "p.yaml"),
        {
            **_scene_case(_sub(SCENE, "entry: [-4 mm, 0 mm, 0 mm]", "entry: [-4 mm, 0 mm, 9 mm]")),
            "p.yaml": _sub(
                _sub(PROC, "scene: scene.yaml", "scene: s.yaml"),
                "    outcome: succeeded",
                "    outcome: succeeded\n  bite:\n    skill: pass-needle\n"
                "    with: {robot: stitcher, entry: entry, exit: exit, pull_length: 20 mm}\n"
                "    on: {done: finished}",
            ),
        },
        1,
        ("off-tissue", "entry"),
    ),
    # --- operator files ---
    _ops("ops-bad-yaml", "events:\n  - {at: 1 s, do: lock\n", ("o.yaml:", "YAML"), sub=True),
    _ops("ops-not-a-mapping", "- lock\n- resume\n", ("events",)),
    _ops("ops-events-not-a-list", "events: {at: 1 s, do: lock}\n", ("o.yaml:1:", "events")),
    _ops("ops-bad-time", "events:\n  - {at: soon, do: lock}\n", ("o.yaml:2:", "at", "soon")),
    _ops("ops-negative-time", "events:\n  - {at: -1 s, do: lock}\n", ("o.yaml:2:", "at")),
    _ops("ops-time-in-newtons", "events:\n  - {at: 3 N, do: lock}\n", ("o.yaml:2:", "at")),
    _ops(
        "ops-unknown-action", "events:\n  - {at: 1 s, do: dance}\n", ("o.yaml:2:", "events[0].do")
    ),
    _ops(
        "ops-unknown-key",
        "events:\n  - {at: 1 s, do: lock, colour: red}\n",
        ("o.yaml:2:", "colour"),
    ),
    _ops(
        "ops-unknown-state",
        "events:\n  - {when: state = nowhere, do: lock}\n",
        ("o.yaml:2:", "nowhere"),
    ),
    _ops(
        "ops-bad-condition", "events:\n  - {when: tension > 3, do: lock}\n", ("o.yaml:2:", "when")
    ),
    _ops(
        "ops-both-triggers",
        "events:\n  - {at: 1 s, when: state = tighten, do: lock}\n",
        ("o.yaml:2:",),
    ),
    _ops(
        "ops-force-without-robot",
        "events:\n  - {at: 1 s, do: force, force: [0, 0, 1]}\n",
        ("o.yaml:2:", "robot"),
    ),
    _ops(
        "ops-unknown-robot",
        "events:\n  - {at: 1 s, do: lock, robot: endobot_7}\n",
        ("o.yaml:2:", "endobot_7"),
    ),
    _ops(
        "ops-python-tag",
        "events: !!python/object/apply:os.system ['touch pwned']\n",
        ("o.yaml:1:",),
    ),
    _ops("ops-deep-nesting", "events: " + "[" * 3000 + "]" * 3000 + "\n", ("o.yaml:1:",)),
    Case(
        "ops-missing",
        ("run", "steps.yaml", "--operator", "nope.yaml", "--out", "out"),
        {},
        2,
        ("nope.yaml",),
        ("out",),
    ),
    # --- CLI arguments and --set ---
    _set("run", "hold_time", 2, ("hold_time", "name=value"), sub=True),
    _set("run", "=1 s", 2, ("name=value",)),
    _set("run", "nope=1 s", 2, ("nope", "hold_time")),
    _set("run", "hold_time=3 N", 1, ("hold_time",)),
    _set("run", "hold_time=10 s", 1, ("hold_time",)),
    _set("run", "hold_time=abc", 1, ("hold_time",)),
    _set("run", "hold_time=!!python/object/apply:os.system [x]", 1, ("hold_time",)),
    _set("run", "hold_time=[1 s", 1, ("hold_time",)),
    _set("validate", "hold_time=1 kg", 1, ("hold_time",), sub=True),
    _set("validate", "hold_time", 2, ("hold_time", "name=value")),
    _set("validate", "nope=3", 2, (f"steps.yaml:{PARAMS_LINE}:", "nope", "override", "hold_time")),
    _set("run", "nope=3", 2, (f"steps.yaml:{PARAMS_LINE}:", "nope", "hold_time")),
    Case(
        "set-run-error-elsewhere-keeps-its-line",
        ("run", "p.yaml", "--set", "hold_time=1 s", "--out", "out"),
        {"p.yaml": _sub(PROC, "duration: 300 ms", "duration: 300 kg")},
        1,
        (f"p.yaml:{_line(PROC, 'duration: 300 ms')}:", "tighten.with.duration"),
        ("out",),
    ),
    Case(
        "run-unknown-backend",
        ("run", "steps.yaml", "--backend", "gazebo", "--out", "out"),
        {},
        2,
        ("gazebo",),
        ("out",),
    ),
    Case(
        "run-replay-without-trace",
        ("run", "steps.yaml", "--backend", "replay", "--out", "out"),
        {},
        2,
        ("--trace",),
        ("out",),
    ),
    Case("run-seed-not-int", ("run", "steps.yaml", "--seed", "abc"), {}, 2, ("--seed",)),
    Case(
        "run-max-time-negative",
        ("run", "steps.yaml", "--max-time", "-1", "--out", "out"),
        {},
        2,
        ("--max-time",),
        ("out/summary.json",),
    ),
    Case("run-unknown-option", ("run", "steps.yaml", "--sed", "1"), {}, 2, ("--sed",)),
    Case(
        "validate-bad-format",
        ("validate", "steps.yaml", "--format", "xml"),
        {},
        2,
        ("--format", "xml"),
    ),
    Case("graph-bad-format", ("graph", "steps.yaml", "--format", "png"), {}, 2, ("png",)),
    Case("graph-bad-engine", ("graph", "steps.yaml", "--engine", "dotty"), {}, 2, ("--engine",)),
    Case("identify-bad-robot", ("identify", "--robot", "E3"), {}, 2, ("E3",)),
    Case("identify-bad-joint", ("identify", "--joint", "9"), {}, 2, ("9",)),
    Case("knot-garbage", ("knot", "k.txt"), {"k.txt": "one two three\n"}, 1, ("k.txt",)),
    Case("knot-missing", ("knot", "nope.npy"), {}, 2, ("nope.npy",)),
    # --- --out ---
    Case(
        "run-out-is-a-file",
        ("run", "steps.yaml", "--out", "f"),
        {"f": "not a folder\n"},
        2,
        ("f",),
        ("f/summary.json",),
        sub=True,
    ),
    Case(
        "run-out-not-writable",
        ("run", "steps.yaml", "--out", "/proc/suture-out"),
        {},
        2,
        ("/proc/suture-out",),
    ),
    Case("plot-out-is-a-file", ("plot", "good.mcap", "--out", "f"), {"f": "x"}, 2, ("f",)),
    Case("report-out-is-a-folder", ("report", "good.mcap", "--out", "d"), {"d/x": "x"}, 2, ("d",)),
    Case(
        "report-out-not-writable",
        ("report", "good.mcap", "--out", "/proc/r.html"),
        {},
        2,
        ("/proc/r.html",),
    ),
    # --- --vary (suture sweep) ---
    *[
        Case(
            f"sweep-vary-{spec}",
            ("sweep", "steps.yaml", "--runs", "2", "--out", "sw", "--vary", spec),
            {},
            code,
            (f"--vary '{spec}'", *needles),
            ("sw/summary.json",),
            sub=spec == "hold_time",
        )
        for spec, code, needles in [
            ("hold_time", 1, ("column 10", "'='")),
            ("hold_time=gauss(1,2)", 1, ("column 11",)),
            ("hold_time=normal(1 s)", 1, ("column 21", "two numbers")),
            ("hold_time=uniform(2 s,1 s)", 1, ("column 23", "b >= a")),
            ("nope=uniform(1 s,2 s)", 2, ("nope",)),
            ("hold_time=choice()", 1, ("column 18",)),
            ("hold_time=normal(1 s,-2 s)", 1, ("column 22", "sigma")),
        ]
    ],
    Case(
        "sweep-runs-zero",
        ("sweep", "steps.yaml", "--runs", "0", "--out", "sw"),
        {},
        2,
        ("--runs",),
        ("sw/summary.json",),
    ),
    Case(
        "sweep-workers-zero",
        ("sweep", "steps.yaml", "--runs", "1", "--out", "sw", "--workers", "0"),
        {},
        2,
        ("--workers",),
        ("sw/summary.json",),
    ),
    Case(
        "sweep-max-time-negative",
        ("sweep", "steps.yaml", "--runs", "1", "--out", "sw", "--max-time", "-1"),
        {},
        2,
        ("--max-time",),
        ("sw/summary.json",),
    ),
    *_trace_cases(),
]

# Known defects in files this suite does not own: case id -> what is wrong and where.
XFAIL: dict[str, str] = {}


def _case_dir(tmp: Path, case: Case) -> Path:
    shutil.copy(DATA / "steps.yaml", tmp / "steps.yaml")
    shutil.copy(DATA / "scene.yaml", tmp / "scene.yaml")
    (tmp / "ops-good.yaml").write_text(OPS, encoding="utf-8")
    (tmp / "good.mcap").write_bytes(GOOD_TRACE)
    for name, content in case.files.items():
        path = tmp / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
    return tmp


def _flat(text: str) -> str:
    return " ".join(text.split())


def _check(case: Case, tmp: Path, code: int, output: str) -> None:
    flat = _flat(output)
    assert "Traceback" not in output, output
    assert code == case.code, f"exit {code}, expected {case.code}:\n{output}"
    for needle in case.needles:
        assert needle in flat, f"{needle!r} not in:\n{output}"
    for rel in case.absent:
        assert not (tmp / rel).exists(), f"{rel} left behind:\n{output}"
    assert not (tmp / "pwned").exists()


def _params(sub: bool) -> list[object]:
    out: list[object] = []
    for case in CASES:
        if sub and not case.sub:
            continue
        marks = []
        if case.id in XFAIL:
            marks.append(pytest.mark.xfail(strict=True, reason=XFAIL[case.id]))
        out.append(pytest.param(case, id=case.id, marks=marks))
    return out


def test_corpus_is_large() -> None:
    assert len(CASES) >= 60
    assert len({c.id for c in CASES}) == len(CASES)
    assert sum(c.sub for c in CASES) >= 10
    kinds = {c.id.split("-")[0] for c in CASES}
    assert {
        "proc",
        "scene",
        "ops",
        "set",
        "run",
        "sweep",
        "trace",
        "replay",
        "diff",
        "plot",
        "report",
    } <= kinds


@pytest.mark.parametrize("case", _params(sub=False))
def test_in_process(case: Case, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _case_dir(tmp_path, case)
    monkeypatch.chdir(tmp_path)
    for key in ("COLUMNS", "NO_COLOR", "TERM"):
        monkeypatch.setenv(key, ENV[key])
    result = CliRunner().invoke(app, list(case.args), catch_exceptions=True)
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        pytest.fail(f"uncaught {type(result.exception).__name__}: {result.exception}")
    _check(case, tmp_path, result.exit_code, result.output)


@pytest.mark.parametrize("case", _params(sub=True))
def test_subprocess(case: Case, tmp_path: Path) -> None:
    _case_dir(tmp_path, case)
    proc = subprocess.run(
        [sys.executable, "-m", "suture_engine.cli", *case.args],
        cwd=tmp_path,
        env=ENV,
        capture_output=True,
        text=True,
        timeout=300,
    )
    _check(case, tmp_path, proc.returncode, proc.stdout + proc.stderr)
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize(
    "value", ["hold_time=3 N", "hold_time=10 s", "hold_time=[1 s", "hold_time=abc", "nope=3"]
)
def test_run_and_validate_agree_on_set(
    value: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """One ``--set`` convention: the same exit code and the same location in both commands."""
    import re

    _case_dir(tmp_path, Case("agree", (), {}, 0, ()))
    monkeypatch.chdir(tmp_path)
    for key in ("COLUMNS", "NO_COLOR", "TERM"):
        monkeypatch.setenv(key, ENV[key])
    runner = CliRunner()
    run = runner.invoke(app, ["run", "steps.yaml", "--set", value, "--out", "out"])
    val = runner.invoke(app, ["validate", "steps.yaml", "--set", value])
    assert run.exit_code == val.exit_code, run.output + val.output
    assert run.exit_code == (2 if value.startswith("nope") else 1)
    where = re.compile(r"steps\.yaml:\d+:\d+:")
    assert where.findall(run.output) == where.findall(val.output) != [], run.output + val.output
    assert not (tmp_path / "out").exists()
