"""`WritingBase`: the machinery every writing env shares (the pen, the board, the ink), and the
framing camera."""

from __future__ import annotations

import math
import pathlib
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces

from clfd_bench.data.resample import min_jerk_profile
from clfd_bench.envs.base import PandaEnv
from clfd_bench.envs.writing.judge import ink_strokes
from clfd_bench.envs.writing.spec import (
    CAMERA_ELEVATION,
    PHYSICS_DT,
    SETTLE_STEPS,
    load_writing_spec,
)
from clfd_bench.resources import resource_path
from clfd_bench.sim.limits import MotionLimits
from clfd_bench.sim.render import CameraSpec, add_segments
from clfd_bench.sim.robot import (
    HOME_QPOS,
    PEN_SLIDE_JOINT,
    PEN_TIP_OFFSET,
    PEN_TIP_SITE,
    robot_model,
)
from clfd_bench.sim.start_configs import solve_configuration


def min_jerk(n: int) -> np.ndarray:
    """[n] the minimum-jerk profile 10s^3 - 15s^4 + 6s^5 at s = 1/n, 2/n, ..., 1 (the first
    sample already moves; the last is at 1)."""
    return min_jerk_profile(np.arange(1, int(n) + 1) / int(n))


def framing_camera(points: np.ndarray, azimuth: float, surface_height: float,
                   fovy: float = 45.0) -> CameraSpec:
    """A camera looking at the centre of the bounding box of `points` [K, 2] (board, m) from
    `azimuth` and `CAMERA_ELEVATION`, at the distance where the box's bounding circle just fits
    the vertical field of view `fovy` (degrees): the shape spans ~40-60 % of the frame."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 0.03)
    distance = radius / math.sin(math.radians(fovy) / 2)
    return CameraSpec(lookat=(float(centre[0]), float(centre[1]), float(surface_height)),
                      distance=float(distance), azimuth=azimuth, elevation=CAMERA_ELEVATION)


class WritingBase(PandaEnv):
    """Shared machinery of the writing envs (pen, board, ink)."""

    tool = "pen"
    dataset = ""

    def __init__(self, render_mode: str | None = None, *, physics_dt: float = PHYSICS_DT,
                 ik_iterations: int = 1, width: int = 640, height: int = 480,
                 limits: str | MotionLimits | None = "panda"):
        self.wspec = load_writing_spec()
        self._low, self._high = self.wspec.low, self.wspec.high  # board bounds [2], m
        self._start_cache: dict[int, np.ndarray] = {}
        self._ink_xy: list[np.ndarray] = []
        self._ink_flags: list[bool] = []
        self._ink_count = 0
        self._commanded_down: list[bool] = []
        self._decision: dict[str, Any] | None = None
        super().__init__(render_mode, physics_dt=physics_dt, ik_iterations=ik_iterations,
                         width=width, height=height, limits=limits)

    # -- scene
    def _task_xml(self) -> pathlib.Path:
        return resource_path("tasks", self.wspec.xml)

    def _bind(self) -> None:
        m = self.model
        self._tip_site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, PEN_TIP_SITE)
        slide = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, PEN_SLIDE_JOINT)
        self._slide_qpos = m.jnt_qposadr[slide]
        self._hand_quat = np.array(self.wspec.hand_quat, dtype=float)
        self._hand_quat /= np.linalg.norm(self._hand_quat)
        self._pen_z = self.wspec.surface_height + PEN_TIP_OFFSET - self.wspec.press_depth

    #: Camera azimuth: looking along -y (from the +y side), the writing direction of the
    #: HelloWorld data (-x) reads left to right and the page's "up" (-y) is up in the image.
    camera_azimuth = 270.0

    def _framed_points(self) -> np.ndarray:
        """[K, 2] board points (m) the camera frames."""
        raise NotImplementedError

    def camera(self) -> CameraSpec:
        """Frames the task's demos on the board (`framing_camera`)."""
        return framing_camera(self._framed_points(), self.camera_azimuth,
                              self.wspec.surface_height)

    def _decorate(self, scene: mujoco.MjvScene) -> None:
        if not self._ink_xy:
            return
        xy = np.array(self._ink_xy)
        z = self.wspec.surface_height + 0.0005
        for a, b in ink_strokes(np.array(self._ink_flags)):
            if b - a >= 2:
                add_segments(scene, np.hstack([xy[a:b], np.full((b - a, 1), z)]),
                             max_segments=max(1, (b - a) // 2))

    # -- geometry helpers
    def hand_target(self, xy: np.ndarray, lift: float = 0.0) -> np.ndarray:
        """Hand position [3] that puts the pen tip at surface point `xy` [2] (pressed by
        `press_depth`), raised by `lift` × `lift_height`."""
        return np.array([xy[0], xy[1], self._pen_z + lift * self.wspec.lift_height])

    def _solve_start(self, xy: np.ndarray) -> np.ndarray:
        q, pos_err, _ = solve_configuration(robot_model(self.tool), self.hand_target(xy),
                                            self._hand_quat, initial_q=HOME_QPOS)
        if pos_err > 1e-3:
            raise ValueError(f"start point {xy.tolist()} is not reachable with the pen down "
                             f"(IK error {pos_err:.4f} m); check tasks/writing.toml placement")
        return q

    def _start_point(self, demo: int) -> np.ndarray:
        raise NotImplementedError

    def _start_qpos(self, demo: int) -> np.ndarray:
        if demo not in self._start_cache:
            self._start_cache[demo] = self._solve_start(self._start_point(demo))
        return self._start_cache[demo]

    def _reset_task(self, demo: int) -> None:
        # Spring pre-compressed so the tip rests exactly on the surface.
        self.data.qpos[self._slide_qpos] = -self.wspec.press_depth
        self._ink_xy, self._ink_flags, self._commanded_down = [], [], []
        self._ink_count = 0
        self._decision = None

    def _default_horizon(self, demo: int) -> int:
        return self._trajectory_steps(demo) + SETTLE_STEPS

    def _trajectory_steps(self, demo: int) -> int:
        raise NotImplementedError

    # -- ink
    def _pen_tip(self) -> np.ndarray:
        return self.data.site_xpos[self._tip_site]

    def _inking(self) -> bool:
        x, y, z = self._pen_tip().tolist()
        w = self.wspec
        return bool(z <= w.surface_height + w.ink_height
                    and w.x_range[0] <= x <= w.x_range[1]
                    and w.y_range[0] <= y <= w.y_range[1])

    def _after_step(self) -> None:
        inked = self._inking()
        self._ink_count += inked
        self._ink_flags.append(inked)
        self._ink_xy.append(self._pen_tip()[:2].copy())
        self._decision = None

    def ink_trace(self) -> np.ndarray:
        """The ink so far: pen tip points [K, 2] (surface, m) of the steps the pen was down."""
        if not self._ink_xy:
            return np.zeros((0, 2))
        flags = np.array(self._ink_flags)
        return np.array(self._ink_xy)[flags]

    def pen_path(self) -> np.ndarray:
        """Pen tip points [N, 2] (surface, m) after every step so far, pen down or up."""
        return np.array(self._ink_xy) if self._ink_xy else np.zeros((0, 2))

    def _task_observation_space(self) -> dict[str, spaces.Space]:
        return {"pen_tip": spaces.Box(-np.inf, np.inf, (3,), np.float64),
                "pen_down": spaces.Box(0.0, 1.0, (1,), np.float64)}

    def _task_obs(self) -> dict[str, np.ndarray]:
        down = self._ink_flags[-1] if self._ink_flags else self._inking()
        return {"pen_tip": self._pen_tip().copy(), "pen_down": np.array([float(down)])}

    def _ink_fraction(self) -> float:
        return self._ink_count / len(self._ink_flags) if self._ink_flags else 0.0

    def _is_success(self, final: bool) -> bool:
        if not final:
            return False
        if self._decision is None:
            self._decision = self._decide()
        return bool(self._decision["is_success"])

    def _decide(self) -> dict[str, Any]:
        raise NotImplementedError

    def _task_info(self) -> dict[str, Any]:
        info: dict[str, Any] = {"ink_fraction": self._ink_fraction()}
        if self._decision is not None:
            info.update({k: v for k, v in self._decision.items() if k != "is_success"})
        return info

    def _task_state(self) -> dict[str, Any]:
        return {"ink_xy": [p.copy() for p in self._ink_xy], "ink_flags": list(self._ink_flags),
                "commanded_down": list(self._commanded_down),
                "start_cache": dict(self._start_cache),
                "decision": self._decision}

    def _restore_task_state(self, state: dict[str, Any]) -> None:
        self._ink_xy = state["ink_xy"]
        self._ink_flags = state["ink_flags"]
        self._ink_count = int(sum(self._ink_flags))
        self._commanded_down = state["commanded_down"]
        self._start_cache = state["start_cache"]
        self._decision = state["decision"]
