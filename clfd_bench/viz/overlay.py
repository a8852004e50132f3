"""Rendering a rollout's frames with the paths drawn into the scene."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from clfd_bench.viz.captions import _caption
from clfd_bench.viz.style import INK_RGBA, PATH_RGBA, VideoStyle

__all__ = ["OverlayRenderer"]

#: Lines on the writing board are lifted this much (m) so the board does not hide them.
_BOARD_LIFT = 0.003
_ZERO3 = np.zeros(3)
_EYE9 = np.eye(3).ravel()
#: Height step (m) between overlapping lines (demonstration < prediction < path / ink).
_LAYER_STEP = 0.0015
#: Opacity of the bodies drawn see-through (the writing hand over its letter).
SEE_THROUGH_ALPHA = 0.12


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
        see_through: ids of bodies drawn at :data:`SEE_THROUGH_ALPHA` opacity, so that what
            they hide shows through them (a camera that frames the letter looks past the
            hand writing it).
    """

    def __init__(self, model: Any, style: VideoStyle, camera: Any,
                 see_through: Sequence[int] = ()):
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
        self._geom_body = np.asarray(model.geom_bodyid)
        self._see_through = np.zeros(model.nbody, dtype=bool)
        self._see_through[list(see_through)] = True
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
        if self._see_through.any():
            self._fade()
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

    def _fade(self) -> None:
        """Makes the scene's geoms of the see-through bodies translucent."""
        scene, geom_type = self.renderer.scene, self._mj.mjtObj.mjOBJ_GEOM
        for k in range(scene.ngeom):
            geom = scene.geoms[k]
            if geom.objtype == geom_type and self._see_through[self._geom_body[geom.objid]]:
                geom.rgba[3] = min(float(geom.rgba[3]), SEE_THROUGH_ALPHA)

    def close(self) -> None:
        self.renderer.close()
