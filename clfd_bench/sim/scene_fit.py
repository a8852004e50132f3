"""Geometry the RoboTasks scenes are derived from: where the demonstrations say things are.

- `grasp_points`: the fingertips' grasp point along each demo ([N, T, 3]); the demos record
  the `hand` frame, props are held 0.1034 m further along its z axis.
- `fit_hinge`: one hinge axis for all openbox demos, fitted to the arcs their grasp points
  trace (each demo on its own circle about the common axis: its own radius and axial offset,
  which the lid's sliding handle absorbs).
- `hinge_angles`: the lid angle each grasp point implies.
- `prop_pose` / `lowest_point`: where a held prop is for a hand pose and how low it reaches,
  for placing shelves, platforms and containers just under where the demos end.

Quaternions are (w, x, y, z); positions in metres in the Panda base frame.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
from scipy.optimize import least_squares

from clfd_bench.sim.robot import GRASP_OFFSET


def rotate(quaternions: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """Rotates a vector [3] by each quaternion of `quaternions` [..., 4]; returns [..., 3]."""
    q = np.asarray(quaternions, dtype=float)
    v = np.asarray(vector, dtype=float).reshape(3)
    flat = q.reshape(-1, 4)
    out = np.empty((len(flat), 3))
    for i, qi in enumerate(flat):
        mujoco.mju_rotVecQuat(out[i], v, qi / np.linalg.norm(qi))
    return out.reshape(q.shape[:-1] + (3,))


def grasp_points(positions: np.ndarray, quaternions: np.ndarray,
                 offset: float = GRASP_OFFSET) -> np.ndarray:
    """Grasp points [..., 3] of hand poses: `offset` metres along each hand's z axis.

    Args:
        positions: [..., 3] hand positions (m).
        quaternions: [..., 4] hand orientations (w, x, y, z).
    """
    return np.asarray(positions, dtype=float) + offset * rotate(quaternions, [0.0, 0.0, 1.0])


@dataclasses.dataclass(frozen=True)
class HingeFit:
    """A hinge axis fitted to demonstrated arcs.

    Attributes:
        point: [3] a point on the axis (the one closest to the demos' mean axial position).
        axis: [3] unit axis direction, horizontal, oriented so that the lid opens by a
            positive rotation (right-hand rule) from the front (towards the demos' start) up.
        radii: [N] each demo's distance from the axis.
        axial: [N] each demo's offset along the axis from `point`.
        radial_residual: [N] max |distance - radius| per demo (m).
        axial_residual: [N] max |axial - axial offset| per demo (m).
    """

    point: np.ndarray
    axis: np.ndarray
    radii: np.ndarray
    axial: np.ndarray
    radial_residual: np.ndarray
    axial_residual: np.ndarray

    @property
    def front(self) -> np.ndarray:
        """[3] horizontal unit vector from the axis to the closed lid's front edge."""
        f = np.cross([0.0, 0.0, 1.0], self.axis)
        return f / np.linalg.norm(f)

    @property
    def yaw(self) -> float:
        """Rotation (rad) about world z that maps the x axis onto `axis`."""
        return float(np.arctan2(self.axis[1], self.axis[0]))


def fit_hinge(points: np.ndarray) -> HingeFit:
    """Fits one horizontal hinge axis to N demonstrated arcs.

    Each demo n is modelled as a circle about the common axis with its own radius r_n and
    axial offset a_n (the gripper may hold the lid at a different place each time); least
    squares over every sample of every demo.

    Args:
        points: [N, T, 3] grasp points of the demos (m).

    Returns:
        A `HingeFit`.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 3 or pts.shape[-1] != 3:
        raise ValueError(f"points must have shape [N, T, 3], got {pts.shape}")
    n_demos = pts.shape[0]
    # Initial guess: plane normal of all points (the arcs are near-planar), centre below the end.
    centred = pts.reshape(-1, 3) - pts.reshape(-1, 3).mean(0)
    normal = np.linalg.svd(centred, full_matrices=False)[2][2]
    yaw0 = float(np.arctan2(normal[1], normal[0]))
    mean = pts.reshape(-1, 3).mean(0)

    def unpack(p):
        axis = np.array([np.cos(p[0]), np.sin(p[0]), 0.0])
        perp = np.array([-axis[1], axis[0], 0.0])
        point = p[1] * perp + np.array([0.0, 0.0, p[2]]) + (mean @ axis) * axis
        return axis, point, p[3:3 + n_demos], p[3 + n_demos:]

    def residuals(p):
        axis, point, r, a = unpack(p)
        d = pts - point
        s = d @ axis
        perp = d - s[..., None] * axis
        return np.concatenate([(np.linalg.norm(perp, axis=-1) - r[:, None]).ravel(),
                               (s - a[:, None]).ravel()])

    perp0 = np.array([-np.sin(yaw0), np.cos(yaw0), 0.0])
    end = pts[:, -1].mean(0)
    p0 = np.concatenate([[yaw0, end @ perp0, pts[:, 0, 2].mean()],
                         np.full(n_demos, 0.25), np.zeros(n_demos)])
    sol = least_squares(residuals, p0)
    axis, point, radii, axial = unpack(sol.x)
    res = sol.fun
    radial = np.abs(res[: pts.shape[0] * pts.shape[1]].reshape(n_demos, -1)).max(1)
    axial_res = np.abs(res[pts.shape[0] * pts.shape[1]:].reshape(n_demos, -1)).max(1)
    # Orient the axis: the demos start in front of it and move up (positive rotation).
    fit = HingeFit(point, axis, radii, axial, radial, axial_res)
    ang = hinge_angles(pts, fit)
    if np.median(ang[:, -1] - ang[:, 0]) < 0:
        fit = HingeFit(point, -axis, radii, -axial, radial, axial_res)
    # Move the point to the demos' mean axial position.
    shift = float(np.mean(fit.axial))
    return dataclasses.replace(fit, point=fit.point + shift * fit.axis, axial=fit.axial - shift)


def hinge_angles(points: np.ndarray, fit: HingeFit) -> np.ndarray:
    """Angle (rad) of each point [..., 3] about the hinge: 0 = horizontal in front of the
    axis (`fit.front`), positive = raised (opening)."""
    d = np.asarray(points, dtype=float) - fit.point
    up = np.cross(fit.axis, fit.front)
    return np.arctan2(d @ up, d @ fit.front)


def grip_slips(positions: np.ndarray, quaternions: np.ndarray, fit: HingeFit
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How far a lid's edge must move in the fingers for the hand to follow the demos: with
    the lid turning about `fit`'s axis to the angle of each grasp point, relative to where it
    was grasped (the first sample).

    Args:
        positions: [N, T, 3] hand positions (m).
        quaternions: [N, T, 4] hand orientations (w, x, y, z).

    Returns:
        radial [N, T] (m, change of the grasp point's distance from the axis), axial [N, T] (m,
        change along the axis) and turn [N, T] (rad, angle of the hand's rotation relative to
        the lid since the first sample).
    """
    pos = np.asarray(positions, dtype=float)
    quat = np.asarray(quaternions, dtype=float)
    g = grasp_points(pos, quat)
    d = g - fit.point
    axial = d @ fit.axis
    radius = np.linalg.norm(d - axial[..., None] * fit.axis, axis=-1)
    ang = hinge_angles(g, fit)
    turn = np.empty(ang.shape)
    lid = np.empty(4)
    rel0 = np.empty(4)
    rel = np.empty(4)
    inv = np.empty(4)
    for n in range(ang.shape[0]):
        for t in range(ang.shape[1]):
            mujoco.mju_axisAngle2Quat(lid, fit.axis, ang[n, t])
            mujoco.mju_negQuat(inv, lid)
            mujoco.mju_mulQuat(rel, inv, quat[n, t] / np.linalg.norm(quat[n, t]))
            if t == 0:
                rel0[:] = rel
            turn[n, t] = 2.0 * np.arccos(min(1.0, abs(float(rel @ rel0))))
    return radius - radius[:, :1], axial - axial[:, :1], turn


def prop_pose(hand_pos: np.ndarray, hand_quat: np.ndarray, rel_pos: np.ndarray,
              rel_quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World pose of a prop held at `rel_pos` [3], `rel_quat` [4] in the hand frame.

    Returns:
        (position [3], quaternion [4] w, x, y, z).
    """
    hq = np.asarray(hand_quat, dtype=float)
    hq = hq / np.linalg.norm(hq)
    pos = np.empty(3)
    mujoco.mju_rotVecQuat(pos, np.asarray(rel_pos, dtype=float), hq)
    quat = np.empty(4)
    mujoco.mju_mulQuat(quat, hq, np.asarray(rel_quat, dtype=float))
    return np.asarray(hand_pos, dtype=float) + pos, quat


def lowest_point(model: mujoco.MjModel, data: mujoco.MjData, body: str) -> float:
    """Lowest world z (m) of the collision geoms of `body` (boxes, spheres, capsules,
    cylinders) in `data`'s current kinematics (call `mj_kinematics` first)."""
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    if bid < 0:
        raise ValueError(f"model has no body {body!r}")
    lowest = np.inf
    for g in np.flatnonzero(model.geom_bodyid == bid):
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue
        z = data.geom_xpos[g, 2]
        r3 = data.geom_xmat[g].reshape(3, 3)[2]  # world z row: z-components of the geom axes
        size = model.geom_size[g]
        gtype = model.geom_type[g]
        if gtype == mujoco.mjtGeom.mjGEOM_BOX:
            low = z - np.abs(r3) @ size
        elif gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
            low = z - size[0]
        elif gtype == mujoco.mjtGeom.mjGEOM_CAPSULE:
            low = z - abs(r3[2]) * size[1] - size[0]
        elif gtype == mujoco.mjtGeom.mjGEOM_CYLINDER:
            low = z - abs(r3[2]) * size[1] - size[0] * np.sqrt(max(0.0, 1.0 - r3[2] ** 2))
        else:
            raise ValueError(f"lowest_point supports box/sphere/capsule/cylinder geoms; body "
                             f"{body!r} has geom type {mujoco.mjtGeom(gtype).name}")
        lowest = min(lowest, float(low))
    if not np.isfinite(lowest):
        raise ValueError(f"body {body!r} has no collision geoms")
    return lowest
