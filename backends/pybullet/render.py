"""Headless rendering: PNG frames from a configurable camera and GIFs of a run.

Frames come from PyBullet's software renderer (``ER_TINY_RENDERER``), so no display or GPU
is needed. :class:`Camera` looks at a target from a distance [m] with yaw, pitch [deg];
:func:`render_frame` returns an RGB array, :func:`save_png` and :func:`save_gif` write files
with Pillow.

``python -m backends.pybullet.render OUT.gif`` renders the scripted demo: a loosely laid
square knot tightened by two graspers pulling the ends to 2 N (the knot is laid by
construction along a hand-built curve, then tightened by tool motion).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from suture_engine.errors import SutureError

__all__ = ["Camera", "RenderError", "render_frame", "save_gif", "save_png"]

Image = NDArray[np.uint8]


class RenderError(SutureError):
    """A frame or file could not be produced.

    Attributes:
        path: the file concerned, or "".
        reason: what went wrong.
    """

    code = "render-error"

    def __init__(self, path: str, reason: str) -> None:
        super().__init__(f"cannot render {path or 'frame'}: {reason}")
        self.path = path
        self.reason = reason


@dataclass(frozen=True)
class Camera:
    """An orbiting camera.

    Attributes:
        target: point looked at, world frame [m].
        distance: distance from the target [m].
        yaw: azimuth about world z [deg].
        pitch: elevation (negative looks down) [deg].
        width: image width [px].
        height: image height [px].
        fov: vertical field of view [deg].
        near: near clipping distance [m].
        far: far clipping distance [m].
    """

    target: tuple[float, float, float] = (0.0, -0.02, 0.02)
    distance: float = 0.25
    yaw: float = 20.0
    pitch: float = -35.0
    width: int = 320
    height: int = 240
    fov: float = 45.0
    near: float = 0.005
    far: float = 2.0

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise RenderError("", f"image size {self.width}x{self.height} must be positive")
        if not 0 < self.near < self.far:
            raise RenderError("", f"clipping range ({self.near}, {self.far}) is invalid")


def render_frame(client: int, camera: Camera | None = None) -> Image:
    """Render the world headless with the tiny software renderer.

    Args:
        client: PyBullet physics client id.
        camera: the camera (default: looking at the tissue from above and in front).

    Returns:
        height×width×3 RGB image.
    """
    import pybullet as p

    cam = camera or Camera()
    view = p.computeViewMatrixFromYawPitchRoll(
        cameraTargetPosition=list(cam.target),
        distance=cam.distance,
        yaw=cam.yaw,
        pitch=cam.pitch,
        roll=0.0,
        upAxisIndex=2,
        physicsClientId=client,
    )
    proj = p.computeProjectionMatrixFOV(
        fov=cam.fov,
        aspect=cam.width / cam.height,
        nearVal=cam.near,
        farVal=cam.far,
        physicsClientId=client,
    )
    _, _, rgba, _, _ = p.getCameraImage(
        cam.width,
        cam.height,
        viewMatrix=view,
        projectionMatrix=proj,
        renderer=p.ER_TINY_RENDERER,
        physicsClientId=client,
    )
    img = np.asarray(rgba, dtype=np.uint8).reshape(cam.height, cam.width, 4)
    return np.ascontiguousarray(img[:, :, :3])


def save_png(image: Image, path: str | Path) -> Path:
    """Write an RGB image as PNG.

    Raises:
        RenderError: the file cannot be written.
    """
    from PIL import Image as PilImage

    out = Path(path)
    try:
        PilImage.fromarray(image).save(out, format="PNG")
    except OSError as exc:
        raise RenderError(str(out), str(exc)) from exc
    return out


def save_gif(frames: Sequence[Image], path: str | Path, fps: float = 10.0) -> Path:
    """Write frames as a looping, palette-optimised GIF.

    Args:
        frames: RGB images of equal size.
        path: output file.
        fps: playback rate [frames/s].

    Raises:
        RenderError: no frames, or the file cannot be written.
    """
    from PIL import Image as PilImage

    out = Path(path)
    if not frames:
        raise RenderError(str(out), "no frames")
    images = [PilImage.fromarray(f).convert("P", palette=PilImage.Palette.ADAPTIVE) for f in frames]
    try:
        images[0].save(
            out,
            format="GIF",
            save_all=True,
            append_images=images[1:],
            duration=int(1000 / fps),
            loop=0,
            optimize=True,
        )
    except OSError as exc:
        raise RenderError(str(out), str(exc)) from exc
    return out


def record(
    client: int, advance: Callable[[], bool], every: int, camera: Camera | None = None
) -> list[Image]:
    """Step a scripted run and grab a frame every ``every`` steps.

    Args:
        client: PyBullet physics client id.
        advance: advances the run by one physics step; returns False when done.
        every: physics steps between frames.
        camera: the camera.

    Returns:
        The frames, the first before any step.
    """
    frames = [render_frame(client, camera)]
    k = 0
    while advance():
        k += 1
        if k % every == 0:
            frames.append(render_frame(client, camera))
    frames.append(render_frame(client, camera))
    return frames


def _demo(out: Path) -> None:
    """Render the square-knot tightening demo to ``out`` (GIF) and a PNG of its last frame."""
    from backends.pybullet.scene import build_scene
    from backends.pybullet.tools import Grasper

    scene = build_scene(
        {"tissue": {}, "suture": {"knot": "square", "segments": 80, "knot_scale": 0.0025}}
    )
    left, right = scene.tools["left"], scene.tools["right"]
    assert isinstance(left, Grasper) and isinstance(right, Grasper)
    cam = Camera(
        target=(0.0, -0.03, 0.03), distance=0.09, yaw=10.0, pitch=-50.0, width=400, height=260
    )
    xl, xr = np.array(left.pose()[0]), np.array(right.pose()[0])
    left.close()
    right.close()
    state = {"t": 0, "hold": 0}

    def advance() -> bool:
        force = 0.5 * (left.grip_force() + right.grip_force())
        if state["t"] > 150 and force < 2.0 and state["hold"] == 0:
            v = 0.02 if force < 0.3 else 0.004
            xl[0] -= v / 1000
            xr[0] += v / 1000
            left.set_pose((xl[0], xl[1], xl[2]))
            right.set_pose((xr[0], xr[1], xr[2]))
        elif force >= 2.0 or state["hold"]:
            state["hold"] += 1
        scene.step()
        state["t"] += 1
        return state["hold"] < 500 and state["t"] < 8000

    frames = record(scene.client, advance, every=100, camera=cam)
    scene.close()
    save_gif(frames, out, fps=8)
    save_png(frames[-1], out.with_suffix(".png"))


if __name__ == "__main__":
    _demo(Path(sys.argv[1] if len(sys.argv) > 1 else "knot.gif"))
