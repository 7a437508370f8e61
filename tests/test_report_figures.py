"""suture plot: figures from the channel catalogue, no-data panels, bad traces."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from report_traces import ROBOTS, write_known_trace

from suture_engine.report.cli_report import plot_command
from suture_engine.report.figures import FIGURE_NAMES, load_trace, render_figures
from suture_engine.trace import channels
from suture_engine.trace.writer import TraceMeta, TraceWriter

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _pixels(png: bytes) -> np.ndarray:
    from matplotlib.image import imread

    return (imread(io.BytesIO(png), format="png")[..., :3] * 255).round().astype(int)


def _count_colour(png: bytes, rgb: tuple[int, int, int], tol: int = 6) -> int:
    px = _pixels(png)
    return int(np.all(np.abs(px - np.array(rgb)) <= tol, axis=-1).sum())


def _count_red(png: bytes) -> int:
    px = _pixels(png)
    return int(((px[..., 0] > 200) & (px[..., 1] < 80) & (px[..., 2] < 80)).sum())


@pytest.fixture(scope="module")
def known(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_known_trace(tmp_path_factory.mktemp("known") / "trace.mcap")


def test_every_figure_from_a_full_trace(known: Path) -> None:
    figures = render_figures(load_trace(known))  # the same figures plot_command writes
    assert [f.name for f in figures] == list(FIGURE_NAMES)
    for fig in figures:
        assert fig.png.startswith(PNG_MAGIC)
        assert _pixels(fig.png).shape[0] > 200
    by_name = {f.name: f for f in figures}
    # Only the second robot's QP and the thread (no thread here) are empty in this trace.
    assert by_name["qp"].missing == (channels.qp_topic(ROBOTS[1]),)
    assert by_name["thread_states"].missing == (channels.GROUND_TRUTH_SUTURE,)
    for name in ("force_tracking", "joint_positions", "task_path", "tension", "timeline"):
        assert by_name[name].missing == (), name


def test_tension_limit_line_is_drawn_only_with_a_limit(tmp_path: Path) -> None:
    with_limit = write_known_trace(tmp_path / "a" / "trace.mcap", tension_limit=2.0)
    without = write_known_trace(tmp_path / "b" / "trace.mcap", tension_limit=None)
    (fig_a,) = render_figures(load_trace(with_limit), ["tension"])
    (fig_b,) = render_figures(load_trace(without), ["tension"])
    assert _count_red(fig_a.png) > 300  # the dashed red limit line across the axes
    assert _count_red(fig_b.png) == 0


def _tension_trace(path: Path, per_robot: bool) -> Path:
    meta = TraceMeta(procedure="t", seed=0, control_rate_hz=1000.0, robots=("left", "right"))
    with TraceWriter(path, meta, fsync=False) as w:
        for k in range(200):
            left, right = 1.0 + 0.5 * np.sin(k / 20), 0.5 + 0.002 * k
            msg: dict[str, object] = {"tension_N": max(left, right), "robot": "left"}
            if per_robot:
                msg["estimates"] = [
                    {"robot": "left", "tension_N": left},
                    {"robot": "right", "tension_N": right},
                ]
            w.write(channels.TENSION_ESTIMATED, k * 1_000_000, msg)
    return path


def test_each_robots_estimate_is_drawn_when_the_trace_has_them(tmp_path: Path) -> None:
    green, purple, blue = (0x2C, 0xA0, 0x2C), (0x94, 0x67, 0xBD), (0x1F, 0x77, 0xB4)
    (each,) = render_figures(load_trace(_tension_trace(tmp_path / "a.mcap", True)), ["tension"])
    (top,) = render_figures(load_trace(_tension_trace(tmp_path / "b.mcap", False)), ["tension"])
    assert _count_colour(each.png, green) > 200 and _count_colour(each.png, purple) > 200
    assert _count_colour(each.png, blue) == 0  # the larger-of series is not drawn twice
    assert _count_colour(top.png, green) == 0 and _count_colour(top.png, purple) == 0
    assert _count_colour(top.png, blue) > 200
    assert each.missing == top.missing == ("/ground_truth/tension",)


def test_timeline_shows_the_notbe_episode(tmp_path: Path) -> None:
    notbe_red = (0xD6, 0x27, 0x28)
    (fig,) = render_figures(load_trace(write_known_trace(tmp_path / "trace.mcap")), ["timeline"])
    assert _count_colour(fig.png, notbe_red) > 50


def test_empty_channels_give_no_data_panels(tmp_path: Path) -> None:
    path = tmp_path / "trace.mcap"
    meta = TraceMeta(procedure="bare", seed=0, control_rate_hz=1000.0, robots=("left",))
    with TraceWriter(path, meta, fsync=False) as w:
        w.write(channels.TRANSITIONS, 0, {"source": "idle", "dest": "autonomous/a"})
    figures = {f.name: f for f in render_figures(load_trace(path))}
    assert figures["force_tracking"].missing == ("/base_wrench/left",)
    assert figures["joint_positions"].missing == ("/joint_state/left",)
    assert figures["task_path"].missing == ("/joint_state/left",)
    assert set(figures["tension"].missing) == {"/tension/estimated", "/ground_truth/tension"}
    assert figures["qp"].missing == ("/qp/left",)
    assert set(figures["timeline"].missing) == {"/events", "/operator"}
    for fig in figures.values():
        assert fig.png.startswith(PNG_MAGIC)


def test_plot_command_on_a_truncated_trace_writes_every_png(known: Path, tmp_path: Path) -> None:
    data = known.read_bytes()
    cut = tmp_path / "trace.mcap"
    cut.write_bytes(data[: int(len(data) * 0.7)])
    loaded = load_trace(cut)
    assert loaded.status.truncated
    assert 0.0 < loaded.duration_s < 2.0
    out = tmp_path / "figs"
    stdout = io.StringIO()
    assert plot_command(cut, out=out, stdout=stdout, err=io.StringIO()) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(f"{n}.png" for n in FIGURE_NAMES)
    assert "ends early" in stdout.getvalue()
    assert "no data on /qp/endobot_2" in stdout.getvalue()


@pytest.mark.parametrize(
    ("content", "code", "needle"),
    [
        (b"not a trace at all", 1, "trace-foreign"),
        (b"\x89MCAP0\r\n" + b"\xff" * 64, 1, "no readable message"),
        (None, 2, "no such file"),
    ],
)
def test_bad_traces_exit_with_a_located_error_and_write_nothing(
    tmp_path: Path, content: bytes | None, code: int, needle: str
) -> None:
    trace = tmp_path / "trace.mcap"
    if content is not None:
        trace.write_bytes(content)
    out = tmp_path / "out"
    err = io.StringIO()
    assert plot_command(trace, out=out, stdout=io.StringIO(), err=err) == code
    assert needle in err.getvalue()
    assert str(trace) in err.getvalue()
    assert "Traceback" not in err.getvalue()
    assert not out.exists()


def test_cli_plot_runs_as_a_command(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from suture_engine.cli import app

    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"nope")
    result = CliRunner().invoke(app, ["plot", str(bad), "--out", str(tmp_path / "p")])
    assert result.exit_code == 1
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert not (tmp_path / "p").exists()


def test_thread_states_keep_the_thread_as_each_state_left_it(tmp_path: Path) -> None:
    path = tmp_path / "trace.mcap"
    meta = TraceMeta(procedure="thread", seed=0, control_rate_hz=1000.0, robots=("left",))

    def line(height_m: float) -> dict[str, list[float]]:
        return {"x": [0.0, 0.01, 0.02], "y": [0.0, 0.0, 0.0], "z": [0.0, height_m, 0.0]}

    with TraceWriter(path, meta, fsync=False) as w:
        w.write(channels.TRANSITIONS, 0, {"source": "idle", "dest": "autonomous/a"})
        w.write(channels.GROUND_TRUTH_SUTURE, 100_000_000, line(0.001))
        w.write(channels.GROUND_TRUTH_SUTURE, 200_000_000, line(0.002))
        # a leaves at 0.25 s with the 0.2 s centerline; b takes no time (the same one)
        w.write(
            channels.TRANSITIONS, 250_000_000, {"source": "autonomous/a", "dest": "autonomous/b"}
        )
        w.write(
            channels.TRANSITIONS, 250_000_000, {"source": "autonomous/b", "dest": "autonomous/c"}
        )
        w.write(channels.GROUND_TRUTH_SUTURE, 300_000_000, line(0.005))
    data = load_trace(path)
    assert [(t, state) for t, state, _ in data.thread_exits] == [
        (0.2, "autonomous/a"),
        (0.2, "autonomous/b"),
        (0.3, "autonomous/c"),  # the trace's last centerline, under its final state
    ]
    assert [m["z"][1] for _, _, m in data.thread_exits] == [0.002, 0.002, 0.005]
    (fig,) = render_figures(data, ["thread_states"])
    assert fig.missing == () and fig.png.startswith(PNG_MAGIC)
    # two shots (a and b share one), each from above and from the side; the rest of the
    # row's panels are left blank: the figure is one row high
    assert 250 < _pixels(fig.png).shape[0] < 400
