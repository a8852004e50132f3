"""The comparison video: several runs' rollouts of one task side by side, in a grid."""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.viz.captions import _font, _run_label, _wrap
from clfd_bench.viz.framing import _camera_for, _is_writing, _motion_points
from clfd_bench.viz.names import _resolve_tasks, _safe
from clfd_bench.viz.rollout import render_rollout
from clfd_bench.viz.style import VideoStyle
from clfd_bench.viz.writer import VideoWriter

__all__ = ["comparison_grid", "comparison_path", "render_comparison_video"]


def comparison_grid(n: int, style: VideoStyle) -> tuple[int, int, int, int]:
    """``(rows, cols, tile_width, tile_height)`` of a comparison of ``n`` tiles in a frame of
    ``style``'s size: ``cols = ceil(sqrt(n))``, ``rows = ceil(n / cols)``, tiles of equal,
    even size (the frame's remainder is a black margin)."""
    if n < 1:
        raise ValueError("a comparison needs at least one run")
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    tw, th = (style.width // cols) // 2 * 2, (style.height // rows) // 2 * 2
    if tw < 16 or th < 16:
        raise ValueError(f"{n} tiles do not fit a {style.width}x{style.height} frame "
                         f"({tw}x{th} each); choose a larger --size")
    return rows, cols, tw, th


def _legend(tile: tuple[int, int], lines: Sequence[str]) -> np.ndarray:
    """A black tile ``(width, height)`` with ``lines`` of text (the comparison's empty
    cell)."""
    from PIL import Image, ImageDraw

    w, h = tile
    img = Image.new("RGB", (w, h))
    draw = ImageDraw.Draw(img)
    font = _font(max(10, h // 16))
    pad = max(4, h // 20)
    wrapped = [part for t in lines for part in _wrap(draw, t, font, w - 2 * pad)]
    draw.multiline_text((pad, pad), "\n".join(wrapped), fill=(255, 255, 255), font=font,
                        spacing=max(2, h // 40))
    return np.asarray(img)


def comparison_path(run_dir: str | os.PathLike[str], task: int | str, demo: int = 0,
                    out_dir: str | os.PathLike[str] = "videos") -> Path:
    """``out_dir/compare_<dataset>_task<j>_<name>_demo<d>.mp4``, named after ``run_dir``'s
    task ``task`` (an index or a name)."""
    from clfd_bench.execution.saved_run import load_run

    run = load_run(run_dir)
    j = _resolve_tasks(task, run.task_names)[0]
    name = _safe(run.task_names[j])
    return Path(out_dir) / f"compare_{run.dataset}_task{j}_{name}_demo{demo}.mp4"


def render_comparison_video(run_dirs: Sequence[str | os.PathLike[str]], task: int | str,
                            demo: int = 0, out_path: str | os.PathLike[str] | None = None,
                            style: VideoStyle | None = None) -> Path:
    """One video of the same task executed by several runs (e.g. every method of a
    leaderboard after learning all tasks), side by side: a grid of tiles
    (:func:`comparison_grid`), each rendered at tile size, captioned with the run's method
    and, on its held closing frames, its outcome (:func:`outcome_caption`). Every tile has
    the same camera (framing all the runs' rollouts) and starts together; a rollout that ends
    earlier holds its last frame. An empty cell, if any, names the task and the colours.

    Args:
        run_dirs: run directories of ``clfd-bench train`` on one dataset (each run's
            predictions after its last learned task are executed).
        task: the task's index or name (the index counts in the first run's task order).
        demo: the demo whose start every prediction starts from (and whose demonstration is
            drawn).
        out_path: the mp4 (default ``videos/compare_<dataset>_task<j>_<name>_demo<d>.mp4``).
        style: the whole frame's :class:`VideoStyle` (its size is the grid's).

    Returns:
        The written mp4.

    Raises:
        ValueError: no runs, runs of different datasets, a run that has not learned the
            task, a demo out of range, or a frame too small for the tiles.
    """
    import tempfile

    import imageio.v2 as iio

    from clfd_bench.envs.registration import env_id_for
    from clfd_bench.execution.env_pool import get_env
    from clfd_bench.execution.saved_run import load_run, load_run_predictions
    from clfd_bench.execution.trace import tool_path

    style = style or VideoStyle()
    runs = [load_run(d) for d in run_dirs]
    if not runs:
        raise ValueError("render_comparison_video needs at least one run directory")
    datasets = sorted({r.dataset for r in runs})
    if len(datasets) > 1:
        raise ValueError(f"the runs are on different datasets ({', '.join(datasets)}); a "
                         "comparison shows one task of one dataset")
    name = runs[0].task_names[_resolve_tasks(task, runs[0].task_names)[0]]
    trajectories = []
    for run in runs:
        if name not in run.learned:
            raise ValueError(f"{run.path} has not learned task {name!r} (learned: "
                             f"{', '.join(run.learned) or 'none'})")
        preds = load_run_predictions(run.path, run.num_learned - 1)
        j = run.learned.index(name)
        if not 0 <= demo < len(preds[j]):
            raise ValueError(f"demo {demo} out of range: {run.path} predicted demos 0.."
                             f"{len(preds[j]) - 1}")
        trajectories.append(preds[j][demo])
    j = runs[0].task_names.index(name)
    demonstration = runs[0].demos()[j][demo]
    dataset = datasets[0]
    out = Path(out_path) if out_path is not None else comparison_path(runs[0].path, j, demo)
    rows, cols, tw, th = comparison_grid(len(runs), style)
    tile = dataclasses.replace(style, width=tw, height=th)
    env = get_env(env_id_for(dataset, name))
    base = env.unwrapped
    # One camera for every tile: the union of all the rollouts' paths and motion.
    targets = np.concatenate([tool_path(base, t) for t in trajectories])
    extra = [tool_path(base, demonstration)]
    if not _is_writing(base):
        extra += [_motion_points(env, t, demo, None, tile.every) for t in trajectories]
    camera = _camera_for(base, targets, np.concatenate(extra), tw / th)
    labels = [_run_label(r) for r in runs]
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".compare.", dir=out.parent) as tmp:
        tiles = []
        for k, traj in enumerate(trajectories):
            path = Path(tmp) / f"tile{k}.mp4"
            writer = VideoWriter(path, tile.fps, quality=9)
            try:
                render_rollout(env, traj, demo, [writer.append], demonstration=demonstration,
                               caption=f"{labels[k]} · '{name}'", style=tile, camera=camera)
            except BaseException:
                writer.abort()
                raise
            tiles.append(writer.close())
        legend = None
        if rows * cols > len(runs):
            learned = "after learning all tasks" if all(r.complete for r in runs) else (
                "after each run's last learned task")
            legend = _legend((tw, th), [f"{dataset}: task {j} '{name}'", f"demo {demo}, {learned}",
                                        "orange: prediction", "green: demonstration",
                                        "blue: the tool's path (writing: its ink)"])
        _compose(tiles, out, style, rows, cols, (tw, th), legend, iio)
    return out


def _compose(tiles: Sequence[Path], out: Path, style: VideoStyle, rows: int, cols: int,
             size: tuple[int, int], legend: np.ndarray | None, iio: Any) -> None:
    """Plays the tile videos side by side into ``out`` (a tile that has ended holds its last
    frame; the first empty cell shows ``legend``)."""
    tw, th = size
    x0, y0 = (style.width - cols * tw) // 2, (style.height - rows * th) // 2
    readers = [iio.get_reader(p) for p in tiles]
    iters = [iter(r) for r in readers]
    last: list[np.ndarray | None] = [None] * len(tiles)
    canvas = np.zeros((style.height, style.width, 3), dtype=np.uint8)
    if legend is not None:
        r, c = divmod(len(tiles), cols)
        canvas[y0 + r * th: y0 + (r + 1) * th, x0 + c * tw: x0 + (c + 1) * tw] = legend
    writer = VideoWriter(out, style.fps)
    try:
        while True:
            fresh = False
            for k, it in enumerate(iters):
                frame = next(it, None)
                if frame is not None:
                    last[k], fresh = np.asarray(frame)[:th, :tw, :3], True
            if not fresh:
                break
            for k, frame in enumerate(last):
                if frame is not None:
                    r, c = divmod(k, cols)
                    canvas[y0 + r * th: y0 + (r + 1) * th, x0 + c * tw: x0 + (c + 1) * tw] = frame
            writer.append(canvas)
    except BaseException:
        writer.abort()
        raise
    finally:
        for reader in readers:
            reader.close()
    writer.close()
