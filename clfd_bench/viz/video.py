"""Videos of a trained run: the robot executing what the learner predicts.

:func:`render_run_videos` reads a run directory (``results.json`` and the predictions saved
after the last learned task), executes each selected task's prediction for one demo in its env
and renders the rollout offscreen (EGL when ``MUJOCO_GL=egl``) to mp4 with imageio-ffmpeg:
one video per task, one "all tasks" video joining them (the paper's Fig. 1), and for HelloWorld
runs the text written with the learned letters in ``clfd/HelloWorld-v3``.

Drawn into the scene (MuJoCo user geoms added after ``update_scene``): the prediction (orange)
and the demonstration (green) as the tool should follow them, the tool's path so far (blue;
for writing, the ink where the pen touched the board, dark blue). A caption names the run's
method, the task and the demo (:func:`run_caption`); the closing frames add the outcome and a
green (success) or red (failure) border (:func:`outcome_caption`). The camera frames what the
rollout is judged by at the frame's aspect (:mod:`clfd_bench.viz.framing`): a writing task's
letter, the robot drawn see-through over it; a RoboTasks task's props, wherever the rollout
takes them (found by a first rollout without rendering). :func:`render_comparison_video` puts
several runs' rollouts of one task side by side, each tile rendered at its own size.

This module is the front door: it renders a run's videos and re-exports the public names of
the modules that do the parts, one concept each: :mod:`clfd_bench.viz.style` (how a video
looks, its colours), :mod:`clfd_bench.viz.framing` (the camera), :mod:`clfd_bench.viz.overlay`
(frames with the paths drawn in), :mod:`clfd_bench.viz.captions` (text and outcome border),
:mod:`clfd_bench.viz.rollout` (one rollout's frames), :mod:`clfd_bench.viz.writer` (mp4
encoding) and :mod:`clfd_bench.viz.compare` (several runs side by side).

Rendering cost, measured on a 2-core VM with software EGL (Mesa, no GPU) on HelloWorld 'h'
(1060 steps, 369 frames at 20 fps), shadows and reflections off: 1280×720 (the default)
renders ~17 frames/s including the simulation and encodes ~51/s, ~13/s end to end (≈ 30 s
for one letter); 480×360 renders ~30/s and encodes ~200/s (≈ 13 s). Shadows and reflections
cost 4-6×, 4× multisampling ~1.2× at 1280×720. Frames are streamed to the encoder, never all
held in memory.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.viz.captions import method_label, outcome_caption, outcome_text, run_caption
from clfd_bench.viz.compare import comparison_grid, comparison_path, render_comparison_video
from clfd_bench.viz.framing import _object_points, frame_camera  # noqa: F401 (its old home)
from clfd_bench.viz.names import _resolve_tasks, _safe, _video_stem
from clfd_bench.viz.overlay import OverlayRenderer
from clfd_bench.viz.rollout import closing_frame, render_rollout
from clfd_bench.viz.style import (
    DEMONSTRATION_RGBA,
    FAILURE_RGB,
    INK_RGBA,
    PATH_RGBA,
    PREDICTION_RGBA,
    SUCCESS_RGB,
    VIDEO_LOOK,
    VideoStyle,
)
from clfd_bench.viz.writer import VideoWriter

__all__ = [
    "DEMONSTRATION_RGBA",
    "FAILURE_RGB",
    "INK_RGBA",
    "PATH_RGBA",
    "PREDICTION_RGBA",
    "SUCCESS_RGB",
    "VIDEO_LOOK",
    "OverlayRenderer",
    "VideoStyle",
    "VideoWriter",
    "closing_frame",
    "comparison_grid",
    "comparison_path",
    "frame_camera",
    "method_label",
    "outcome_caption",
    "outcome_text",
    "render_comparison_video",
    "render_rollout",
    "render_text_video",
    "render_run_videos",
    "run_caption",
    "text_for_letters",
]

HELLO_WORLD = "hello world"


def text_for_letters(learned: Sequence[str], text: str = HELLO_WORLD) -> str:
    """``text`` restricted to the learned letters (spaces kept, repeated spaces merged): all
    of "hello world" when every letter was learned, e.g. "he" after learning h and e."""
    kept = "".join(c for c in text if c == " " or c in set(learned))
    return " ".join(kept.split())


def render_run_videos(run_dir: str | os.PathLike[str], task: int | str | None = None,
                      demo: int = 0, out_dir: str | os.PathLike[str] = "videos", *,
                      style: VideoStyle | None = None, rerun_path: str | os.PathLike[str] | None
                      = None, all_tasks_video: bool = True, hello_world: bool = True
                      ) -> list[Path]:
    """Renders the robot executing a run's predictions after its last learned task.

    Args:
        run_dir: a directory written by ``clfd-bench train``.
        task: a task index, a task name, or None / "all" for every learned task.
        demo: the demo whose start each prediction starts from (and whose demonstration is
            drawn).
        out_dir: where the mp4 files go.
        style: a :class:`VideoStyle`.
        rerun_path: also log the rendered rollouts to this ``.rrd`` file.
        all_tasks_video: with several tasks, also write one video of all of them in order.
        hello_world: for HelloWorld runs with all tasks selected, also write the text
            ("hello world", or its learned letters) with ``clfd/HelloWorld-v3``.

    Returns:
        The written files: ``{run}_task{j}_{name}_demo{d}.mp4`` per task, then
        ``{run}_all_tasks_demo{d}.mp4`` and ``{run}_text_demo{d}.mp4`` when made; ``{run}``
        is the run directory's name, prefixed by its method when it does not start with it
        (a leaderboard's runs are all called e.g. ``fast_nodet_o0_s0``: ``hn_fast_nodet_o0_s0``).
    """
    from clfd_bench.envs.registration import env_id_for
    from clfd_bench.execution.env_pool import get_env
    from clfd_bench.execution.saved_run import load_run, load_run_predictions
    from clfd_bench.progress import progress

    style = style or VideoStyle()
    out_dir = Path(out_dir)
    saved = load_run(run_dir)
    run_dir, dataset, m = saved.path, saved.dataset, saved.num_learned
    if m == 0:
        raise ValueError(f"{run_dir} has no learned task yet; nothing to render")
    names = saved.learned
    selected = _resolve_tasks(task, names)
    preds = load_run_predictions(run_dir, m - 1)
    demos = dict(enumerate(saved.demos()))
    n_demos = min(len(preds[j]) for j in selected)
    if not 0 <= demo < n_demos:
        raise ValueError(f"demo {demo} out of range: the run predicted demos 0..{n_demos - 1}")
    stem = _video_stem(saved)
    logger = None
    if rerun_path is not None:
        from clfd_bench.viz.rerun_log import RolloutLogger

        logger = RolloutLogger(rerun_path, recording_name=f"video {run_dir.name}")
    written: list[Path] = []
    joint = None
    if all_tasks_video and len(selected) > 1:
        joint = VideoWriter(out_dir / f"{stem}_all_tasks_demo{demo}.mp4", style.fps)
    try:
        for j in progress(selected, desc=f"videos {run_dir.name}", unit="task"):
            try:
                env_id = env_id_for(dataset, names[j])
            except KeyError as exc:
                warnings.warn(f"no video of task {j} ({names[j]}): {exc.args[0]}",
                              stacklevel=2)
                continue
            env = get_env(env_id)
            writer = VideoWriter(out_dir / f"{stem}_task{j}_{_safe(names[j])}_demo{demo}.mp4",
                                 style.fps)
            sinks = [writer.append] + ([joint.append] if joint is not None else [])
            try:
                result, _ = render_rollout(
                    env, preds[j][demo], demo, sinks, demonstration=demos[j][demo],
                    caption=run_caption(saved, f"task {j} '{names[j]}'", demo),
                    style=style, trace=logger is not None)
            except BaseException:
                writer.abort()
                raise
            written.append(writer.close())
            if logger is not None:
                logger.log_rollout(f"video/{names[j]}/demo_{demo}", env.unwrapped, result,
                                   prediction=preds[j][demo], demonstration=demos[j][demo])
        if joint is not None:
            written.append(joint.close())
            joint = None
        if hello_world and dataset == "helloworld" and len(selected) == m:
            path = _render_text(saved, stem, out_dir, names, preds, demos, demo, style, logger)
            if path is not None:
                written.append(path)
    finally:
        if joint is not None:
            joint.abort()
        if logger is not None:
            logger.close()
    return written


def render_text_video(run_dir: str | os.PathLike[str], demo: int = 0,
                      out_dir: str | os.PathLike[str] = "videos", *,
                      style: VideoStyle | None = None) -> Path | None:
    """Renders only the HelloWorld text ("hello world", or the letters learned so far) written
    with ``clfd/HelloWorld-v3`` from a HelloWorld run's predictions after its last task.

    Returns:
        The mp4's path, or None when the run learned none of the text's letters.
    """
    from clfd_bench.execution.saved_run import load_run, load_run_predictions

    run = load_run(run_dir)
    if run.dataset != "helloworld":
        raise ValueError(f"{run.path} is a {run.dataset} run; the text video needs helloworld")
    if run.num_learned == 0:
        raise ValueError(f"{run.path} has no learned task yet; nothing to render")
    preds = load_run_predictions(run.path, run.num_learned - 1)
    demos = dict(enumerate(run.demos()))
    return _render_text(run, _video_stem(run), Path(out_dir), run.learned,
                        preds, demos, demo, style or VideoStyle(), None)


def _render_text(saved: Any, stem: str, out_dir: Path, names: Sequence[str],
                 preds: dict[int, np.ndarray],
                 demos: dict[int, np.ndarray], demo: int, style: VideoStyle,
                 logger: Any) -> Path | None:
    """Writes the HelloWorld text from the learned letters (``clfd/HelloWorld-v3``)."""
    from clfd_bench.execution.env_pool import get_env

    text = text_for_letters(names)
    if not text:
        return None
    env = get_env("clfd/HelloWorld-v3", text=text)
    base = env.unwrapped
    if not 0 <= demo < base.num_demos:
        return None
    index = {name: j for j, name in enumerate(names)}
    letters = [c for c in text if c != " "]
    trajectory = [preds[index[c]][demo] for c in letters]
    demonstration = [demos[index[c]][demo] for c in letters]
    writer = VideoWriter(out_dir / f"{stem}_text_demo{demo}.mp4", style.fps)
    try:
        result, _ = render_rollout(env, trajectory, demo, [writer.append],
                                   demonstration=demonstration,
                                   caption=run_caption(saved, f"'{text}'", demo),
                                   style=style, trace=logger is not None)
    except BaseException:
        writer.abort()
        raise
    if logger is not None:
        logger.log_rollout(f"video/text/demo_{demo}", base, result, prediction=trajectory,
                           demonstration=demonstration)
    return writer.close()
