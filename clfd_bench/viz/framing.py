"""Where a video's camera looks from: free cameras built from the scene's geometry."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["frame_camera"]


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
