"""``suture run --video FILE.gif``: headless frames of a run at a fixed sim-time interval.

:class:`VideoCapture` is a per-tick hook (``run_procedure(on_tick=...)``): it grabs a
frame through the scene renderer (:func:`backends.pybullet.render.render_frame`,
PyBullet's software renderer, no display needed) whenever the simulated time has
advanced by ``interval_s`` since the last frame, and :meth:`VideoCapture.write` saves
the frames as a looping GIF with Pillow, atomically (a temporary file in the same
folder, then a rename), so a reader never sees a half-written file.

Memory stays bounded: when ``max_frames`` frames are held, every other frame is
dropped and the interval doubles, so a long run gives a coarser, never a larger, video.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from suture_engine.errors import SutureError

__all__ = ["VideoCapture", "VideoError", "VideoResult", "video_path"]


class VideoError(SutureError):
    """A video that cannot be made.

    Attributes:
        path: the requested file.
        reason: what went wrong.
    """

    code = "video-error"

    def __init__(self, path: str, reason: str) -> None:
        super().__init__(f"--video {path}: {reason}")
        self.path = path
        self.reason = reason


@dataclass(frozen=True)
class VideoResult:
    """A written video.

    Attributes:
        path: the GIF file.
        frames: frames written.
        interval_s: sim time between frames [s] (after any thinning).
        fps: playback rate [frames/s].
    """

    path: Path
    frames: int
    interval_s: float
    fps: float


def video_path(requested: str | Path, out_dir: Path) -> Path:
    """Where ``--video FILE`` goes: a relative name lands in the run's output folder.

    Raises:
        VideoError: the name does not end in ``.gif``.
    """
    req = Path(requested)
    if req.suffix.lower() != ".gif":
        raise VideoError(str(requested), "the video is written as a GIF; name it FILE.gif")
    return req if req.is_absolute() else out_dir / req


class VideoCapture:
    """Collect frames every ``interval_s`` of simulated time.

    Args:
        interval_s: sim time between frames [s] (> 0).
        camera: a :class:`backends.pybullet.render.Camera` (None: the renderer's default).
        max_frames: frames held at most (>= 2); beyond it the video is thinned.
        fps: playback rate of the GIF [frames/s].

    Raises:
        VideoError: a non-positive interval or fewer than 2 frames allowed.
    """

    def __init__(
        self,
        interval_s: float = 0.1,
        camera: Any = None,
        max_frames: int = 600,
        fps: float = 10.0,
    ) -> None:
        if not interval_s > 0.0:
            raise VideoError("", f"the frame interval must be > 0 s, got {interval_s}")
        if max_frames < 2:
            raise VideoError("", f"max_frames must be >= 2, got {max_frames}")
        self.interval_s = float(interval_s)
        self.camera = camera
        self.max_frames = int(max_frames)
        self.fps = float(fps)
        self.frames: list[Any] = []
        self.frame_times: list[float] = []
        """Sim time of each held frame [s]."""
        self._next_t = 0.0

    def _client(self, interp: Any) -> int:
        client = getattr(interp.backend, "client", None)
        if not isinstance(client, int):
            raise VideoError("", "this backend does not render frames (use --backend pybullet)")
        return client

    def __call__(self, interp: Any) -> None:
        """The per-tick hook: grab a frame when its time has come."""
        t = interp.tick_index * interp.dt
        if t + 0.5 * interp.dt < self._next_t:
            return
        self.capture(self._client(interp), t)

    def capture(self, client: int, t: float) -> None:
        """Render one frame of PyBullet client ``client`` at sim time ``t`` [s]."""
        from backends.pybullet.render import render_frame

        self.frames.append(render_frame(client, self.camera))
        self.frame_times.append(t)
        self._next_t = t + self.interval_s
        if len(self.frames) >= self.max_frames:
            self.frames = self.frames[::2]
            self.frame_times = self.frame_times[::2]
            self.interval_s *= 2.0
            self._next_t = self.frame_times[-1] + self.interval_s

    def write(self, path: str | Path) -> VideoResult:
        """Write the frames as a GIF, atomically.

        Raises:
            VideoError: no frames, or the file cannot be written.
        """
        from backends.pybullet.render import RenderError, save_gif

        out = Path(path)
        if not self.frames:
            raise VideoError(str(out), "no frames were captured")
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=".video-", suffix=".gif", dir=out.parent)
            os.close(fd)
        except OSError as exc:
            raise VideoError(str(out), exc.strerror or str(exc)) from None
        try:
            save_gif(self.frames, tmp, fps=self.fps)
            os.chmod(tmp, 0o644)  # mkstemp makes it private; a video is shared like the trace
            os.replace(tmp, out)
        except (RenderError, OSError) as exc:
            try:
                os.remove(tmp)
            except OSError:
                pass
            raise VideoError(str(out), str(exc)) from None
        return VideoResult(out, len(self.frames), self.interval_s, self.fps)
