"""Where a video's camera looks from: free cameras built from the scene's geometry, framing
what a rollout is judged by.

* Writing (HelloWorld, LASA on the board): the letter. The camera looks down at the board from
  the +y side (the letters read left to right) at :data:`WRITING_VIEW`, close enough that the
  prediction and the demonstration fill 1 / :data:`WRITING_MARGIN` of the frame; the robot is
  drawn see-through (:func:`see_through_bodies`) so the hand does not hide the ink under it.
* RoboTasks: the props. A view from beyond the task, across its longest extent, frames the
  tool's path, the hand and the props' boxes wherever the rollout takes them
  (:func:`_motion_points`, a first rollout without rendering); the arm is left to enter the
  frame from its edge.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["WRITING_MARGIN", "WRITING_VIEW", "frame_camera", "see_through_bodies"]


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


#: The writing camera's (azimuth, elevation), degrees: from the +y side, so the HelloWorld
#: letters (written towards -x) read left to right; 50° down, steep enough that a letter is
#: little foreshortened, not so steep that the camera sits in the hand above the pen.
WRITING_VIEW = (-90.0, -50.0)
#: The letter spans 1 / this of the frame's width or height (whichever it fills first).
WRITING_MARGIN = 1.15
#: RoboTasks: the view's elevation (degrees; its azimuth: :func:`_side_azimuth`).
_PROPS_ELEVATION = -35.0
#: Radius (m) kept in view around the hand's and fingers' origins (the hand is ~0.2 m wide).
_HAND_REACH = 0.1
#: Radius (m) kept in view around a prop's origin where its geoms' boxes are not at hand (the
#: closing frame's trace records props' origins only).
_PROP_REACH = 0.05
_HAND_BODIES = ("hand", "left_finger", "right_finger")
#: The eight corners of a unit box (the sign pattern), [8, 3].
_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)


def _is_writing(base: Any) -> bool:
    return getattr(base, "tool", None) == "pen" and hasattr(base, "wspec")


def see_through_bodies(base: Any) -> list[int]:
    """Ids of the bodies a video draws see-through: in a writing env, the robot's (links,
    hand, fingers; not the pen), which would hide the part of the letter beyond the pen from
    a camera that frames the letter; none otherwise."""
    from clfd_bench.sim.robot import ROBOT_BODIES

    return _body_ids(base, ROBOT_BODIES) if _is_writing(base) else []


def _camera_for(base: Any, target: np.ndarray, extra: np.ndarray, aspect: float):
    """The camera of a rollout video (the module's docstring says what each frames).

    Args:
        base: the unwrapped env.
        target: the tool's path [K, 3] (m).
        extra: more points to keep in view [K', 3]: writing, the demonstration's path;
            otherwise also the hand and the props wherever they go (:func:`_motion_points`).
        aspect: the frame's width / height.
    """
    fovy = float(base.model.vis.global_.fovy)
    if _is_writing(base):
        # The letter on the board: the prediction and the demonstration (both on the
        # surface; the text's pen lifts between letters are a few mm).
        return frame_camera(np.concatenate([target, extra]), *WRITING_VIEW, fovy=fovy,
                            aspect=aspect, margin=WRITING_MARGIN)
    points = np.concatenate([target, extra])
    return frame_camera(points, _side_azimuth(points), _PROPS_ELEVATION, fovy=fovy,
                        aspect=aspect)


def _side_azimuth(points: np.ndarray) -> float:
    """The azimuth (degrees) of a view across the points' longest horizontal extent (their
    principal axis in the floor's plane, so that it runs along the frame's width), from the
    side away from the robot's base at the origin (so the arm is behind what it handles,
    not in front of it)."""
    xy = np.asarray(points, float)[:, :2]
    xy = xy[np.isfinite(xy).all(axis=1)]
    centre = xy.mean(axis=0)
    spread = np.cov((xy - centre).T) if len(xy) > 1 else np.eye(2)
    axis = np.linalg.eigh(spread)[1][:, -1]  # the principal axis (largest eigenvalue)
    forward = np.array([-axis[1], axis[0]])  # across it
    if forward @ -centre < 0:  # look towards the base, from beyond the task
        forward = -forward
    return math.degrees(math.atan2(forward[1], forward[0]))


def _inflate(points: np.ndarray, radius: float) -> np.ndarray:
    """``points`` [K, 3] and the corners of a cube of half-side ``radius`` around each
    [9K, 3]."""
    corners = np.vstack([np.zeros((1, 3)), _CORNERS]) * radius  # (9, 3)
    return (np.asarray(points, float).reshape(-1, 1, 3) + corners).reshape(-1, 3)


def _motion_points(env: Any, trajectory: Any, demo: int, settle_s: float | None,
                   every: int) -> np.ndarray:
    """Where the hand and the props go when ``trajectory`` is executed [K, 3] (m): a first
    rollout without rendering (the same steps as the rendered one; simulation costs little
    next to rendering) that records, every ``every`` steps, the hand's and fingers' origins
    (inflated by :data:`_HAND_REACH`) and the corners of the props' geoms' boxes
    (:func:`_prop_box_points`)."""
    from clfd_bench.execution.execute import execute
    from clfd_bench.execution.trace import FrameHook

    hand: list[np.ndarray] = []
    props: list[np.ndarray] = [np.zeros((0, 3))]

    def look(base: Any, tracer: Any) -> np.ndarray:
        hand.append(_hand_points(base))
        props.append(_prop_box_points(base))
        return _NO_FRAME

    execute(env, trajectory, demo, settle_s=settle_s,
            frame_hook=FrameHook(look, lambda frame: None, every))
    return np.concatenate([_inflate(np.concatenate(hand), _HAND_REACH), *props])


_NO_FRAME = np.zeros((1, 1, 3), dtype=np.uint8)


def _body_ids(base: Any, names: tuple[str, ...]) -> list[int]:
    import mujoco

    ids = [mujoco.mj_name2id(base.model, mujoco.mjtObj.mjOBJ_BODY, n) for n in names]
    return [i for i in ids if i >= 0]


def _hand_points(base: Any) -> np.ndarray:
    """World positions [K, 3] of the hand's and the fingers' origins in the current state."""
    return np.array([base.data.xpos[i] for i in _body_ids(base, _HAND_BODIES)]).reshape(-1, 3)


def _object_points(base: Any) -> np.ndarray:
    """World positions [K, 3] of the movable bodies that are not the robot (props)."""
    from clfd_bench.execution.trace import object_bodies

    ids = list(object_bodies(base.model, present_only=True).values())
    return np.array([base.data.xpos[i] for i in ids]).reshape(-1, 3)


def _prop_box_points(base: Any) -> np.ndarray:
    """The corners [8G, 3] (m, world) of the bounding boxes of the props' G visible geoms in
    the current state (each geom's box from the model, ``geom_aabb``, posed by the geom's
    position and orientation): a prop is framed whole, not by its origin."""
    from clfd_bench.execution.trace import object_bodies

    model, data = base.model, base.data
    bodies = np.zeros(model.nbody, dtype=bool)
    bodies[list(object_bodies(model, present_only=True).values())] = True
    geoms = np.flatnonzero(bodies[model.geom_bodyid] & (model.geom_rgba[:, 3] > 0))
    if len(geoms) == 0:
        return np.zeros((0, 3))
    aabb = model.geom_aabb[geoms]  # (G, 6): centre, half-sizes in the geom's frame
    local = aabb[:, None, :3] + _CORNERS[None] * aabb[:, None, 3:]  # (G, 8, 3)
    rot = data.geom_xmat[geoms].reshape(-1, 3, 3)  # (G, 3, 3)
    world = np.einsum("gij,gkj->gki", rot, local) + data.geom_xpos[geoms][:, None, :]
    return world.reshape(-1, 3)
