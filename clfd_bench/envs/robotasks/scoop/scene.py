"""Scoop's scene: a scoop drawn through a bin of beans and lifted out level."""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.checks import checks_json
from clfd_bench.envs.robotasks.common import Scene, bean_pool, box_walls, first_toucher, obj_id
from clfd_bench.envs.robotasks.scoop import success
from clfd_bench.sim.grasp import Grasp

__all__ = ["SCENE", "ScoopScene"]


class ScoopScene(Scene):
    """A scoop held by its handle, a bin of beans on a stand. Success: `success.checks` (the scoop
    never slips and never touches the bin; it ends out of the bin, level, holding at least
    `min_beans` beans; at most `max_spilled` ever landed outside the bin). Where it ends is not
    judged: nothing in the scene marks demo j's end (no container), and a scoopful held level
    out of the bin is the task done wherever the hand is.

    The beans: the bin's contents up to `[scene] surface_z` are not simulated body by body (a
    bed deep enough for the demos' 8 cm spread of dip depth would take hundreds of spheres).
    They are a lattice of grain sites, `[scene] grain_spacing` apart, filling the bin. A grain
    becomes a bean (a free sphere from a pool of `n_beans`, which otherwise waits out of the
    scene, without contacts or weight) when the scoop's bowl sweeps it up: when its site passes
    into the bowl's cavity through the bowl's opening, not through a wall or the floor (a grain
    the bowl's outside pushes through is displaced and gone). From then on the bean is
    physical: it rides in the bowl, rolls out when the bowl tips, falls. A bean that falls back
    into the bin's contents (below the surface, within the walls, outside the bowl) rejoins
    them and returns to the pool; one that lands outside the bin is spilled and stays where it
    lies. A grain is taken only if no bean is already within a bean's diameter of it (a full
    bowl takes no more)."""

    needs_release = False

    def __init__(self, doc: dict[str, Any]):
        super().__init__(doc)
        self.n_beans, self.bean_radius, self.bean_names = bean_pool(self.scene, "scoop")
        self.object_bodies = ("scoop",) + self.bean_names

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        x0, x1, y0, y1 = (float(v) for v in s["bin_walls"])
        floor, rim = float(s["bin_floor_z"]), float(s["bin_rim_z"])
        surface = float(s["surface_z"])
        t = float(s.get("bin_wall_thickness", 0.008)) / 2
        cx, cy, hx, hy = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 2, (y1 - y0) / 2
        spec.body("bin").pos = [cx, cy, floor]
        box_walls(spec, "bin", (-hx, hx, -hy, hy), 0.0, rim - floor, t)
        g = spec.geom("bin_floor")
        g.size, g.pos = [hx + 2 * t, hy + 2 * t, 0.004], [0.0, 0.0, -0.004]
        g = spec.geom("material")
        g.size, g.pos = [hx, hy, (surface - floor) / 2], [0.0, 0.0, (surface - floor) / 2]
        stand_h = (floor - 0.008 - self.table_z) / 2
        spec.body("bin_stand").pos = [cx, cy, self.table_z + stand_h]
        spec.geom("bin_stand_support").size = [max(0.01, hx - 0.01), max(0.01, hy - 0.01),
                                               stand_h]
        for name in self.bean_names:
            b = spec.worldbody.add_body()
            b.name = name
            b.gravcomp = 1.0  # in the pool: weightless (compiled so that gravcomp is on)
            # A frictionless sphere (condim 1) takes no torque: three slides, no rotation.
            for axis in ((1, 0, 0), (0, 1, 0), (0, 0, 1)):
                j = b.add_joint()
                j.type = mujoco.mjtJoint.mjJNT_SLIDE
                j.axis = list(axis)
            g = b.add_geom()
            g.name = f"{name}_geom"
            g.type = mujoco.mjtGeom.mjGEOM_SPHERE
            g.size = [self.bean_radius, 0.0, 0.0]
            g.mass = float(s.get("bean_mass", 0.002))
            g.rgba = [0.35, 0.2, 0.1, 1.0]
            g.friction = [0.6, 0.005, 0.0001]
            g.condim = 1
            g.priority = 1  # a bean's contact takes the bean's condim (frictionless)
            g.contype = g.conaffinity = 0  # in the pool: no contacts

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        s = self.scene
        self.scoop = obj_id(model, mujoco.mjtObj.mjOBJ_BODY, "scoop")
        self.bean_ids = np.array([obj_id(model, mujoco.mjtObj.mjOBJ_BODY, n)
                                  for n in self.bean_names])
        self.bean_geoms = np.array([obj_id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{n}_geom")
                                    for n in self.bean_names])
        self.bin_geoms = np.array([obj_id(model, mujoco.mjtObj.mjOBJ_GEOM, f"bin_{n}") for n in
                                   ("floor", "wall_back", "wall_front", "wall_right",
                                    "wall_left")])
        # each bean's three slides: x, y, z of its centre (world, its body at the origin)
        self._bean_qpos = np.array([model.jnt_qposadr[model.body_jntadr[b]]
                                    for b in self.bean_ids])
        self._bean_dof = np.array([model.jnt_dofadr[model.body_jntadr[b]]
                                   for b in self.bean_ids])
        #: the bowl's cavity (inside its walls, floor and opening plane) and its outside, in
        #: the scoop's frame: [2, 3] (low corner, high corner); the opening is at z low.
        self._cavity = np.asarray(s["bowl_cavity"], dtype=float).reshape(2, 3)
        self._outer = np.asarray(s["bowl_outer"], dtype=float).reshape(2, 3)
        x0, x1, y0, y1 = (float(v) for v in s["bin_walls"])
        self._walls = (x0, x1, y0, y1)
        self._surface = float(s["surface_z"])
        self._rim = float(s["bin_rim_z"])
        r = self.bean_radius
        #: the grain lattice: sites origin + (i, j, k) * spacing inside the bin, up to a bean
        #: radius under the surface; `_taken` [nx, ny, nz] marks the grains already gone.
        self._spacing = float(s.get("grain_spacing", 2 * r + 0.001))
        self._origin = np.array([x0 + r, y0 + r, float(s["bin_floor_z"]) + r])
        top = np.array([x1 - r, y1 - r, self._surface - r])
        self._shape = tuple(int(v) for v in np.floor((top - self._origin) / self._spacing) + 1)
        #: where the beans wait in the pool (world) [n_beans, 3]: far under the room's floor.
        self._pool = np.column_stack([np.arange(self.n_beans) * 3 * r,
                                      np.zeros(self.n_beans), np.full(self.n_beans, -10.0)])
        self._taken = np.zeros(self._shape, dtype=bool)
        self._active = np.zeros(self.n_beans, dtype=bool)
        self._spilled = np.zeros(self.n_beans, dtype=bool)
        #: the scoop's pose at the previous step (position [3], rotation [3, 3]) or None.
        self._prev: tuple[np.ndarray, np.ndarray] | None = None
        corners = np.stack(np.meshgrid(*self._outer.T, indexing="ij"), -1).reshape(-1, 3)
        self._outer_corners = corners
        self._cavity_mid = self._cavity.mean(0)
        #: the cavity and a bean radius past its opening: a heaped scoopful counts
        self._heaped = self._cavity - [[0.0, 0.0, self.bean_radius], [0.0, 0.0, 0.0]]
        self._is_bin_geom = np.zeros(model.ngeom, dtype=bool)
        self._is_bin_geom[self.bin_geoms] = True
        self._is_bean_geom = np.zeros(model.ngeom, dtype=bool)
        self._is_bean_geom[self.bean_geoms] = True

    def _sites_near(self, poses: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        """[K, 3] lattice indices of the grains not yet taken within the bounding box of the
        bowl's outside at `poses` (scoop position [3], rotation [3, 3])."""
        pts = np.concatenate([p + self._outer_corners @ rot.T for p, rot in poses])
        lo = np.ceil((pts.min(0) - self._origin) / self._spacing).astype(int)
        hi = np.floor((pts.max(0) - self._origin) / self._spacing).astype(int) + 1
        lo, hi = np.maximum(lo, 0), np.minimum(hi, self._shape)
        if np.any(hi <= lo):
            return np.zeros((0, 3), dtype=int)
        block = ~self._taken[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
        return np.argwhere(block) + lo

    # -- the pool
    def _set_active(self, i: int, active: bool) -> None:
        b, g = int(self.bean_ids[i]), int(self.bean_geoms[i])
        m = self.model
        m.body_gravcomp[b] = 0.0 if active else 1.0
        # the broad phase filters on the bodies' contype / conaffinity (the compiler's OR of
        # their geoms'), so both levels change
        m.geom_contype[g] = m.geom_conaffinity[g] = 1 if active else 0
        m.body_contype[b] = m.body_conaffinity[b] = 1 if active else 0
        self._active[i] = active

    def _park(self, data: mujoco.MjData, i: int) -> None:
        self._set_active(i, False)
        a, v = self._bean_qpos[i], self._bean_dof[i]
        data.qpos[a:a + 3] = self._pool[i]
        data.qvel[v:v + 3] = 0.0

    def _spawn(self, data: mujoco.MjData, i: int, pos: np.ndarray, vel: np.ndarray) -> None:
        self._set_active(i, True)
        a, v = self._bean_qpos[i], self._bean_dof[i]
        data.qpos[a:a + 3] = pos
        data.qvel[v:v + 3] = vel

    def _in_box(self, local: np.ndarray, box: np.ndarray, pad: float = 0.0) -> np.ndarray:
        return np.all((local >= box[0] - pad) & (local <= box[1] + pad), axis=-1)

    def _local(self, data: mujoco.MjData, points: np.ndarray) -> np.ndarray:
        """[..., 3] world points in the scoop's frame."""
        return (points - data.xpos[self.scoop]) @ data.xmat[self.scoop].reshape(3, 3)

    def beans_in_bowl(self, data: mujoco.MjData) -> int:
        """Active beans whose centres are inside the bowl (within its walls, from its floor
        up to a bean radius past its opening: a heaped scoopful counts)."""
        if not self._active.any():
            return 0
        local = self._local(data, data.xpos[self.bean_ids[self._active]])
        return int(np.count_nonzero(self._in_box(local, self._heaped)))

    def bowl_centre(self, data: mujoco.MjData) -> np.ndarray:
        """[3] the bowl's centre (world): the middle of its cavity."""
        return data.xpos[self.scoop] + data.xmat[self.scoop].reshape(3, 3) @ self._cavity_mid

    # -- episode
    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.demo = demo
        self.place_held_prop(data, grasp)
        for i in range(self.n_beans):
            self._park(data, i)
        self._taken[:] = False
        self._spilled[:] = False
        self._prev = None

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.record = {"scooped": 0, "returned": 0, "spilled": 0, "bin_touched_by": None,
                       "pool_empty": 0}

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        """Takes the grains the bowl sweeps up, returns the beans that fall back into the bin,
        counts the ones that land outside it, and notes the first thing other than a bean that
        touches the bin."""
        rec = self.record
        changed = False
        pos = data.xpos[self.scoop].copy()
        rot = data.xmat[self.scoop].reshape(3, 3).copy()
        prev_pos, prev_rot = self._prev if self._prev is not None else (pos, rot)
        c = self._outer_corners
        low = min(pos[2] + (c @ rot[2]).min(), prev_pos[2] + (c @ prev_rot[2]).min())
        near = (self._sites_near([(pos, rot), (prev_pos, prev_rot)])
                if low < self._surface else ())  # the bowl reaches into the beans
        if len(near):
            sites = self._origin + near * self._spacing
            local = (sites - pos) @ rot
            prev = (sites - prev_pos) @ prev_rot
            inside = self._in_box(local, self._cavity)
            entered = inside & ~self._in_box(prev, self._cavity)
            solid = self._in_box(local, self._outer) & ~inside
            self._taken[tuple(near[solid].T)] = True  # pushed aside by the bowl's outside
            ks = np.flatnonzero(entered)
            if len(ks):
                self._taken[tuple(near[ks].T)] = True
                pooled = list(np.flatnonzero(~self._active & ~self._spilled))
                if not pooled:
                    rec["pool_empty"] += len(ks)  # the scoop already holds every bean
                    ks = ks[:0]
            if len(ks):
                vel = np.empty(6)
                mujoco.mj_objectVelocity(self.model, data, mujoco.mjtObj.mjOBJ_BODY,
                                         self.scoop, vel, 0)
                beans = [data.xpos[b].copy() for b in self.bean_ids[self._active]]
                for k in ks:
                    if not self._through_opening(prev[k], local[k]):
                        continue  # pushed in through a wall: displaced
                    site = sites[k]
                    if beans and np.min(np.linalg.norm(np.asarray(beans) - site, axis=1)
                                        ) < 2 * self.bean_radius:
                        continue  # the bowl is full here
                    if not pooled:
                        rec["pool_empty"] += 1
                        continue
                    v = vel[3:] + np.cross(vel[:3], site - pos)
                    self._spawn(data, int(pooled.pop(0)), site, v)
                    beans.append(site)
                    rec["scooped"] += 1
                    changed = True
        self._prev = (pos, rot)
        if changed:
            mujoco.mj_kinematics(self.model, data)
            changed = False
        # beans that fell back into the bin's contents, or out of the bin
        act = np.flatnonzero(self._active & ~self._spilled)
        if len(act):
            p = data.xpos[self.bean_ids[act]]
            x0, x1, y0, y1 = self._walls
            within = (p[:, 0] > x0) & (p[:, 0] < x1) & (p[:, 1] > y0) & (p[:, 1] < y1)
            in_bowl = self._in_box(self._local(data, p), self._cavity, self.bean_radius)
            back = within & (p[:, 2] < self._surface) & ~in_bowl
            for i in act[back]:
                self._park(data, int(i))
                rec["returned"] += 1
                changed = True
            out = ~within & (p[:, 2] < self._rim) & ~in_bowl
            if out.any():
                self._spilled[act[out]] = True
                rec["spilled"] += int(np.count_nonzero(out))
        if changed:
            mujoco.mj_kinematics(self.model, data)
        if rec["bin_touched_by"] is None:
            rec["bin_touched_by"] = first_toucher(self.model, data, self._is_bin_geom,
                                                  self._is_bean_geom)

    def _through_opening(self, before: np.ndarray, after: np.ndarray) -> bool:
        """Whether the segment `before` -> `after` (scoop frame) enters the cavity through its
        opening (the face at the cavity's low z), not through a wall or the floor."""
        lo, hi = self._cavity
        d = after - before
        t_in = np.full(3, -np.inf)
        for a in range(3):
            if abs(d[a]) < 1e-12:
                if not lo[a] <= before[a] <= hi[a]:
                    return False
                continue
            t0, t1 = (lo[a] - before[a]) / d[a], (hi[a] - before[a]) / d[a]
            t_in[a] = min(t0, t1)
        axis = int(np.argmax(t_in))
        return axis == 2 and before[2] < lo[2]

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        rec = self.record
        beans = self.beans_in_bowl(data)
        grip = data.xpos[self.scoop]  # the scoop's origin: the grasp point on its handle
        rot = data.xmat[self.scoop].reshape(3, 3)
        touched = rec["bin_touched_by"]
        # the opening faces -z of the scoop: its tilt from straight up
        tilt = math.degrees(math.acos(min(1.0, max(-1.0, -float(rot[2, 2])))))
        lowest = float(grip[2] + (self._outer_corners @ rot[2]).min())
        checks = success.checks(grasp.held(data), touched, lowest - self._rim, tilt, beans,
                                int(rec["spilled"]), self.success_cfg)
        ok = all(c.passed for c in checks)
        return ok, {"beans_in_scoop": beans, "beans_spilled": int(rec["spilled"]),
                    "beans_scooped": int(rec["scooped"]), "grip_point": grip.tolist(),
                    "bowl_centre": self.bowl_centre(data).tolist(), "bowl_tilt_deg": tilt,
                    "bowl_out_of_bin": checks[2].passed, "bin_touched_by": touched,
                    "checks": checks_json(checks)}

    def scene_state(self) -> dict[str, Any]:
        state = super().scene_state()
        state.update({"taken": self._taken.copy(), "active": self._active.copy(),
                      "spilled_beans": self._spilled.copy(),
                      "prev": None if self._prev is None else
                      (self._prev[0].copy(), self._prev[1].copy())})
        return state

    def restore_scene_state(self, state: dict[str, Any]) -> None:
        super().restore_scene_state(state)
        self._taken = np.asarray(state["taken"], dtype=bool).copy()
        for i, a in enumerate(np.asarray(state["active"], dtype=bool)):
            self._set_active(i, bool(a))
        self._spilled = np.asarray(state["spilled_beans"], dtype=bool).copy()
        prev = state["prev"]
        self._prev = None if prev is None else (np.asarray(prev[0]).copy(),
                                                np.asarray(prev[1]).copy())


SCENE = ScoopScene
