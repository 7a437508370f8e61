"""``suture validate``, ``suture schema`` and ``suture graph`` through the real command."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import jsonschema
import pytest

from suture_engine.language.source import load_yaml_file, load_yaml_text

ROOT = Path(__file__).resolve().parent.parent
BUNDLED = sorted((ROOT / "procedures").glob("*.yaml"))


def _suture(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "suture_engine.cli", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )


def test_bundled_procedures_validate() -> None:
    result = _suture("validate", *[str(p.relative_to(ROOT)) for p in BUNDLED])
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.count(": valid") == len(BUNDLED)


def test_a_state_turned_off_by_when_is_not_checked_against_the_scenes_tools(
    tmp_path: Path,
) -> None:
    """The interrupted suture by algorithm 3 (its default) runs on the bent-tip bench,
    where the secure-knot states (algorithm 2's hook and stitcher) are turned off: valid.
    A state turned on by its ``when:`` is checked, and its tools do not match the scene;
    the interrupted suture's own ``secure`` refuses that earlier (``requires``), so this
    uses a file of its own."""
    off = _suture("validate", "procedures/interrupted-suture.yaml")
    assert off.returncode == 0, off.stdout + off.stderr
    procedures = ROOT / "procedures"
    path = tmp_path / "secure-on-bent-tip.yaml"
    path.write_text(
        "procedure: secure-on-bent-tip\n"
        f"scene: {procedures / 'scenes' / 'bench-bent-tip-posts.yaml'}\n"
        "backend: pybullet-surgical-stitched\n"
        "params: {secure: {type: bool, default: false}}\n"
        "roles: {stitcher: endobot_1, grasper: endobot_2}\n"
        "initial: knot\n"
        "states:\n"
        f"  knot: {{when: '${{secure}}', use: {procedures / 'secure-knot.yaml'},\n"
        "         with: {entry: entry_2, exit: exit_2, site: knot_2}, on: {done: closed}}\n"
        "  closed: {outcome: succeeded}\n"
    )
    for secure, valid in (("false", True), ("true", False)):
        result = _suture(
            "validate", "--allow-outside", "--set", f"secure={secure}", str(path)
        )  # fmt: skip
        assert (result.returncode == 0) is valid, result.stdout + result.stderr
        assert ("tool-mismatch" in result.stdout) is not valid, result.stdout


def test_json_output_of_a_valid_file_is_an_empty_list() -> None:
    result = _suture("validate", "--format", "json", "procedures/stitch.yaml")
    assert result.returncode == 0 and json.loads(result.stdout) == []


@pytest.mark.parametrize(
    "args",
    [
        ("validate", "no/such/file.yaml"),
        ("validate", "--format", "xml", "procedures/stitch.yaml"),
        ("validate", "--set", "oops", "procedures/stitch.yaml"),
        ("validate",),
        ("graph", "procedures/stitch.yaml", "--format", "png"),
        ("graph", "no/such/file.yaml"),
    ],
)
def test_usage_and_io_errors_exit_2_without_traceback(args: tuple[str, ...]) -> None:
    result = _suture(*args)
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stdout + result.stderr


def test_set_overrides_parameters() -> None:
    ok = _suture("validate", "--set", "algorithm=1", "procedures/square-knot.yaml")
    assert ok.returncode == 0, ok.stdout
    bad = _suture("validate", "--set", "algorithm=7", "procedures/square-knot.yaml")
    assert bad.returncode == 1 and "out-of-bounds" in bad.stdout


def test_schema_is_json_schema_and_accepts_the_bundled_procedures() -> None:
    result = _suture("schema")
    assert result.returncode == 0
    schema = json.loads(result.stdout)
    jsonschema.Draft202012Validator.check_schema(schema)
    validator = jsonschema.Draft202012Validator(schema)
    for path in BUNDLED:
        errors = list(validator.iter_errors(load_yaml_file(path).data))
        assert errors == [], f"{path.name}: {errors[0].message}"


def test_schema_rejects_misspelt_keys_and_skill_parameters() -> None:
    schema = json.loads(_suture("schema").stdout)
    validator = jsonschema.Draft202012Validator(schema)
    base = (ROOT / "procedures" / "stitch.yaml").read_text()
    for broken in (
        base.replace("initial:", "intial:"),
        base.replace("pull_length:", "pul_length:"),
    ):
        data = load_yaml_text(broken, "x.yaml").data
        assert list(validator.iter_errors(data)), "the schema accepted a misspelt key"


def test_graph_mermaid_labels_states_with_skill_and_invariant() -> None:
    result = _suture("graph", "procedures/stitch.yaml", "--format", "mermaid")
    assert result.returncode == 0
    text = result.stdout
    assert text.startswith("stateDiagram")
    assert "[*] --> s0" in text
    assert "skill pass-needle" in text and "invariant tension <= 3 N" in text
    # bite, then the strand laid out (a guarded move: done or not, on to lowering)
    assert "s1 --> s2: done" in text and "s2 --> s3: done" in text and "s2 --> s3: failed" in text
    assert "s4 --> [*]" in text
    assert "Lock" in text


def test_graph_square_knot_shows_the_two_simple_knots() -> None:
    text = _suture("graph", "procedures/square-knot.yaml", "--format", "mermaid").stdout
    assert text.count("use knot-algorithm-2") == 2
    assert "mirror=True" in text and "mirror=False" in text


def test_graph_dot() -> None:
    result = _suture("graph", "procedures/secure-knot.yaml", "--format", "dot")
    assert result.returncode == 0
    assert result.stdout.startswith('digraph "secure-knot"')
    assert "skill tension-regulate" in result.stdout and "->" in result.stdout


def test_graph_of_an_invalid_procedure_exits_1() -> None:
    result = _suture("graph", "tests/corpus/misspelt-state-key.yaml")
    assert result.returncode == 1 and "unknown-key" in result.stderr


def test_validate_imports_no_heavy_module() -> None:
    code = (
        "import sys, io, glob\n"
        "from pathlib import Path\n"
        "from suture_engine.validation.report import validate_command\n"
        "rc = validate_command([Path(p) for p in sorted(glob.glob('procedures/*.yaml'))],"
        " out=io.StringIO())\n"
        "heavy = ('pint', 'numpy', 'scipy', 'pybullet', 'matplotlib', 'osqp', 'mcap', 'rich',"
        " 'numba')\n"
        "print(rc, [m for m in heavy if m in sys.modules])\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=False
    )
    assert result.stdout.strip() == "0 []", result.stdout + result.stderr


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.stem)
def test_every_bundled_procedure_draws(path: Path) -> None:
    from suture_engine.language.loader import load_procedure
    from suture_engine.validation.graph import to_dot, to_mermaid

    proc = load_procedure(path)
    mermaid, dot = to_mermaid(proc), to_dot(proc)
    assert mermaid.startswith("stateDiagram-v2\n") and dot.startswith("digraph ")
    for i, state in enumerate(proc.states.values()):
        assert f" as s{i}" in mermaid and f"  s{i} [label=" in dot
        if state.skill is not None:
            assert f"skill {state.skill}" in mermaid
    assert dot.count("{") == dot.count("}")


def test_graph_through_transitions_graph_machine() -> None:
    result = _suture("graph", "procedures/stitch.yaml", "--engine", "transitions")
    assert result.returncode == 0, result.stderr
    text = result.stdout
    assert "stateDiagram-v2" in text
    assert 'state "bite<br/>skill pass-needle<br/>invariant tension <= 3 N' in text
    assert "s1 --> s2: done" in text and "[*] --> s0" in text
