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
green (success) or red (failure) border (:func:`outcome_caption`). The camera frames the robot
and the props wherever the rollout takes them (found by a first rollout without rendering) at
the frame's aspect (:func:`frame_camera`). :func:`render_comparison_video` puts several runs'
rollouts of one task side by side, each tile rendered at its own size.

Rendering cost, measured on a 2-core VM with software EGL (Mesa, no GPU) on HelloWorld 'h'
(1060 steps, 369 frames at 20 fps), shadows and reflections off: 1280×720 (the default)
renders ~17 frames/s including the simulation and encodes ~51/s, ~13/s end to end (≈ 30 s
for one letter); 480×360 renders ~30/s and encodes ~200/s (≈ 13 s). Shadows and reflections
cost 4-6×, 4× multisampling ~1.2× at 1280×720. Frames are streamed to the encoder, never all
held in memory.
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
        shadows: render shadows and reflections (4-6× slower with software OpenGL).
        antialias: 4× multisampling (~1.2× slower with software OpenGL at 1280×720).
        max_segments: most line segments drawn per path (paths are subsampled to it).
        line_px: line width in pixels (default: height / 120).
        caption: draw a caption (run point, outcome) into the frames.
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


def frame_camera(points: np.ndarray, azimuth: float, elevation: float, fovy: float = 45.0,
                 aspect: float = 16 / 9, margin: float = 1.08):
    """A free camera that keeps ``points`` ``[K, 3]`` (m) in view from ``azimuth`` /
    ``elevation`` (degrees, MuJoCo's convention): looks at the centre of their bounding box
    from the nearest distance at which every point projects inside both the vertical field of
    view (``fovy``) and the horizontal one (``aspect`` = width / height), times ``margin``.
    So a wide frame (16:9) is filled sideways instead of fitting the points' bounding sphere
    into its smaller, vertical field of view."""
    from clfd_bench.sim.render import CameraSpec

    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        raise ValueError("frame_camera needs at least one finite point")
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    center = (lo + hi) / 2
    az, el = math.radians(azimuth), math.radians(elevation)
    forward = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= max(float(np.linalg.norm(right)), 1e-9)
    up = np.cross(right, forward)
    rel = pts - center  # (K, 3)
    depth, x, y = rel @ forward, np.abs(rel @ right), np.abs(rel @ up)  # (K,) each
    tan_y = math.tan(math.radians(fovy) / 2)
    tan_x = tan_y * aspect
    # A point at depth z (along the view) is inside the frame from distance d when
    # |x| <= (d + z) tan_x and |y| <= (d + z) tan_y.
    need = np.maximum(x / tan_x, y / tan_y) - depth
    distance = margin * max(float(need.max()), 0.05 / tan_y)
    return CameraSpec(lookat=tuple(float(c) for c in center), distance=float(distance),
                      azimuth=float(azimuth), elevation=float(elevation))


def _is_writing(base: Any) -> bool:
    return getattr(base, "tool", None) == "pen" and hasattr(base, "wspec")


def _camera_for(base: Any, target: np.ndarray, extra: np.ndarray, aspect: float):
    """The camera of a rollout video. Writing: from the +y side, low (30° down) so the letter
    shows below the hand and reads left to right, looking just above the letter from at least
    0.8 m (the hand and forearm in view). Otherwise: a three-quarter view from in front of
    the robot, beyond the task, framing ``target`` (the tool's path) and ``extra`` (the robot
    and the props wherever they go during the rollout, :func:`_motion_points`) in the frame's
    aspect (:func:`frame_camera`)."""
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


#: Radius (m) around the robot's body origins and the props' that a frame keeps in view (the
#: links and props have size; a body origin is one point of them).
_ROBOT_REACH = 0.1
_PROP_REACH = 0.05


def _inflate(points: np.ndarray, radius: float) -> np.ndarray:
    """``points`` [K, 3] and the corners of a cube of half-side ``radius`` around each
    [9K, 3]."""
    corners = np.array([[0, 0, 0]] + [[x, y, z] for x in (-1, 1) for y in (-1, 1)
                                      for z in (-1, 1)], dtype=float) * radius  # (9, 3)
    return (np.asarray(points, float).reshape(-1, 1, 3) + corners).reshape(-1, 3)


def _motion_points(env: Any, trajectory: Any, demo: int, settle_s: float | None,
                   every: int) -> np.ndarray:
    """Where the robot and the props go when ``trajectory`` is executed [K, 3] (m): a first
    rollout without rendering (the same steps as the rendered one; simulation costs little
    next to rendering) that records the robot's body origins and the props' every ``every``
    steps, inflated by their reach."""
    from clfd_bench.execution.execute import execute
    from clfd_bench.execution.trace import FrameHook

    robot: list[np.ndarray] = []
    props: list[np.ndarray] = []

    def look(base: Any, tracer: Any) -> np.ndarray:
        robot.append(_robot_points(base))
        props.append(_object_points(base))
        return _NO_FRAME

    execute(env, trajectory, demo, settle_s=settle_s,
            frame_hook=FrameHook(look, lambda frame: None, every))
    return np.concatenate([_inflate(np.concatenate(robot), _ROBOT_REACH),
                           _inflate(np.concatenate(props), _PROP_REACH)])


_NO_FRAME = np.zeros((1, 1, 3), dtype=np.uint8)


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


def _wrap(draw: Any, line: str, font: Any, width: int) -> list[str]:
    """``line`` broken at spaces (a word longer than ``width`` at a character) into lines of
    at most ``width`` pixels in ``font``: nothing is cut off."""
    out: list[str] = []
    current = ""
    for word in line.split(" "):
        trial = f"{current} {word}" if current else word
        if draw.textlength(trial, font=font) <= width:
            current = trial
            continue
        if current:
            out.append(current)
        current = word
        while draw.textlength(current, font=font) > width and len(current) > 1:
            cut = len(current) - 1
            while cut > 1 and draw.textlength(current[:cut], font=font) > width:
                cut -= 1
            out.append(current[:cut])
            current = current[cut:]
    out.append(current)
    return out


def _caption(frame: np.ndarray, text: str | None,
             border: tuple[int, int, int] | None = None) -> np.ndarray:
    """``frame`` with ``text`` (if any; one line per ``\\n``, each wrapped at the frame's
    width, never cut) in its top-left corner on a dark veil, and an optional coloured
    border."""
    from PIL import Image, ImageDraw

    out = frame.copy()
    if text:
        img = Image.fromarray(frame)
        draw = ImageDraw.Draw(img)
        font = _font(max(10, frame.shape[0] // 24))
        pad = max(3, frame.shape[0] // 60) + 3  # clear of the border
        lines = [part for line in text.split("\n")
                 for part in _wrap(draw, line, font, frame.shape[1] - 2 * pad - 6)]
        fitted = "\n".join(lines)
        x0, y0, x1, y1 = draw.multiline_textbbox((pad, pad), fitted, font=font)
        # a dark veil, not an opaque box: a long reason wrapped over a small tile leaves the
        # scene visible under it
        box = np.s_[max(0, y0 - 2):y1 + 3, max(0, x0 - 3):x1 + 4]
        veiled = out.copy()
        veiled[box] = (veiled[box].astype(np.float32) * 0.35).astype(np.uint8)
        img = Image.fromarray(veiled)
        ImageDraw.Draw(img).multiline_text((pad, pad), fitted, fill=(255, 255, 255), font=font)
        out = np.asarray(img).copy()
    if border is not None:
        w = max(3, frame.shape[0] // 60)
        out[:w], out[-w:], out[:, :w], out[:, -w:] = border, border, border, border
    return out


def method_label(method: str) -> str:
    """How a video names a run's method (its ``config.method``): the registry name upper-cased
    ("hn" -> "HN"); a plugin named by an import spec (``pkg.mod:MyMethod``) by its class."""
    return method.rsplit(":", 1)[-1] if ":" in method else method.upper()


def outcome_text(result: Any) -> tuple[str, str]:
    """``(short, reason)`` of an :class:`~clfd_bench.execution.execute.ExecResult`:
    ``("success", "")``, or ``("failed (<kind>)", <the env's reason>)`` with the kind of
    :data:`~clfd_bench.execution.execute.FAILURE_KINDS` (reflex, tracking, task, ...)."""
    if result.success:
        return "success", ""
    return f"failed ({result.failure_kind or 'unknown'})", str(result.failure_reason or "")


def outcome_caption(caption: str, result: Any) -> tuple[str, tuple[int, int, int]]:
    """The text and border colour of a rollout's held closing frames: ``caption · success``
    (green), or ``caption · failed (<kind>)`` and on a second line the env's reason (red)."""
    short, reason = outcome_text(result)
    text = f"{caption} · {short}" if caption else short
    if reason:
        text += f"\n{reason}"
    return text, SUCCESS_RGB if result.success else FAILURE_RGB


def render_rollout(env: Any, trajectory: Any, demo: int, sinks: Sequence[Callable], *,
                   demonstration: Any | None = None, caption: str = "",
                   style: VideoStyle | None = None, trace: bool = False,
                   settle_s: float | None = None, camera: Any | None = None):
    """Executes ``trajectory`` from demo ``demo``'s start and streams rendered frames, with
    the paths drawn in, to every sink (e.g. ``VideoWriter.append``).

    Args:
        env: a clfd-bench env (no render mode needed; e.g. ``env_pool.get_env(id)``).
        trajectory: what ``clfd_bench.execution.execute.execute`` takes (data units).
        demo: the demo to reset to.
        sinks: callables taking one frame ``[H, W, 3]`` uint8.
        demonstration: the demonstration in the same form, drawn in green (optional).
        caption: text drawn top-left; the outcome is added on the held closing frames
            (:func:`outcome_caption`).
        style: a :class:`VideoStyle`.
        trace: keep the rollout's step-by-step trace (for rerun logging).
        settle_s: seconds of settling after the trajectory (default: the rollout's).
        camera: a ``CameraSpec`` (default: one framing the tool's path, the robot and the
            props wherever this rollout takes them, found by a first rollout without
            rendering).

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
    if camera is None:  # the writing camera frames the letters only
        moving = ([] if _is_writing(base)
                  else [_motion_points(env, trajectory, demo, settle_s, style.every)])
        extra = np.concatenate([np.zeros((0, 3)), *moving, *(s for s, _ in static[:-1])])
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
            text, border = outcome_caption(caption, result)
            held = _caption(last[0], text if style.caption else None, border=border)
            for _ in range(style.hold_frames):
                for s in sinks:
                    s(held)
            count[0] += style.hold_frames
    finally:
        overlay.close()
    return result, count[0]


def closing_frame(env: Any, trajectory: Any, demo: int, *, demonstration: Any | None = None,
                  style: VideoStyle | None = None, settle_s: float | None = None):
    """Executes ``trajectory`` from demo ``demo``'s start to its horizon and renders only its
    closing frame: the final state, with the demonstration (green), the prediction (orange)
    and the tool's whole path (blue; writing: the ink) drawn in, from the camera a video of
    the rollout would use (framing the path, the robot and the props wherever they went).

    Args:
        env: a clfd-bench env (no render mode needed; e.g. ``env_pool.get_env(id)``).
        trajectory: what ``clfd_bench.execution.execute.execute`` takes (data units).
        demo: the demo to reset to.
        demonstration: the demonstration in the same form (optional).
        style: size and look (its caption and hold settings are not used).
        settle_s: seconds of settling after the trajectory (default: the rollout's).

    Returns:
        ``(ExecResult with its trace, frame [H, W, 3] uint8)``.
    """
    import types

    from clfd_bench.execution.execute import execute
    from clfd_bench.execution.trace import tool_path

    style = style or VideoStyle()
    base = env.unwrapped
    result = execute(env, trajectory, demo, trace=True, settle_s=settle_s)
    tr = result.trace
    target = tool_path(base, trajectory)
    static = [(target, PREDICTION_RGBA)]
    if demonstration is not None:
        static.insert(0, (tool_path(base, demonstration), DEMONSTRATION_RGBA))
    moving = [] if _is_writing(base) else [
        _inflate(tr.hand_pos[::style.every], _ROBOT_REACH), _inflate(_robot_points(base),
                                                                     _ROBOT_REACH),
        *(_inflate(pose[::style.every, :3], _PROP_REACH) for pose in tr.objects.values())]
    extra = np.concatenate([np.zeros((0, 3)), *moving, *(p for p, _ in static[:-1])])
    camera = _camera_for(base, target, extra, style.width / style.height)
    overlay = OverlayRenderer(base.model, dataclasses.replace(style, caption=False), camera)
    try:
        overlay.start(static, expected_steps=len(tr.time),
                      lift=_BOARD_LIFT if _is_writing(base) else 0.0)
        flags = [None] * len(tr.time) if tr.tool_down is None else [bool(f) for f in
                                                                    tr.tool_down]
        recorded = types.SimpleNamespace(tool_positions=list(tr.tool_pos),
                                         tool_down_flags=flags)
        frame = overlay(base, recorded)
    finally:
        overlay.close()
    return result, frame


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


def run_caption(run: Any, what: str, demo: int) -> str:
    """``HN · task 3 'l' · demo 0``: the run's method (its config), what is executed, the
    demo; ``· after task i`` when the run has not learned all its tasks yet."""
    parts = [_run_label(run), what, f"demo {demo}"]
    if not run.complete:
        parts.append(f"after task {run.num_learned - 1} of {len(run.task_names)}")
    return " · ".join(parts)


def _run_label(run: Any) -> str:
    """A run in a caption: its method (:func:`method_label`), or its folder's name when the
    run records none."""
    return method_label(run.method) if run.method else run.path.name


def _video_stem(run: Any) -> str:
    """A run's videos' file-name stem: its directory's name, prefixed by its method when the
    name does not start with it, so the runs of a leaderboard (one name per method folder)
    do not overwrite each other's videos in one folder."""
    name = _safe(run.path.resolve().name)
    method = _safe(run.method.rsplit(":", 1)[-1]) if run.method else ""
    return name if not method or name.startswith(method) else f"{method}_{name}"


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


# ----------------------------------------------------------------------------- comparison
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
