"""Encoding: frames streamed into an mp4 that appears only when it is whole."""

from __future__ import annotations

import os
import uuid
from pathlib import Path

import numpy as np

__all__ = ["VideoWriter"]


class VideoWriter:
    """Streams frames ``[H, W, 3]`` uint8 into an mp4 (H.264 via imageio-ffmpeg), written to a
    temporary sibling and renamed into place on :meth:`close` (atomic). ``quality``: imageio's
    0-10 scale."""

    def __init__(self, path: str | os.PathLike[str], fps: float, quality: int = 7):
        import imageio.v2 as iio

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self.path.with_name(f".{self.path.stem}.{uuid.uuid4().hex[:8]}.tmp.mp4")
        self._writer = iio.get_writer(self._tmp, fps=fps, codec="libx264", quality=quality,
                                      macro_block_size=2, ffmpeg_log_level="error")
        self.frames = 0

    def append(self, frame: np.ndarray) -> None:
        self._writer.append_data(np.ascontiguousarray(frame))
        self.frames += 1

    def close(self) -> Path:
        self._writer.close()
        if self.frames == 0:
            self._tmp.unlink(missing_ok=True)
            raise ValueError(f"no frames were written to {self.path}")
        os.replace(self._tmp, self.path)
        return self.path

    def abort(self) -> None:
        try:
            self._writer.close()
        finally:
            self._tmp.unlink(missing_ok=True)
