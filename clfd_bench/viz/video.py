"""Videos of a trained run: the robot executing what the learner predicts.

:func:`render_run_videos` reads a run directory (``results.json`` and the predictions saved
after the last learned task), executes each selected task's prediction for one demo in its env
and renders the rollout offscreen (EGL when ``MUJOCO_GL=egl``) to mp4 with imageio-ffmpeg:
one video per task, one "all tasks" video joining them (the paper's Fig. 1), and for HelloWorld
runs the text written with the learned letters in ``clfd/HelloWorld-v2``.

Drawn into the scene (MuJoCo user geoms added after ``update_scene``): the prediction (orange)
and the demonstration (green) as the tool should follow them, the tool's path so far (blue;
for writing, the ink where the pen touched the board, dark blue). A caption names the run
point, and the closing frames get a green (success) or red (failure) border.

Rendering cost: software OpenGL renders ~10-15 frames/s at 480×360 with shadows and
reflections off (they cost ~7×); the defaults (:class:`VideoStyle`) keep a 1000-step task
under a minute. Frames are streamed to the encoder, never all held in memory.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import uuid
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "OverlayRenderer",
    "VideoStyle",
    "VideoWriter",
    "frame_camera",
    "render_rollout",
    "render_text_video",
    "render_run_videos",
    "text_for_letters",
]

PREDICTION_RGBA = (1.0, 0.55, 0.0, 1.0)
DEMONSTRATION_RGBA = (0.15, 0.7, 0.25, 1.0)
PATH_RGBA = (0.15, 0.35, 0.95, 1.0)
INK_RGBA = (0.05, 0.05, 0.35, 1.0)
SUCCESS_RGB = (40, 190, 70)
FAILURE_RGB = (220, 40, 40)
HELLO_WORLD = "hello world"
#: Lines on the writing board are lifted this much (m) so the board does not hide them.
_BOARD_LIFT = 0.003
_ZERO3 = np.zeros(3)
_EYE9 = np.eye(3).ravel()
#: Height step (m) between overlapping lines (demonstration < prediction < path / ink).
_LAYER_STEP = 0.0015


@dataclasses.dataclass(frozen=True)
class VideoStyle:
    """How videos look and cost.

    Attributes:
        width, height: frame size in pixels (even numbers: H.264 needs them).
        fps: frames per simulated second, also the playback rate (real time); 60 / fps should
            be an integer (the control rate is 60 Hz).
        hold_s: seconds the last frame of each rollout is held (with the outcome border).
        shadows: render shadows and reflections (≈ 7× slower with software OpenGL).
        antialias: 4× multisampling (≈ 2× slower with software OpenGL).
        max_segments: most line segments drawn per path (paths are subsampled to it).
        line_px: line width in pixels (default: height / 120).
        caption: draw a caption (run point, outcome) into the frames.
    """

    width: int = 480
    height: int = 360
    fps: float = 20.0
    hold_s: float = 0.75
    shadows: bool = False
    antialias: bool = False
    max_segments: int = 150
    line_px: float | None = None
    caption: bool = True

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


class VideoWriter:
    """Streams frames ``[H, W, 3]`` uint8 into an mp4 (H.264 via imageio-ffmpeg), written to a
    temporary sibling and renamed into place on :meth:`close` (atomic)."""

    def __init__(self, path: str | os.PathLike[str], fps: float):
        import imageio.v2 as iio

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self.path.with_name(f".{self.path.stem}.{uuid.uuid4().hex[:8]}.tmp.mp4")
        self._writer = iio.get_writer(self._tmp, fps=fps, codec="libx264", quality=7,
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


def frame_camera(points: np.ndarray, azimuth: float, elevation: float, fovy: float = 45.0,
                 aspect: float = 4 / 3, margin: float = 1.05):
    """A free camera that keeps ``points`` ``[K, 3]`` (m) in view from ``azimuth`` /
    ``elevation`` (degrees, MuJoCo's convention): looks at the centre of their bounding box
    from the distance at which their bounding sphere fits the smaller field of view."""
    from clfd_bench.sim.render import CameraSpec

    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        raise ValueError("frame_camera needs at least one finite point")
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    center = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 0.05)
    half = math.radians(fovy) / 2
    if aspect < 1:
        half = math.atan(math.tan(half) * aspect)
    distance = margin * radius / math.sin(half)
    return CameraSpec(lookat=tuple(float(c) for c in center), distance=float(distance),
                      azimuth=float(azimuth), elevation=float(elevation))


def _is_writing(base: Any) -> bool:
    return getattr(base, "tool", None) == "pen" and hasattr(base, "wspec")


def _camera_for(base: Any, target: np.ndarray, extra: np.ndarray, aspect: float):
    """The camera of a rollout video. Writing: from the +y side, low (30° down) so the letter
    shows below the hand and reads left to right, looking just above the letter from at least
    0.8 m (the hand and forearm in view). Otherwise: a three-quarter view from in front of
    the robot, beyond the task, framing the robot, the path and the objects."""
    from clfd_bench.sim.render import CameraSpec

    fovy = float(base.model.vis.global_.fovy)
    if _is_writing(base):
        fit = frame_camera(target, -90.0, -30.0, fovy=fovy, aspect=aspect, margin=1.2)
        lookat = (target.min(axis=0) + target.max(axis=0)) / 2 + np.array([0.0, 0.0, 0.1])
        return CameraSpec(lookat=tuple(float(v) for v in lookat),
                          distance=max(0.8, fit.distance), azimuth=-90.0, elevation=-30.0)
    c = np.nanmean(target, axis=0)
    toward = math.degrees(math.atan2(c[1], c[0]))
    return frame_camera(np.concatenate([target, extra]), toward + 180.0 + 40.0, -25.0,
                        fovy=fovy, aspect=aspect)


def _robot_points(base: Any) -> np.ndarray:
    """World positions [K, 3] of the robot's bodies in the current state."""
    import mujoco

    from clfd_bench.sim.robot import ROBOT_BODIES

    ids = [mujoco.mj_name2id(base.model, mujoco.mjtObj.mjOBJ_BODY, n) for n in ROBOT_BODIES]
    return np.array([base.data.xpos[i] for i in ids if i >= 0])


def _object_points(base: Any) -> np.ndarray:
    """World positions [K, 3] of the movable bodies that are not the robot (props)."""
    from clfd_bench.execution.trace import object_bodies

    ids = list(object_bodies(base.model, present_only=True).values())
    return np.array([base.data.xpos[i] for i in ids]).reshape(-1, 3)


def _subsample(points: np.ndarray, max_segments: int) -> np.ndarray:
    stride = max(1, math.ceil((len(points) - 1) / max(1, max_segments)))
    idx = np.arange(0, len(points), stride)
    if idx[-1] != len(points) - 1:
        idx = np.append(idx, len(points) - 1)
    return points[idx]


class OverlayRenderer:
    """Renders a clfd-bench env's scene with paths drawn in (a ``FrameHook`` render function).

    Args:
        model: the env's ``MjModel``.
        style: a :class:`VideoStyle`.
        camera: a ``clfd_bench.sim.render.CameraSpec``.
    """

    def __init__(self, model: Any, style: VideoStyle, camera: Any):
        import mujoco

        from clfd_bench.sim.render import ensure_gl_backend

        ensure_gl_backend()
        self._mj = mujoco
        gl = model.vis.global_
        if style.width > gl.offwidth or style.height > gl.offheight:
            raise ValueError(f"video size {style.width}x{style.height} exceeds the model's "
                             f"offscreen buffer {gl.offwidth}x{gl.offheight}; render smaller")
        self.style = style
        quality = model.vis.quality
        samples = quality.offsamples
        if not style.antialias:  # the GL context takes its multisampling from the model
            quality.offsamples = 0
        try:
            self.renderer = mujoco.Renderer(model, height=style.height, width=style.width,
                                            max_geom=10000)
        finally:
            quality.offsamples = samples
        if not style.shadows:
            flags = self.renderer.scene.flags
            for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION,
                         mujoco.mjtRndFlag.mjRND_SKYBOX):
                flags[flag] = 0
        self.camera = camera.to_mjv() if hasattr(camera, "to_mjv") else camera
        self.line_px = style.line_px or max(2.0, style.height / 120)
        self.static: list[tuple[np.ndarray, tuple[float, ...]]] = []
        self.caption = ""
        self._lifts: list[np.ndarray] = [np.zeros(3)]
        self._stride = 1
        self._seen = 0
        self._path: list[np.ndarray] = []
        self._ink: list[tuple[np.ndarray, np.ndarray]] = []
        self._last_down: tuple[np.ndarray, bool] | None = None

    def start(self, static: Sequence[tuple[np.ndarray, tuple[float, ...]]], expected_steps: int,
              caption: str = "", lift: float = 0.0) -> None:
        """Begins a rollout: lines to draw throughout, the rollout's length (sets the
        subsampling of the live path) and the caption. ``lift`` raises every line (m)."""
        self.static = [(_subsample(np.asarray(p, float), self.style.max_segments), rgba)
                       for p, rgba in static]
        # Lines that overlap (prediction on demonstration, ink on both) are drawn at slightly
        # different heights: equal depths make them flicker into dots.
        self._lifts = [np.array([0.0, 0.0, lift + _LAYER_STEP * k])
                       for k in range(len(static) + 1)]
        self.caption = caption
        self._stride = max(1, math.ceil(expected_steps / (2 * self.style.max_segments)))
        self._seen = 0
        self._path, self._ink = [], []
        self._last_down = None

    def _add_line(self, a: np.ndarray, b: np.ndarray, rgba: np.ndarray, layer: int) -> bool:
        """Adds one line segment a -> b [3] (m) to the scene; False when the scene is full."""
        scene, mj = self.renderer.scene, self._mj
        if scene.ngeom >= scene.maxgeom:
            return False
        geom = scene.geoms[scene.ngeom]
        mj.mjv_initGeom(geom, mj.mjtGeom.mjGEOM_LINE, _ZERO3, _ZERO3, _EYE9, rgba)
        lift = self._lifts[layer]
        mj.mjv_connector(geom, mj.mjtGeom.mjGEOM_LINE, self.line_px, a + lift, b + lift)
        scene.ngeom += 1
        return True

    def _segments(self, pairs, rgba: Sequence[float], layer: int) -> None:
        color = np.asarray(rgba, dtype=np.float32)
        for a, b in pairs:
            if not self._add_line(a, b, color, layer):
                return

    def _consume(self, tracer: Any) -> None:
        """Takes the tool positions recorded since the last frame (subsampled)."""
        positions, flags = tracer.tool_positions, tracer.tool_down_flags
        for k in range(self._seen, len(positions)):
            if k % self._stride and k != len(positions) - 1:
                continue
            p, down = positions[k], flags[k]
            if down is None:
                self._path.append(p)
                continue
            if down and self._last_down is not None and self._last_down[1]:
                self._ink.append((self._last_down[0], p))
            self._last_down = (p, bool(down))
        self._seen = len(positions)

    def __call__(self, base: Any, tracer: Any) -> np.ndarray:
        self._consume(tracer)
        self.renderer.update_scene(base.data, camera=self.camera)
        for layer, (points, rgba) in enumerate(self.static):
            self._segments(zip(points[:-1], points[1:], strict=True), rgba, layer)
        top = len(self.static)
        if self._path:
            self._segments(zip(self._path[:-1], self._path[1:], strict=True), PATH_RGBA, top)
        self._segments(self._ink, INK_RGBA, top)
        frame = self.renderer.render().copy()
        if self.style.caption and self.caption:
            frame = _caption(frame, self.caption)
        return frame

    def close(self) -> None:
        self.renderer.close()


@functools.lru_cache(maxsize=4)
def _font(size: int):
    from PIL import ImageFont

    return ImageFont.load_default(size=size)


def _caption(frame: np.ndarray, text: str | None,
             border: tuple[int, int, int] | None = None) -> np.ndarray:
    """``frame`` with ``text`` (if any) in its top-left corner and an optional coloured
    border."""
    from PIL import Image, ImageDraw

    out = frame.copy()
    if text:
        img = Image.fromarray(frame)
        draw = ImageDraw.Draw(img)
        font = _font(max(10, frame.shape[0] // 24))
        x0, y0, x1, y1 = draw.textbbox((6, 4), text, font=font)
        draw.rectangle((x0 - 3, y0 - 2, x1 + 3, y1 + 2), fill=(0, 0, 0))
        draw.text((6, 4), text, fill=(255, 255, 255), font=font)
        out = np.asarray(img).copy()
    if border is not None:
        w = max(3, frame.shape[0] // 60)
        out[:w], out[-w:], out[:, :w], out[:, -w:] = border, border, border, border
    return out


def render_rollout(env: Any, trajectory: Any, demo: int, sinks: Sequence[Callable], *,
                   demonstration: Any | None = None, caption: str = "",
                   style: VideoStyle | None = None, trace: bool = False,
                   settle_s: float | None = None):
    """Executes ``trajectory`` from demo ``demo``'s start and streams rendered frames, with
    the paths drawn in, to every sink (e.g. ``VideoWriter.append``).

    Args:
        env: a clfd-bench env (no render mode needed; e.g. ``env_pool.get_env(id)``).
        trajectory: what ``clfd_bench.execution.execute.execute`` takes (data units).
        demo: the demo to reset to.
        sinks: callables taking one frame ``[H, W, 3]`` uint8.
        demonstration: the demonstration in the same form, drawn in green (optional).
        caption: text drawn top-left; the outcome is added on the held closing frames.
        style: a :class:`VideoStyle`.
        trace: keep the rollout's step-by-step trace (for rerun logging).
        settle_s: seconds of settling after the trajectory (default: the rollout's).

    Returns:
        ``(ExecResult, frames written per sink)``; the frame count is
        ``style.frames_for(result.steps)``.
    """
    from clfd_bench.execution.execute import execute
    from clfd_bench.execution.trace import FrameHook, tool_path

    style = style or VideoStyle()
    base = env.unwrapped
    target = tool_path(base, trajectory)
    static = [(target, PREDICTION_RGBA)]
    if demonstration is not None:
        static.insert(0, (tool_path(base, demonstration), DEMONSTRATION_RGBA))
    env.reset(options={"demo": int(demo)})
    extra = np.concatenate([_robot_points(base), _object_points(base)]
                           + [s for s, _ in static[:-1]])
    camera = _camera_for(base, target, extra, style.width / style.height)
    overlay = OverlayRenderer(base.model, style, camera)
    last: list[np.ndarray] = []
    count = [0]

    def sink(frame: np.ndarray) -> None:
        last[:] = [frame]
        count[0] += 1
        for s in sinks:
            s(frame)

    try:
        overlay.start(static, expected_steps=len(target) + 60, caption=caption,
                      lift=_BOARD_LIFT if _is_writing(base) else 0.0)
        result = execute(env, trajectory, demo, trace=trace, settle_s=settle_s,
                         frame_hook=FrameHook(overlay, sink, style.every))
        if style.hold_frames and last:
            outcome = "success" if result.success else "failure"
            text = (f"{caption}: {outcome}" if caption else outcome) if style.caption else None
            held = _caption(last[0], text,
                            border=SUCCESS_RGB if result.success else FAILURE_RGB)
            for _ in range(style.hold_frames):
                for s in sinks:
                    s(held)
            count[0] += style.hold_frames
    finally:
        overlay.close()
    return result, count[0]


def text_for_letters(learned: Sequence[str], text: str = HELLO_WORLD) -> str:
    """``text`` restricted to the learned letters (spaces kept, repeated spaces merged): all
    of "hello world" when every letter was learned, e.g. "he" after learning h and e."""
    kept = "".join(c for c in text if c == " " or c in set(learned))
    return " ".join(kept.split())


# ----------------------------------------------------------------------------- run videos
def _resolve_tasks(task: int | str | None, names: Sequence[str]) -> list[int]:
    if task is None or (isinstance(task, str) and task.lower() == "all"):
        return list(range(len(names)))
    if isinstance(task, str) and task.lstrip("-").isdigit():
        task = int(task)
    if isinstance(task, int):
        if not 0 <= task < len(names):
            raise ValueError(f"task index {task} out of range: the run learned tasks 0.."
                             f"{len(names) - 1} ({', '.join(names)})")
        return [task]
    if task in names:
        return [list(names).index(task)]
    raise ValueError(f"the run learned no task {task!r}; valid: an index 0..{len(names) - 1}, "
                     f"a name ({', '.join(names)}) or 'all'")


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


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
            ("hello world", or its learned letters) with ``clfd/HelloWorld-v2``.

    Returns:
        The written files: ``{run}_task{j}_{name}_demo{d}.mp4`` per task, then
        ``{run}_all_tasks_demo{d}.mp4`` and ``{run}_text_demo{d}.mp4`` when made.
    """
    from clfd_bench.envs.registration import env_id_for
    from clfd_bench.execution.env_pool import get_env
    from clfd_bench.execution.saved_run import load_run, load_run_predictions
    from clfd_bench.progress import progress

    style = style or VideoStyle()
    out_dir = Path(out_dir)
    run = load_run(run_dir)
    run_dir, dataset, m = run.path, run.dataset, run.num_learned
    if m == 0:
        raise ValueError(f"{run_dir} has no learned task yet; nothing to render")
    names = run.learned
    selected = _resolve_tasks(task, names)
    preds = load_run_predictions(run_dir, m - 1)
    demos = dict(enumerate(run.demos()))
    n_demos = min(len(preds[j]) for j in selected)
    if not 0 <= demo < n_demos:
        raise ValueError(f"demo {demo} out of range: the run predicted demos 0..{n_demos - 1}")
    run = _safe(run_dir.resolve().name)
    logger = None
    if rerun_path is not None:
        from clfd_bench.viz.rerun_log import RolloutLogger

        logger = RolloutLogger(rerun_path, recording_name=f"video {run_dir.name}")
    written: list[Path] = []
    joint = None
    if all_tasks_video and len(selected) > 1:
        joint = VideoWriter(out_dir / f"{run}_all_tasks_demo{demo}.mp4", style.fps)
    try:
        for j in progress(selected, desc=f"videos {run_dir.name}", unit="task"):
            try:
                env_id = env_id_for(dataset, names[j])
            except KeyError as exc:
                warnings.warn(f"no video of task {j} ({names[j]}): {exc.args[0]}",
                              stacklevel=2)
                continue
            env = get_env(env_id)
            writer = VideoWriter(out_dir / f"{run}_task{j}_{_safe(names[j])}_demo{demo}.mp4",
                                 style.fps)
            sinks = [writer.append] + ([joint.append] if joint is not None else [])
            try:
                result, _ = render_rollout(
                    env, preds[j][demo], demo, sinks, demonstration=demos[j][demo],
                    caption=f"after task {m - 1}: task {j} '{names[j]}', demo {demo}",
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
            path = _render_text(run, out_dir, names, preds, demos, demo, style, logger)
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
    with ``clfd/HelloWorld-v2`` from a HelloWorld run's predictions after its last task.

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
    return _render_text(_safe(run.path.resolve().name), Path(out_dir), run.learned, preds,
                        demos, demo, style or VideoStyle(), None)


def _render_text(run: str, out_dir: Path, names: Sequence[str], preds: dict[int, np.ndarray],
                 demos: dict[int, np.ndarray], demo: int, style: VideoStyle,
                 logger: Any) -> Path | None:
    """Writes the HelloWorld text from the learned letters (``clfd/HelloWorld-v2``)."""
    from clfd_bench.execution.env_pool import get_env

    text = text_for_letters(names)
    if not text:
        return None
    env = get_env("clfd/HelloWorld-v2", text=text)
    base = env.unwrapped
    if not 0 <= demo < base.num_demos:
        return None
    index = {name: j for j, name in enumerate(names)}
    letters = [c for c in text if c != " "]
    trajectory = [preds[index[c]][demo] for c in letters]
    demonstration = [demos[index[c]][demo] for c in letters]
    writer = VideoWriter(out_dir / f"{run}_text_demo{demo}.mp4", style.fps)
    try:
        result, _ = render_rollout(env, trajectory, demo, [writer.append],
                                   demonstration=demonstration,
                                   caption=f"'{text}' from the learned letters, demo {demo}",
                                   style=style, trace=logger is not None)
    except BaseException:
        writer.abort()
        raise
    if logger is not None:
        logger.log_rollout(f"video/text/demo_{demo}", base, result, prediction=trajectory,
                           demonstration=demonstration)
    return writer.close()
