"""Contacts of the robot with the scene (`CollisionMonitor`), and the scene's floor height.

A robot link, hand or finger pushing a non-robot geom harder than the collision bound
(`clfd_bench.sim.limits.COLLISION_FORCE`, libfranka's default threshold) is a "collision"
(a `clfd_bench.sim.limits.Violation`); the pen and a held prop touch the scene by design and
do not count. `floor_height` is the height below which a commanded position is unreachable.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from clfd_bench.sim.limits import COLLISION_FORCE, Violation
from clfd_bench.sim.robot import ROBOT_BODIES


def floor_height(model: mujoco.MjModel) -> float:
    """Height (m) of the scene's floor: the highest upward-facing plane geom fixed to the world
    (the Menagerie floor at 0, lowered as a table in some scenes); -inf without one."""
    planes = np.flatnonzero((model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)
                            & (model.geom_bodyid == 0))
    heights = []
    for g in planes:
        mat = np.empty(9)
        mujoco.mju_quat2Mat(mat, model.geom_quat[g])
        if mat[8] > 0.999:  # the plane's normal (its z axis) points up
            heights.append(float(model.geom_pos[g, 2]))
    return max(heights) if heights else -math.inf


class CollisionMonitor:
    """Contacts of the robot with the scene, and their forces.

    Args:
        model: the compiled scene.
        robot_bodies: names of the robot's bodies whose contacts count (default: the Panda's
            links, hand and fingers; a tool such as the pen, or a held prop, is not among them
            and touches the scene by design).
        force_bound: N, normal force summed over the contacts of one (robot body, other geom)
            pair.
    """

    def __init__(self, model: mujoco.MjModel, robot_bodies: tuple[str, ...] = ROBOT_BODIES,
                 force_bound: float = COLLISION_FORCE):
        self.model = model
        self.force_bound = float(force_bound)
        ids = []
        for name in robot_bodies:
            b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
            if b < 0:
                raise ValueError(f"model has no body {name!r}")
            ids.append(b)
        self._is_robot = np.isin(model.geom_bodyid, ids)
        self._force = np.zeros(6)
        self.peak = 0.0

    def reset(self) -> None:
        """Clears `peak` (the largest robot-scene pair force seen, N)."""
        self.peak = 0.0

    def _geom_name(self, g: int) -> str:
        m = self.model
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g)
        if name:
            return name
        body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g]))
        return body or f"geom {g}"

    def check(self, data: mujoco.MjData, step: int) -> Violation | None:
        """A collision when, in the current contacts (those of the last physics step), the
        (robot body, other geom) pair pushing hardest does so with more than `force_bound`;
        else None. `step` is the step index to report."""
        if data.ncon == 0:
            return None
        geom = data.contact.geom  # (ncon, 2)
        robot = self._is_robot[geom]
        if not robot.any():  # the usual case: no robot geom in contact
            return None
        hit = robot[:, 0] != robot[:, 1]
        m, f = self.model, self._force
        totals: dict[tuple[int, int], float] = {}
        for i in np.flatnonzero(hit):
            mujoco.mj_contactForce(m, data, int(i), f)
            g1, g2 = int(geom[i, 0]), int(geom[i, 1])
            rg, og = (g1, g2) if robot[i, 0] else (g2, g1)
            key = (int(m.geom_bodyid[rg]), og)
            totals[key] = totals.get(key, 0.0) + abs(float(f[0]))
        if not totals:
            return None
        (body, other), force = max(totals.items(), key=lambda kv: kv[1])
        self.peak = max(self.peak, force)
        if force <= self.force_bound:
            return None
        who = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, body)
        return Violation("collision", "contact force", force, self.force_bound, "N", step,
                         detail=f"{who} hit {self._geom_name(other)}")
