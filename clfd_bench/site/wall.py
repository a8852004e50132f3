"""The video wall's tiles: one execution video per (run, task), rendered once.

Each tile is rendered by :func:`clfd_bench.viz.video.render_run_videos` (its public API only)
into a folder of its own, whose name carries a key of what the video shows (the run's
predictions file, the simulator's fingerprint, the tile's size and rate, the demo, the
videos' look): a tile whose folder already holds an mp4 is reused, so an interrupted site
build resumes, and a run trained or executed again, or a new camera, gets new videos. The
video writer renames a finished file into place, so a killed build leaves no half-written
video.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path

__all__ = ["WALL_STYLE", "TileJob", "TileResult", "existing_video", "poster_for", "render_tiles",
           "tile_key"]

WALL_STYLE = {"width": 240, "height": 180, "fps": 6.0}
"""Size and frame rate of the wall's tiles: software OpenGL costs ~35-45 ms per frame
whatever the size at this scale, so the frame rate sets the cost (a 1000-step HelloWorld
letter: ~110 frames, ~5 s)."""


@dataclasses.dataclass(frozen=True)
class TileJob:
    """One tile to render: ``task`` of the run in ``run_dir``, from demo ``demo``'s start,
    as a ``width`` × ``height`` video at ``fps``, into ``out_dir``."""

    run_dir: str
    task: int
    demo: int
    out_dir: str
    width: int
    height: int
    fps: float


@dataclasses.dataclass(frozen=True)
class TileResult:
    """What rendering a tile gave: the video (None when there is none) and why not."""

    job: TileJob
    video: Path | None
    error: str | None = None
    seconds: float = 0.0
    reused: bool = False


def tile_key(predictions_sha256: str | None, fingerprint: str | None, demo: int,
             width: int, height: int, fps: float) -> str:
    """A short key of what a tile shows (folder name part): also the videos' look
    (:data:`~clfd_bench.viz.video.VIDEO_LOOK`), so a new camera renders the tiles again."""
    from clfd_bench.viz.video import VIDEO_LOOK

    text = (f"{predictions_sha256}|{fingerprint}|{demo}|{width}x{height}@{fps:g}|look{VIDEO_LOOK}"
            "|no-reason")
    return hashlib.sha256(text.encode()).hexdigest()[:10]


def existing_video(out_dir: str | os.PathLike[str], task: int) -> Path | None:
    """The finished video of ``task`` in a tile's folder (temporary files, whose names start
    with a dot, do not count), or None."""
    folder = Path(out_dir)
    if not folder.is_dir():
        return None
    videos = sorted(p for p in folder.glob("*.mp4") if not p.name.startswith("."))
    named = [p for p in videos if f"task{task}_" in p.name]
    return (named or videos or [None])[0]


def poster_for(video: str | os.PathLike[str]) -> Path:
    """The poster of a tile's video: its last frame as a PNG beside it (``<video>.png``; the
    closing frame shows the outcome's border and the whole path), written once, atomically.

    A wall of dozens of autoplaying videos is more than a browser decodes at once (headless
    Chromium shows some of them black), so the wall shows posters and plays a video only while
    the pointer is on it."""
    import uuid

    import imageio.v2 as iio

    video = Path(video)
    poster = video.with_suffix(".png")
    if poster.is_file():
        return poster
    frames = iio.mimread(video, memtest=False)  # a tile is small: ~100 frames of 240x180
    if not frames:
        raise ValueError(f"{video} has no frame; delete its folder and build the site again")
    tmp = poster.with_name(f".{poster.stem}.{uuid.uuid4().hex[:8]}.tmp.png")
    try:
        iio.imwrite(tmp, frames[-1])
        os.replace(tmp, poster)
    finally:
        tmp.unlink(missing_ok=True)
    return poster


def _render(job: TileJob) -> TileResult:
    """Renders one tile (in this process or a worker)."""
    import warnings

    from clfd_bench.viz.video import VideoStyle, render_run_videos

    start = time.perf_counter()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            paths = render_run_videos(
                job.run_dir, task=job.task, demo=job.demo, out_dir=job.out_dir,
                # the page prints a failure's reason under its tile: over the tile's closing
                # frames, wrapped small, it would hide the letter
                style=VideoStyle(width=job.width, height=job.height, fps=job.fps,
                                 caption_reason=False),
                all_tasks_video=False, hello_world=False)
    except Exception as exc:  # one tile's failure is shown on its tile, not fatal to the site
        return TileResult(job, None, f"{type(exc).__name__}: {exc}",
                          time.perf_counter() - start)
    video = existing_video(job.out_dir, job.task) if paths else None
    error = None
    if video is None:
        error = "; ".join(str(w.message) for w in caught) or "no video was written"
    return TileResult(job, video, error, time.perf_counter() - start)


def _worker_init() -> None:
    from clfd_bench.procs import die_with_parent

    die_with_parent()  # a killed site build leaves no worker behind
    os.environ.setdefault("CLFD_NO_PROGRESS", "1")
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # pragma: no cover - torch is a dependency
        pass


def render_tiles(jobs: Sequence[TileJob], workers: int = 1,
                 on_done: Callable[[TileResult], None] | None = None) -> list[TileResult]:
    """Renders the tiles of ``jobs`` that have no video yet (the others are reused), with
    ``workers`` processes; returns one result per job, in order."""
    results: dict[int, TileResult] = {}
    todo = []
    for k, job in enumerate(jobs):
        video = existing_video(job.out_dir, job.task)
        if video is not None:
            results[k] = TileResult(job, video, reused=True)
        else:
            todo.append(k)

    def finish(k: int, result: TileResult) -> None:
        results[k] = result
        if on_done is not None:
            on_done(result)

    if workers <= 1 or len(todo) <= 1:
        for k in todo:
            finish(k, _render(jobs[k]))
    else:
        import concurrent.futures
        import multiprocessing

        ctx = multiprocessing.get_context("spawn")  # no inherited GL contexts or torch threads
        with concurrent.futures.ProcessPoolExecutor(
                max_workers=min(workers, len(todo)), mp_context=ctx,
                initializer=_worker_init) as pool:
            for k, result in zip(todo, pool.map(_render, [jobs[k] for k in todo],
                                                chunksize=1), strict=True):
                finish(k, result)
    return [results[k] for k in range(len(jobs))]
