"""The ``suture knot`` command: file formats, output and exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from suture_engine.cli import app
from suture_engine.suture import curves

runner = CliRunner()


def test_npy_json_and_text_files(tmp_path: Path) -> None:
    pts = 0.001 * curves.granny_knot(right=False)
    np.save(tmp_path / "c.npy", pts)
    (tmp_path / "c.json").write_text(json.dumps({"points": pts.tolist()}))
    np.savetxt(tmp_path / "c.csv", pts, delimiter=",", header="x,y,z")
    for name in ("c.npy", "c.json", "c.csv"):
        result = runner.invoke(app, ["knot", str(tmp_path / name), "--json"])
        assert result.exit_code == 0, result.output
        data = json.loads(result.stdout)
        assert (data["type"], data["chirality"], data["v3"]) == ("granny", "left", -2)


def test_text_output_with_geometry(tmp_path: Path) -> None:
    np.save(tmp_path / "t.npy", curves.trefoil())
    result = runner.invoke(
        app,
        [
            "knot",
            str(tmp_path / "t.npy"),
            "--tissue-point",
            "0",
            "0",
            "-5",
            "--tissue-normal",
            "0",
            "0",
            "1",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "knot: trefoil (right)" in result.stdout
    assert "t^2 - t + 1" in result.stdout
    assert "seated: False" in result.stdout


def test_errors_have_exit_codes_and_no_traceback(tmp_path: Path) -> None:
    missing = runner.invoke(app, ["knot", str(tmp_path / "none.npy")])
    assert missing.exit_code == 2
    (tmp_path / "bad.txt").write_text("1 2\n3 4\n")
    bad = runner.invoke(app, ["knot", str(tmp_path / "bad.txt")])
    assert bad.exit_code == 1
    (tmp_path / "junk.json").write_text("{not json")
    junk = runner.invoke(app, ["knot", str(tmp_path / "junk.json")])
    assert junk.exit_code == 1
    for result in (missing, bad, junk):
        assert "Traceback" not in result.output
