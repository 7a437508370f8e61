"""Headless rendering: frames show the scene where a pinhole model puts it; files round-trip."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from backends.pybullet.render import Camera, RenderError, render_frame, save_gif, save_png


def _project(cam: Camera, point: np.ndarray) -> tuple[float, float]:
    """Pixel (column, row) of a world point by an independent pinhole model of ``cam``."""
    yaw, pitch = math.radians(cam.yaw), math.radians(cam.pitch)
    # PyBullet's yaw/pitch convention: the eye sits behind the target along the view direction.
    forward = np.array(
        [math.sin(yaw) * math.cos(pitch), -math.cos(yaw) * math.cos(pitch), math.sin(pitch)]
    )
    forward = -forward
    eye = np.asarray(cam.target) - cam.distance * forward
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    d = point - eye
    x, y, z = d @ right, d @ up, d @ forward
    f = (cam.height / 2) / math.tan(math.radians(cam.fov) / 2)
    return cam.width / 2 + f * x / z, cam.height / 2 - f * y / z


@pytest.fixture
def world():  # type: ignore[no-untyped-def]
    import pybullet as p

    c = p.connect(p.DIRECT)
    yield c
    p.disconnect(physicsClientId=c)


def test_sphere_appears_where_a_pinhole_camera_puts_it(world: int) -> None:
    import pybullet as p

    cam = Camera(target=(0.0, 0.0, 0.0), distance=0.3, yaw=30.0, pitch=-40.0)
    empty = render_frame(world, cam)
    assert empty.shape == (cam.height, cam.width, 3) and empty.dtype == np.uint8
    centre = np.array([0.02, 0.01, 0.015])
    vis = p.createVisualShape(
        p.GEOM_SPHERE, radius=0.006, rgbaColor=[1, 0, 0, 1], physicsClientId=world
    )
    p.createMultiBody(0, -1, vis, centre.tolist(), physicsClientId=world)
    img = render_frame(world, cam).astype(int)
    red = (img[:, :, 0] > 120) & (img[:, :, 1] < 60) & (img[:, :, 2] < 60)
    assert red.sum() > 20
    rows, cols = np.nonzero(red)
    u, v = _project(cam, centre)
    assert abs(cols.mean() - u) < 3 and abs(rows.mean() - v) < 3
    assert not ((empty[:, :, 0] > 120) & (empty[:, :, 1] < 60) & (empty[:, :, 2] < 60)).any()


def test_png_and_gif_round_trip(tmp_path: Path) -> None:
    from PIL import Image

    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 255, (24, 32, 3), dtype=np.uint8) for _ in range(4)]
    png = save_png(frames[0], tmp_path / "f.png")
    assert np.array_equal(np.asarray(Image.open(png).convert("RGB")), frames[0])
    gif = save_gif(frames, tmp_path / "run.gif", fps=5)
    with Image.open(gif) as im:
        assert im.n_frames == 4 and im.size == (32, 24)


def test_bad_inputs_are_typed_errors(tmp_path: Path) -> None:
    with pytest.raises(RenderError):
        Camera(width=0)
    with pytest.raises(RenderError):
        save_gif([], tmp_path / "x.gif")
    with pytest.raises(RenderError) as err:
        save_png(np.zeros((4, 4, 3), np.uint8), tmp_path / "missing" / "x.png")
    assert "missing" in err.value.path
