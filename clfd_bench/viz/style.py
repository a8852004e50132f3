"""How a rollout video looks and what it costs (:class:`VideoStyle`), and the colours every
video draws with."""

from __future__ import annotations

import dataclasses

__all__ = ["DEMONSTRATION_RGBA", "FAILURE_RGB", "INK_RGBA", "PATH_RGBA", "PREDICTION_RGBA",
           "SUCCESS_RGB", "VIDEO_LOOK", "VideoStyle"]

VIDEO_LOOK = 2
"""The version of what a video shows for a given rollout and style (camera, colours, what is
drawn): raised with every change to it, so that videos kept by key (the site's wall tiles)
are rendered again. 2: the camera frames the letter (writing) or the props (RoboTasks)."""

PREDICTION_RGBA = (1.0, 0.55, 0.0, 1.0)
DEMONSTRATION_RGBA = (0.15, 0.7, 0.25, 1.0)
PATH_RGBA = (0.15, 0.35, 0.95, 1.0)
INK_RGBA = (0.05, 0.05, 0.35, 1.0)
SUCCESS_RGB = (40, 190, 70)
FAILURE_RGB = (220, 40, 40)


@dataclasses.dataclass(frozen=True)
class VideoStyle:
    """How videos look and cost.

    Attributes:
        width, height: frame size in pixels (even numbers: H.264 needs them).
        fps: frames per simulated second, also the playback rate (real time); 60 / fps should
            be an integer (the control rate is 60 Hz).
        hold_s: seconds the last frame of each rollout is held (with the outcome border).
        shadows: render shadows and reflections (4-6× slower with software OpenGL).
        antialias: 4× multisampling (~1.2× slower with software OpenGL at 1280×720).
        max_segments: most line segments drawn per path (paths are subsampled to it).
        line_px: line width in pixels (default: height / 120).
        caption: draw a caption (run point, outcome) into the frames.
        caption_reason: the closing caption of a failed rollout adds the env's reason (off:
            only "failed (<kind>)", e.g. for a small tile whose page prints the reason: a
            long reason wrapped over a small frame hides it).
    """

    width: int = 1280
    height: int = 720
    fps: float = 20.0
    hold_s: float = 0.75
    shadows: bool = False
    antialias: bool = False
    max_segments: int = 150
    line_px: float | None = None
    caption: bool = True
    caption_reason: bool = True

    def __post_init__(self) -> None:
        if self.width % 2 or self.height % 2 or self.width < 16 or self.height < 16:
            raise ValueError(f"video size must be even and >= 16 px, got {self.width}x"
                             f"{self.height}")
        if not 0 < self.fps <= 60:
            raise ValueError(f"fps must be in (0, 60] (the control rate is 60 Hz), got {self.fps}")
        if self.hold_s < 0:
            raise ValueError(f"hold_s must be >= 0, got {self.hold_s}")

    @property
    def every(self) -> int:
        """Env steps between frames."""
        return max(1, int(round(60.0 / self.fps)))

    @property
    def hold_frames(self) -> int:
        return int(round(self.hold_s * self.fps))

    def frames_for(self, steps: int) -> int:
        """Frames of one rollout of ``steps`` env steps: the reset state, every
        :attr:`every`-th step, then :attr:`hold_frames`."""
        return 1 + steps // self.every + self.hold_frames
