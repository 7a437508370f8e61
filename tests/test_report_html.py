"""suture report: one self-contained HTML page per run, checked in headless Chromium."""

from __future__ import annotations

import base64
import io
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from report_traces import write_known_trace

from suture_engine.report.cli_report import report_command
from suture_engine.report.figures import FIGURE_NAMES, load_trace
from suture_engine.report.html import build_report, knot_info
from suture_engine.trace import channels
from suture_engine.trace.writer import TraceMeta, TraceWriter

PROCEDURE = Path(__file__).parent / "procedures" / "steps.yaml"
CHROMIUM = shutil.which("chromium") or (
    "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None
)


@pytest.fixture(scope="module")
def page_and_trace(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("run")
    trace = write_known_trace(
        folder / "trace.mcap", extra_meta={"procedure_file": str(PROCEDURE.resolve())}
    )
    out = folder / "report.html"
    assert report_command(trace, out=out, stdout=io.StringIO(), err=io.StringIO()) == 0
    return out, trace


def test_page_embeds_every_figure_as_png(page_and_trace: tuple[Path, Path]) -> None:
    html = page_and_trace[0].read_text(encoding="utf-8")
    images = re.findall(r"src='data:image/png;base64,([A-Za-z0-9+/=]+)'", html)
    assert len(images) == len(FIGURE_NAMES)
    for b64 in images:
        assert base64.b64decode(b64).startswith(b"\x89PNG")
    for name in FIGURE_NAMES:
        assert f"id='fig-{name}'" in html


def test_page_is_self_contained(page_and_trace: tuple[Path, Path]) -> None:
    html = page_and_trace[0].read_text(encoding="utf-8")
    assert not re.search(r"""(src|href)\s*=\s*['"]?(https?:|//)""", html)
    assert "<script" not in html


def test_page_holds_summary_knot_and_graph(page_and_trace: tuple[Path, Path]) -> None:
    html = page_and_trace[0].read_text(encoding="utf-8")
    assert "<th>outcome</th><td>succeeded</td>" in html
    assert "<th>retries</th><td>1</td>" in html
    assert "from /ground_truth/knot" in html
    assert "<th>type</th><td>square</td>" in html
    graph = re.search(r"<pre class='mermaid'>(.*?)</pre>", html, re.S)
    assert graph is not None
    assert graph.group(1).startswith("stateDiagram-v2")
    for state in ("prepare", "tighten", "release", "finished"):  # the states of steps.yaml
        assert state in graph.group(1)


def test_no_procedure_file_and_no_knot_are_said(tmp_path: Path) -> None:
    trace = write_known_trace(tmp_path / "trace.mcap", knot=False)
    html = build_report(load_trace(trace), figures=[])
    assert "no data on /ground_truth/knot" in html
    assert "no graph" in html


def test_knot_is_classified_from_the_last_centerline(tmp_path: Path) -> None:
    path = tmp_path / "trace.mcap"
    s = np.linspace(0.0, 2 * np.pi, 200)
    # A trefoil, opened by dropping its last points (an open suture tied in a trefoil).
    x, y, z = np.sin(s) + 2 * np.sin(2 * s), np.cos(s) - 2 * np.cos(2 * s), -np.sin(3 * s)
    meta = TraceMeta(procedure="k", seed=0, control_rate_hz=100.0)
    with TraceWriter(path, meta, fsync=False) as w:
        w.write(
            channels.GROUND_TRUTH_SUTURE,
            0,
            {
                "x": (x[:-8] / 100).tolist(),
                "y": (y[:-8] / 100).tolist(),
                "z": (z[:-8] / 100).tolist(),
            },
        )
    info = knot_info(load_trace(path))
    assert info.source.startswith("classified from")
    assert info.fields["type"] == "trefoil"


def test_truncated_trace_is_flagged(page_and_trace: tuple[Path, Path], tmp_path: Path) -> None:
    data = page_and_trace[1].read_bytes()
    cut = tmp_path / "trace.mcap"
    cut.write_bytes(data[: int(len(data) * 0.7)])
    html = build_report(load_trace(cut), figures=[])
    assert "The trace ends early" in html


def test_bad_trace_leaves_no_report(tmp_path: Path) -> None:
    trace = tmp_path / "trace.mcap"
    trace.write_bytes(b"garbage")
    out = tmp_path / "report.html"
    err = io.StringIO()
    assert report_command(trace, out=out, stdout=io.StringIO(), err=err) == 1
    assert "trace-foreign" in err.getvalue()
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [trace]  # no temporary file either


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (CI installs it)")
def test_chromium_screenshot_shows_the_figures(
    page_and_trace: tuple[Path, Path], tmp_path: Path
) -> None:
    from matplotlib.image import imread

    shot = tmp_path / "shot.png"
    cmd = [
        str(CHROMIUM),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp_path / 'profile'}",
        "--hide-scrollbars",
        "--window-size=1000,2400",
        f"--screenshot={shot}",
        page_and_trace[0].as_uri(),
    ]
    subprocess.run(cmd, check=True, capture_output=True, timeout=120)
    px = imread(str(shot))[..., :3]
    background = np.all(px > 0.98, axis=-1)
    assert (~background).mean() > 0.02, "the screenshot is blank"
    # The first figure (force tracking) starts below the summary tables; its plotted
    # lines are saturated colours, which the page's text and tables do not use.
    saturated = (px.max(axis=-1) - px.min(axis=-1)) > 0.35
    rows = np.nonzero(saturated.any(axis=1))[0]
    assert rows.size > 50, "no coloured figure pixels in the screenshot"


def test_one_knot_entry_per_stitch_is_shown(tmp_path: Path) -> None:
    import json

    trace = write_known_trace(tmp_path / "trace.mcap", knot=False)
    knots = [{"type": "square", "determinant": 9}, {"type": "granny", "determinant": 9}]
    (tmp_path / "summary.json").write_text(json.dumps({"knot": knots}), encoding="utf-8")
    info = knot_info(load_trace(trace), classify=False)
    assert info.source.startswith("summary.json")
    assert info.fields["stitch 1 type"] == "square"
    assert info.fields["stitch 2 type"] == "granny"
    html = build_report(load_trace(trace), figures=[])
    assert "stitch 2 type" in html and "granny" in html
