"""Scoop's scene: a scoop drawn through a bin of beans and lifted out level."""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.checks import checks_json
from clfd_bench.envs.robotasks.common import Scene, bean_pool, box_walls, first_toucher, obj_id
from clfd_bench.envs.robotasks.scoop import kernels, success
from clfd_bench.sim.grasp import Grasp

_NO_SITES = np.empty(0, dtype=np.intp)  # no site entered the cavity

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
        self._origin_list = self._origin.tolist()
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
        self._bowl_box = ((self._cavity[0] - r).tolist(), (self._cavity[1] + r).tolist())
        #: whether the cavity lies within the bowl's outside box: then a site outside the
        #: outside box is in neither, and a step whose sites are all outside it changes nothing.
        self._nested = bool(np.all(self._cavity[0] >= self._outer[0])
                            and np.all(self._cavity[1] <= self._outer[1]))
        #: a bean below this height (world z) may rejoin the bin or be spilled; above it not.
        self._settle_z = max(self._surface, self._rim)
        #: the grain sites (world) [nx, ny, nz, 3]: origin + (i, j, k) * spacing, the same
        #: expression (and bits) as the sites of lattice indices computed one by one.
        self._grid = self._origin + np.moveaxis(np.indices(self._shape), 0, -1) * self._spacing
        #: (pose, lowest z, bounds or None) of the pose `_prev` holds (see `_pose_low`).
        self._prev_cache: tuple[Any, float, list[float] | None] | None = None
        #: (block, its free mask, its free sites [K, 3]) of the last sweep (see `_sweep`).
        self._free_cache: tuple[tuple[int, ...], np.ndarray, np.ndarray] | None = None
        #: (indices, body ids) of the active beans not spilled, None when to be recomputed.
        self._live: tuple[np.ndarray, np.ndarray] | None = None
        self._view_data: mujoco.MjData | None = None

    def _pose_low(self, pos: np.ndarray, rot: np.ndarray) -> float:
        """The lowest z (world) of the bowl's outside box with the scoop at `pos` [3], `rot`
        [3, 3]."""
        return pos[2] + (self._outer_corners @ rot[2]).min()

    def _pose_bounds(self, pos: np.ndarray, rot: np.ndarray) -> list[float]:
        """The world bounding box of the bowl's outside box with the scoop at `pos` [3], `rot`
        [3, 3]: [6] floats, low corner then high corner."""
        pts = pos + self._outer_corners @ rot.T
        return pts.min(0).tolist() + pts.max(0).tolist()

    def _block(self, a: list[float], b: list[float]) -> tuple[int, ...] | None:
        """The lattice block (index ranges lo0, hi0, lo1, hi1, lo2, hi2) of the sites within
        the world bounding box of the bowl's outside at two poses (`_pose_bounds` `a`, `b`),
        or None when it is empty."""
        # numpy's ceil / floor((p - origin) / spacing) on floats: the same IEEE operations,
        # exact integer results. The poses are finite: `track` runs only after a step whose
        # physics passed the env's blow-up check.
        o, sp, shape = self._origin_list, self._spacing, self._shape
        lo = [max(math.ceil((min(a[k], b[k]) - o[k]) / sp), 0) for k in range(3)]
        hi = [min(math.floor((max(a[k + 3], b[k + 3]) - o[k]) / sp) + 1, shape[k])
              for k in range(3)]
        if hi[0] <= lo[0] or hi[1] <= lo[1] or hi[2] <= lo[2]:
            return None
        return lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]

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
        self._live = None

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

    def _in_box(self, local: np.ndarray, box: np.ndarray) -> np.ndarray:
        """Whether each point of `local` [..., 3] lies in `box` [2, 3] (low, high corner; the
        faces included): bool [...] (`kernels.in_box`)."""
        flat = np.ascontiguousarray(local, dtype=float).reshape(-1, 3)
        return kernels.in_box(flat, box).reshape(local.shape[:-1])

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
        self._free_cache = None
        self._spilled[:] = False
        self._live = None
        self._prev = None

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.record = {"scooped": 0, "returned": 0, "spilled": 0, "bin_touched_by": None,
                       "pool_empty": 0}

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        """Takes the grains the bowl sweeps up, returns the beans that fall back into the bin,
        counts the ones that land outside it, and notes the first thing other than a bean that
        touches the bin.

        Runs every control step, so it skips what cannot change anything (each skip is exact:
        what it skips would have found nothing): the grain lattice while the bowl is above
        the beans; the grains' cavity and entry tests when no grain is inside the bowl's
        outside box (the cavity lies within it); the active beans' tests while none is below
        the bin's rim and surface. The previous pose's values are kept, not recomputed."""
        rec = self.record
        if self._view_data is not data:
            self._scoop_pos = data.xpos[self.scoop]
            self._scoop_rot = data.xmat[self.scoop].reshape(3, 3)
            self._view_data = data
        pos = self._scoop_pos.copy()
        rot = self._scoop_rot.copy()
        low_now = self._pose_low(pos, rot)
        bounds_now = None
        if self._prev is None:
            prev_pos, prev_rot, low_prev = pos, rot, low_now
        else:
            prev_pos, prev_rot = self._prev
            low_prev = self._prev_values()[1]
        if min(low_now, low_prev) < self._surface:  # the bowl reaches into the beans
            bounds_now = self._pose_bounds(pos, rot)
            bounds_prev = bounds_now if self._prev is None else self._prev_bounds()
            block = self._block(bounds_now, bounds_prev)
            if block is not None and self._sweep(data, rec, block, pos, rot, prev_pos,
                                                 prev_rot):
                mujoco.mj_kinematics(self.model, data)
        self._prev = (pos, rot)
        self._prev_cache = (self._prev, low_now, bounds_now)
        # beans that fell back into the bin's contents, or out of the bin
        act, ids = self._live_beans()
        if len(act) and self._settle(data, rec, act, data.xpos[ids]):
            mujoco.mj_kinematics(self.model, data)
        if rec["bin_touched_by"] is None:
            rec["bin_touched_by"] = first_toucher(self.model, data, self._is_bin_geom,
                                                  self._is_bean_geom)

    def _prev_values(self) -> tuple[Any, float, list[float] | None]:
        """(pose, `_pose_low`, `_pose_bounds` or None if not computed yet) of `_prev`, kept
        from the step that set it (recomputed after a restore: the same bits)."""
        if self._prev_cache is None or self._prev_cache[0] is not self._prev:
            self._prev_cache = (self._prev, self._pose_low(*self._prev), None)
        return self._prev_cache

    def _prev_bounds(self) -> list[float]:
        pose, low, bounds = self._prev_values()
        if bounds is None:
            bounds = self._pose_bounds(*pose)
            self._prev_cache = (pose, low, bounds)
        return bounds

    def _live_beans(self) -> tuple[np.ndarray, np.ndarray]:
        """(indices [L], body ids [L]) of the active beans not spilled (kept until a bean is
        spawned, parked or spilled)."""
        if self._live is None:
            act = np.flatnonzero(self._active & ~self._spilled)
            self._live = (act, self.bean_ids[act])
        return self._live

    def _sweep(self, data: mujoco.MjData, rec: dict[str, Any], block: tuple[int, ...],
               pos: np.ndarray, rot: np.ndarray, prev_pos: np.ndarray,
               prev_rot: np.ndarray) -> bool:
        """The grains of the lattice `block` not taken yet, with the scoop at `pos` [3], `rot`
        [3, 3] now and at `prev_pos`, `prev_rot` the step before: those in the bowl's outside
        but not its cavity are pushed aside (taken); those that entered the cavity since the
        previous pose are taken and, if through the opening with room and a bean in the pool,
        become beans. Returns whether a bean was spawned.

        The block's free mask and sites are kept while the block and the grains taken stay
        the same (the bowl often stays within the same lattice block for a few steps)."""
        lo0, hi0, lo1, hi1, lo2, hi2 = block
        view = (slice(lo0, hi0), slice(lo1, hi1), slice(lo2, hi2))
        taken = self._taken[view]  # a view: writing it marks the lattice
        cache = self._free_cache
        if cache is not None and cache[0] == block:
            free, sites = cache[1], cache[2]
        else:
            free = ~taken
            sites = self._grid[view][free]  # [K, 3], in lattice (lexicographic) order
            self._free_cache = (block, free, sites)
        if not len(sites):
            return False
        local = (sites - pos) @ rot
        inside, solid, n_outer, n_inside, n_solid = kernels.classify(local, self._outer,
                                                                     self._cavity)
        if self._nested and not n_outer:
            return False  # no grain in the bowl's outside (nor, so, in its cavity)
        if not n_inside:  # solid: pushed aside by the bowl's outside, taken
            if n_solid:
                self._mark(block, taken, free, sites, solid)
            return False
        prev = (sites - prev_pos) @ prev_rot
        entered, gone, n_entered, n_gone = kernels.entered(inside, solid, prev, self._cavity)
        if n_gone:  # taken: pushed aside or entered
            self._mark(block, taken, free, sites, gone)
        ks = np.flatnonzero(entered) if n_entered else _NO_SITES
        if len(ks):
            pooled = list(np.flatnonzero(~self._active & ~self._spilled))
            if not pooled:
                rec["pool_empty"] += len(ks)  # the scoop already holds every bean
                ks = ks[:0]
        changed = False
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
        return changed

    def _mark(self, block: tuple[int, ...], taken: np.ndarray, free: np.ndarray,
              sites: np.ndarray, gone: np.ndarray) -> None:
        """Marks the free sites `gone` [K] of the block (`taken`: the block's view of the
        lattice, `free` its free mask, `sites` [K, 3] the free sites) taken, and keeps the
        block's new free mask and sites."""
        taken[free] = gone  # the free sites: False before, `gone` now
        self._free_cache = (block, ~taken, sites[~gone])

    def _settle(self, data: mujoco.MjData, rec: dict[str, Any], act: np.ndarray,
                p: np.ndarray) -> bool:
        """Of the active beans `act` [L] (not spilled) at `p` [L, 3] (world): parks those that
        fell back into the bin's contents (within its walls, below its surface, not in the
        bowl) and marks spilled those that landed outside it (below its rim, outside its
        walls, not in the bowl). Returns whether a bean was parked. Per bean, in floats:
        comparisons only, exact; the bowl test reads the scoop-frame positions of all L beans
        (`_local`) as always."""
        pl = p.tolist()
        settle = self._settle_z
        if not any(q[2] < settle for q in pl):
            return False  # none is low enough to be back in the bin or out of it
        x0, x1, y0, y1 = self._walls
        (b0, b1, b2), (c0, c1, c2) = self._bowl_box
        local = None
        back, out = [], []
        for j, (x, y, z) in enumerate(pl):
            within = x0 < x < x1 and y0 < y < y1
            if not (z < self._surface if within else z < self._rim):
                continue
            if local is None:
                local = self._local(data, p).tolist()
            u, v, w = local[j]
            if b0 <= u <= c0 and b1 <= v <= c1 and b2 <= w <= c2:
                continue  # in the bowl
            (back if within else out).append(j)
        for j in back:
            self._park(data, int(act[j]))
            rec["returned"] += 1
        if out:
            self._spilled[act[out]] = True
            self._live = None
            rec["spilled"] += len(out)
        return bool(back)

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
        self._free_cache = None
        for i, a in enumerate(np.asarray(state["active"], dtype=bool)):
            self._set_active(i, bool(a))
        self._spilled = np.asarray(state["spilled_beans"], dtype=bool).copy()
        self._live = None
        prev = state["prev"]
        self._prev = None if prev is None else (np.asarray(prev[0]).copy(),
                                                np.asarray(prev[1]).copy())


SCENE = ScoopScene
