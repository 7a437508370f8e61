"""``suture run --video``: frames at a fixed sim-time interval, GIF written atomically."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from suture_engine.runtime.run import run_procedure
from suture_engine.runtime.video import VideoCapture, VideoError, video_path

ROOT = Path(__file__).resolve().parent.parent
PROCS = ROOT / "tests" / "procedures"
SUTURE = [sys.executable, "-c", "from suture_engine.cli import main; main()"]


def _gif_frames(path: Path) -> tuple[int, int]:
    """(frames stored, total duration [ms]) of a GIF, read back by Pillow."""
    with Image.open(path) as im:
        n = int(getattr(im, "n_frames", 1))
        total = 0
        for i in range(n):
            im.seek(i)
            total += int(im.info["duration"])
        return n, total


@pytest.fixture()
def client() -> object:
    import pybullet as p

    cid = p.connect(p.DIRECT)
    p.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=-1,
        baseVisualShapeIndex=p.createVisualShape(
            p.GEOM_BOX, halfExtents=[0.02, 0.02, 0.02], physicsClientId=cid
        ),
        physicsClientId=cid,
    )
    yield cid
    p.disconnect(physicsClientId=cid)


def test_frames_follow_the_sim_clock_and_the_gif_keeps_the_timing(tmp_path: Path) -> None:
    capture = VideoCapture(interval_s=0.05, fps=20.0)
    result = run_procedure(
        PROCS / "reach.yaml", backend="pybullet", out=tmp_path / "run", on_tick=capture
    )
    sim = result.summary.sim_time_s
    times = np.asarray(capture.frame_times)
    # one frame at t = 0 and then one every 50 ms of simulated time (to the tick)
    assert times[0] == 0.0
    np.testing.assert_allclose(np.diff(times), 0.05, atol=1.5e-3)
    assert len(times) == int(np.floor(sim / 0.05 + 1e-9)) + 1
    # the robot moves during reach: the first and the last frame differ visibly
    first, last = capture.frames[0].astype(int), capture.frames[-1].astype(int)
    assert first.shape == (240, 320, 3)
    assert np.mean(np.any(first != last, axis=2)) > 0.002
    written = capture.write(video_path("reach.gif", result.out_dir))
    assert written.path == result.out_dir / "reach.gif"
    stored, total_ms = _gif_frames(written.path)
    # Pillow merges identical consecutive frames but keeps their display time
    assert 2 <= stored <= len(times)
    assert total_ms == len(times) * 50
    assert sorted(p.name for p in result.out_dir.iterdir()) == [
        "reach.gif",
        "summary.json",
        "trace.mcap",
    ]


def test_thinning_keeps_memory_bounded_and_doubles_the_interval(client: int) -> None:
    capture = VideoCapture(interval_s=0.1, max_frames=4)
    interp = SimpleNamespace(backend=SimpleNamespace(client=client), dt=0.01, tick_index=0)
    for k in range(120):  # 1.2 s of 10 ms ticks
        interp.tick_index = k
        capture(interp)
    # 0, .1, .2, .3 -> thinned to 0, .2 (every .2 s) -> 0, .2, .4, .6 -> 0, .4 -> 0, .4, .8
    np.testing.assert_allclose(capture.frame_times, [0.0, 0.4, 0.8], atol=1e-9)
    assert capture.interval_s == pytest.approx(0.4)
    assert len(capture.frames) == 3


def test_a_backend_without_frames_is_refused() -> None:
    capture = VideoCapture()
    interp = SimpleNamespace(backend=object(), dt=0.001, tick_index=0)
    with pytest.raises(VideoError, match="pybullet"):
        capture(interp)


def test_write_is_atomic_and_errors_are_typed(tmp_path: Path, client: int) -> None:
    capture = VideoCapture()
    with pytest.raises(VideoError, match="no frames"):
        capture.write(tmp_path / "empty.gif")
    capture.capture(client, 0.0)
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    with pytest.raises(VideoError):
        capture.write(blocked / "v.gif")
    ok = capture.write(tmp_path / "v.gif")
    assert ok.frames == 1
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".video-")] == []
    with pytest.raises(VideoError, match="GIF"):
        video_path("movie.mp4", tmp_path)
    assert video_path(tmp_path / "abs.gif", Path("elsewhere")) == tmp_path / "abs.gif"
    with pytest.raises(VideoError, match="> 0"):
        VideoCapture(interval_s=0.0)


def test_cli_video_end_to_end_and_usage_errors(tmp_path: Path) -> None:
    out = tmp_path / "o"
    res = subprocess.run(
        [*SUTURE, "run", str(PROCS / "steps.yaml"), "--out", str(out), "--video", "run.gif"],
        capture_output=True,
        text=True,
        timeout=240,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    assert "video:" in res.stdout
    stored, total_ms = _gif_frames(out / "run.gif")
    assert stored >= 1 and total_ms == 7 * 100  # 0.6 s at 0.1 s: frames at 0, 0.1, ..., 0.6
    for extra, message in (
        (["--video", "run.mp4"], "GIF"),
        (["--video", "run.gif", "--backend", "ideal"], "pybullet"),
        (["--video", "run.gif", "--video-interval", "0"], "> 0"),
    ):
        res = subprocess.run(
            [*SUTURE, "run", str(PROCS / "steps.yaml"), "--out", str(tmp_path / "x"), *extra],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
        assert res.returncode == 2, (extra, res.stdout, res.stderr)
        assert message in res.stderr
        assert "Traceback" not in res.stderr
