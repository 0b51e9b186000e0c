"""Headless MP4 recording (H.264 through imageio-ffmpeg) of an environment's overview camera.

:class:`VideoRecorder` subscribes to a :class:`~ipbench.envs.sorting.SortingEnv`'s frame
listener, so the video shows the robot moving during each skill, not only the step results.
"""

from __future__ import annotations

from pathlib import Path

import imageio.v2 as imageio
import numpy as np

__all__ = ["VideoRecorder", "write_mp4"]


def write_mp4(path: str | Path, frames: list[np.ndarray], fps: float = 30.0) -> Path:
    """Write (H, W, 3) uint8 frames as an H.264 MP4; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with imageio.get_writer(
        path, fps=fps, codec="libx264", quality=7, pixelformat="yuv420p", macro_block_size=8
    ) as writer:
        for frame in frames:
            writer.append_data(np.ascontiguousarray(frame))
    return path


class VideoRecorder:
    """Collects overview frames of ``env`` at ``fps`` simulated frames per second."""

    def __init__(self, env, fps: float = 30.0) -> None:
        self.env, self.fps, self.frames = env.unwrapped, fps, []
        self.env.add_frame_listener(self.capture, fps)

    def capture(self) -> None:
        frame = self.env.render()
        if frame is None:
            raise ValueError("VideoRecorder needs an env made with render_mode='rgb_array'")
        self.frames.append(frame)

    def save(self, path: str | Path) -> Path:
        return write_mp4(path, self.frames, self.fps)
