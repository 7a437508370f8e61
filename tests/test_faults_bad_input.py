"""Bad fault input (``tests/bad_input/faults/cases.yaml``): a located, human error, the
right exit code, no traceback, no run started (no output folder left behind)."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from suture_engine.cli import app

DATA = Path(__file__).resolve().parent / "bad_input"
CASES: list[dict[str, Any]] = yaml.safe_load((DATA / "faults" / "cases.yaml").read_text())["cases"]


def test_corpus_shape() -> None:
    assert len(CASES) >= 25
    assert len({c["id"] for c in CASES}) == len(CASES)
    assert {c["code"] for c in CASES} == {1, 2}
    assert sum("scene_faults" in c for c in CASES) >= 5


@pytest.mark.parametrize("case", CASES, ids=[c["id"] for c in CASES])
def test_case(case: dict[str, Any], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    shutil.copy(DATA / "steps.yaml", tmp_path / "steps.yaml")
    scene = (DATA / "scene.yaml").read_text(encoding="utf-8")
    (tmp_path / "scene.yaml").write_text(scene + case.get("scene_faults", ""), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("COLUMNS", "400")
    monkeypatch.setenv("NO_COLOR", "1")
    args = ["run", "steps.yaml", "--backend", case.get("backend", "ideal"), "--out", "out"]
    if "fault" in case:
        args += ["--fault", case["fault"]]
    result = CliRunner().invoke(app, args, catch_exceptions=True)
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        pytest.fail(f"uncaught {type(result.exception).__name__}: {result.exception}")
    text = " ".join(result.output.split())
    assert result.exit_code == case["code"], result.output
    assert "Traceback" not in result.output
    for needle in case["needles"]:
        assert needle in text, (needle, result.output)
    if "line" in case:
        assert f"scene.yaml:{case['line']}:" in text, result.output
    if "fault" in case:
        assert f"--fault {case['fault']!r}" in text or "no step" in text, result.output
    assert not (tmp_path / "out").exists()
