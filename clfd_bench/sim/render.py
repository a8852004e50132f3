"""Offscreen rendering of a MuJoCo scene (EGL when `MUJOCO_GL=egl`), and video writing."""

from __future__ import annotations

import dataclasses
import os
import pathlib
from collections.abc import Callable

import mujoco
import numpy as np


@dataclasses.dataclass(frozen=True)
class CameraSpec:
    """A free camera looking at `lookat` [3] m from `distance` m, `azimuth`/`elevation` degrees."""

    lookat: tuple[float, float, float] = (0.35, 0.0, 0.25)
    distance: float = 1.5
    azimuth: float = 150.0
    elevation: float = -25.0

    def to_mjv(self) -> mujoco.MjvCamera:
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.lookat
        cam.distance = self.distance
        cam.azimuth = self.azimuth
        cam.elevation = self.elevation
        return cam


def ensure_gl_backend() -> None:
    """Defaults `MUJOCO_GL` to "egl" (headless) when no backend is chosen and there is no display.
    Must run before the first renderer is created."""
    if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
        os.environ["MUJOCO_GL"] = "egl"


class OffscreenRenderer:
    """Renders RGB frames [H, W, 3] uint8 of `model`/`data` from a `CameraSpec` or a named
    camera of the model.

    Args:
        fast: turn shadows and reflections off (software EGL renders ~4x faster).
    """

    def __init__(self, model: mujoco.MjModel, width: int = 640, height: int = 480,
                 camera: CameraSpec | str | None = None, fast: bool = True):
        ensure_gl_backend()
        if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
            raise ValueError(
                f"render size {width}x{height} exceeds the model's offscreen buffer "
                f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}; raise "
                "visual/global offwidth/offheight in the MJCF or render smaller")
        self._renderer = mujoco.Renderer(model, height=height, width=width)
        camera = camera if camera is not None else CameraSpec()
        self._camera = camera.to_mjv() if isinstance(camera, CameraSpec) else camera
        if fast:
            self._renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
            self._renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False

    def render(self, data: mujoco.MjData,
               decorate: Callable[[mujoco.MjvScene], None] | None = None) -> np.ndarray:
        """One frame [H, W, 3] uint8 of the current state; `decorate(scene)` may add geoms
        (e.g. with `add_segments`) before drawing."""
        self._renderer.update_scene(data, camera=self._camera)
        if decorate is not None:
            decorate(self._renderer.scene)
        return self._renderer.render().copy()

    def close(self) -> None:
        self._renderer.close()


def add_segments(scene: mujoco.MjvScene, points: np.ndarray, width: float = 0.0015,
                 rgba: tuple[float, float, float, float] = (0.05, 0.05, 0.3, 1.0),
                 max_segments: int = 1500) -> None:
    """Adds a polyline through `points` [K, 3] (m) to `scene` as capsules, subsampled to at
    most `max_segments` and to the scene's free geom slots."""
    points = np.asarray(points, dtype=float)
    if len(points) < 2:
        return
    free = scene.maxgeom - scene.ngeom
    n = min(len(points) - 1, max_segments, free)
    if n < 1:
        return
    idx = np.linspace(0, len(points) - 1, n + 1).round().astype(int)
    rgba_arr = np.array(rgba, dtype=np.float32)
    for a, b in zip(idx[:-1], idx[1:], strict=True):
        geom = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3),
                            np.eye(3).ravel(), rgba_arr)
        mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, width, points[a], points[b])
        scene.ngeom += 1


def write_video(frames: list[np.ndarray], path: str | os.PathLike, fps: float = 30.0) -> None:
    """Writes frames ([H, W, 3] uint8 each) to a video file (mp4 via imageio-ffmpeg, or gif),
    atomically (temp file + rename)."""
    import imageio.v3 as iio

    if not frames:
        raise ValueError("no frames to write; render with record=True first")
    path = pathlib.Path(path)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    iio.imwrite(tmp, np.stack(frames), fps=fps)
    os.replace(tmp, path)
