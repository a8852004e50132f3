"""The four RoboTasks scenes: how props are placed for a demo and what counts as success.

Each scene reads its numbers from the task spec (`tasks/<task>.toml`, see
`clfd_bench.envs.robotask_specs`), edits the composed `MjSpec` (poses and sizes the spec
derives from the demonstrations), places the props at `reset` for demo j (the held prop at the
grasp point, the rest where demo j needs it) and decides success from the physical state.

| task | held prop (grasp) | success |
|---|---|---|
| openbox | lid handle (connect) | lid hinge angle >= `min_lid_angle_deg` |
| bottle2shelf | bottle (weld) | released bottle lying on the shelf |
| platestandingtolying | plate (weld) | released plate lying on the platform, rack blocks in place |
| pouring | cup (weld) | >= `min_fraction` of the beans inside the container |

Success is decided from the state alone (no history besides the blocks' start positions), so it
can be evaluated at any step; `clfd_bench.execution.rollout.rollout` evaluates it after the
trajectory and the settling time.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces

from clfd_bench.sim.grasp import Grasp, GraspSpec
from clfd_bench.sim.robot import GRASP_SITE


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise ValueError(f"task scene has no {kind.name[6:].lower()} {name!r}; "
                         "is the task MJCF in tasks/ complete?")
    return i


def _yaw_quat(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def _free_qpos(model: mujoco.MjModel, body: int) -> int:
    jnt = model.body_jntadr[body]
    if jnt < 0 or model.jnt_type[jnt] != mujoco.mjtJoint.mjJNT_FREE:
        raise ValueError(f"body {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body)!r} "
                         "needs a free joint")
    return int(model.jnt_qposadr[jnt])


def set_free_pose(model: mujoco.MjModel, data: mujoco.MjData, body: int, pos: np.ndarray,
                  quat: np.ndarray) -> None:
    """Puts a free body at a world pose, at rest."""
    adr = _free_qpos(model, body)
    data.qpos[adr:adr + 3] = pos
    data.qpos[adr + 3:adr + 7] = np.asarray(quat) / np.linalg.norm(quat)
    dof = model.jnt_dofadr[model.body_jntadr[body]]
    data.qvel[dof:dof + 6] = 0.0


def _tilt_from_vertical(v: np.ndarray) -> float:
    """Angle (deg) between a unit vector's line and the world z axis (in [0, 90])."""
    return float(np.degrees(np.arccos(min(1.0, abs(float(v[2]))))))


def _support(spec: mujoco.MjSpec, body: str, top: list[float], half_xy: list[float],
             yaw: float, table_z: float, board: str, column: str) -> None:
    """Sizes a static support (board on a column down to the table), top centre at `top`."""
    b = spec.body(body)
    b.pos = list(top)
    b.quat = list(_yaw_quat(yaw))
    spec.geom(board).size = [half_xy[0], half_xy[1], 0.01]
    spec.geom(board).pos = [0.0, 0.0, -0.01]
    half_h = max(0.005, (top[2] - 0.02 - table_z) / 2)
    spec.geom(column).size = [max(0.01, half_xy[0] - 0.02), max(0.01, half_xy[1] - 0.02), half_h]
    spec.geom(column).pos = [0.0, 0.0, -0.02 - half_h]


class Scene:
    """Base of the RoboTasks scenes (one instance per env).

    Args:
        doc: the task spec (parsed TOML, see `clfd_bench.envs.robotask_specs.load_task_spec`).
    """

    #: names of the bodies reported in the observation's `objects` [K, 7] (pos, quat).
    object_bodies: tuple[str, ...] = ()

    def __init__(self, doc: dict[str, Any]):
        self.doc = doc
        self.scene = doc["scene"]
        self.success_cfg = doc["success"]
        g = doc["grasp"]
        self.grasp_spec = GraspSpec(
            kind=g["kind"], body=g["body"], solref=tuple(g.get("solref", (0.01, 1.0))),
            max_slip=float(g.get("max_slip", 0.03)),
            max_slip_angle=float(np.radians(g.get("max_slip_angle_deg", 30.0))),
            closed_opening=float(g.get("closed_opening", 0.0)),
            exclude=tuple(g.get("exclude", ())),
            prop_pos=tuple(float(v) for v in g.get("prop_pos", (0.0, 0.0, 0.0))),
            prop_quat=tuple(float(v) for v in g.get("prop_quat", (1.0, 0.0, 0.0, 0.0))))
        self.table_z = float(self.scene.get("table_z", 0.0))

    # -- composition
    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        if self.table_z != 0.0:
            spec.geom("floor").pos = [0.0, 0.0, self.table_z]
            ped = spec.worldbody.add_geom()
            ped.name = "pedestal"
            ped.type = mujoco.mjtGeom.mjGEOM_CYLINDER
            ped.size = [0.11, -self.table_z / 2, 0.0]
            ped.pos = [-0.04, 0.0, self.table_z / 2]
            ped.rgba = [0.3, 0.3, 0.32, 1.0]
            ped.contype = ped.conaffinity = 0

    def bind(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.grasp_site = _id(model, mujoco.mjtObj.mjOBJ_SITE, GRASP_SITE)
        self.object_ids = [_id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in self.object_bodies]

    # -- episode
    def place_held_prop(self, data: mujoco.MjData, grasp: Grasp) -> None:
        """Puts the held prop (a free body) where the grasp holds it: at the spec's
        `[grasp] prop_pos`, `prop_quat` in the grasp-site frame."""
        pos, quat = grasp.held_pose(data)
        set_free_pose(self.model, data, grasp.body_id, pos, quat)

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        """Places the props for `demo` (robot already placed, kinematics current)."""
        raise NotImplementedError

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        """(success, task info) from the current physical state."""
        raise NotImplementedError

    def scene_state(self) -> dict[str, Any]:
        """Episode state beyond the physics state (for pickling)."""
        return {}

    def restore_scene_state(self, state: dict[str, Any]) -> None:
        pass

    def observation_space(self) -> dict[str, spaces.Space]:
        return {"objects": spaces.Box(-np.inf, np.inf, (len(self.object_bodies), 7), np.float64)}

    def observation(self, data: mujoco.MjData) -> dict[str, np.ndarray]:
        ids = self.object_ids
        return {"objects": np.concatenate([data.xpos[ids], data.xquat[ids]], axis=1)}


class OpenBoxScene(Scene):
    """A box with a hinged lid (no hinge friction; a lip on its front edge puts its balance at
    93.2 deg: past it the lid falls open onto its 120 deg stop, below it shut). The gripper
    holds the lid's handle, which slides on the lid, so only the hinge angle follows the
    hand. Placed by `[scene] hinge_pos`, `hinge_yaw_deg` (the fitted hinge axis)."""

    object_bodies = ("lid", "lid_handle")

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        box = spec.body("box")
        box.pos = list(self.scene["hinge_pos"])
        box.quat = list(_yaw_quat(np.radians(self.scene["hinge_yaw_deg"])))

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.box = _id(model, mujoco.mjtObj.mjOBJ_BODY, "box")
        self.handle = _id(model, mujoco.mjtObj.mjOBJ_BODY, "lid_handle")
        j = {n: _id(model, mujoco.mjtObj.mjOBJ_JOINT, n)
             for n in ("lid_hinge", "handle_axial", "handle_radial")}
        self.qadr = {n: int(model.jnt_qposadr[i]) for n, i in j.items()}
        self.jrange = {n: model.jnt_range[i].copy() for n, i in j.items()}
        self.handle_rest = model.body_pos[self.handle].copy()  # in the lid frame: (x, r, h)

    def lid_angle(self, data: mujoco.MjData) -> float:
        """Lid hinge angle, degrees (0 closed, positive open)."""
        return float(np.degrees(data.qpos[self.qadr["lid_hinge"]]))

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        # The grasp point in the hinge frame decides the lid angle and the handle's slides.
        rot = data.xmat[self.box].reshape(3, 3)
        local = rot.T @ (data.site_xpos[self.grasp_site] - data.xpos[self.box])
        x0, r0, h = self.handle_rest
        rho2 = local[1] ** 2 + local[2] ** 2
        r = float(np.sqrt(max(rho2 - h * h, 1e-12)))
        angle = float(np.arctan2(local[2], local[1]) - np.arctan2(h, r))
        values = {"lid_hinge": angle, "handle_radial": r - r0, "handle_axial": local[0] - x0}
        for name, v in values.items():
            lo, hi = self.jrange[name]
            if not lo <= v <= hi:
                raise ValueError(f"demo {demo}'s start puts the gripper outside the lid handle's "
                                 f"range ({name} = {v:.4f}, range [{lo}, {hi}]): the openbox "
                                 "scene does not fit this demo; regenerate tasks/openbox.toml")
            data.qpos[self.qadr[name]] = v

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        angle = self.lid_angle(data)
        ok = angle >= float(self.success_cfg["min_lid_angle_deg"])
        return ok, {"lid_angle_deg": angle}


class BottleScene(Scene):
    """A bottle held upright by its neck; a shelf where the demos end. Success: the bottle,
    released, lies (axis within `max_tilt_deg` of horizontal) on the shelf's top."""

    object_bodies = ("bottle",)

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        _support(spec, "shelf", s["shelf_top"], s["shelf_half_size"],
                 np.radians(s.get("shelf_yaw_deg", 0.0)), self.table_z, "shelf_board",
                 "shelf_support")

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.bottle = _id(model, mujoco.mjtObj.mjOBJ_BODY, "bottle")
        self.shelf = _id(model, mujoco.mjtObj.mjOBJ_BODY, "shelf")

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.place_held_prop(data, grasp)

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        c = self.success_cfg
        rot = data.xmat[self.shelf].reshape(3, 3)
        com = rot.T @ (data.xipos[self.bottle] - data.xpos[self.shelf])
        half = self.scene["shelf_half_size"]
        on_top = abs(com[0]) <= half[0] and abs(com[1]) <= half[1]
        height = float(com[2])
        axis = data.xmat[self.bottle].reshape(3, 3)[:, 2]
        tilt = 90.0 - _tilt_from_vertical(axis)  # from horizontal
        lying = tilt <= float(c["max_tilt_deg"])
        resting = float(c["min_height"]) <= height <= float(c["max_height"])
        released = not grasp.held(data)
        ok = bool(released and on_top and lying and resting)
        return ok, {"bottle_tilt_deg": tilt, "bottle_height": height, "on_shelf": bool(on_top)}


class PlateScene(Scene):
    """A plate standing in a rack of four blocks; a platform where the demos end. Success: the
    plate, released, lies (normal within `max_tilt_deg` of vertical) on the platform, and
    every block is within `max_block_shift` of where it started and upright."""

    blocks = ("block1", "block2", "block3", "block4")
    object_bodies = ("plate",) + blocks

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        _support(spec, "platform", s["platform_top"], s["platform_half_size"],
                 np.radians(s.get("platform_yaw_deg", 0.0)), self.table_z, "platform_top",
                 "platform_support")

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.plate = _id(model, mujoco.mjtObj.mjOBJ_BODY, "plate")
        self.disc = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "plate_disc")
        self.platform = _id(model, mujoco.mjtObj.mjOBJ_BODY, "platform")
        self.block_ids = [_id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in self.blocks]
        gid = model.body_geomadr[self.block_ids[0]]
        self.block_half_h = float(model.geom_size[gid][2])
        self.block_start = np.zeros((len(self.blocks), 3))

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.place_held_prop(data, grasp)
        mujoco.mj_kinematics(self.model, data)
        # The rack stands on the table under the plate, turned with the plate's plane.
        centre = data.geom_xpos[self.disc]
        in_plane = data.xmat[self.plate].reshape(3, 3)[:, 0]
        yaw = float(np.arctan2(in_plane[1], in_plane[0]))
        c, s = np.cos(yaw), np.sin(yaw)
        rack = np.array([[c, -s], [s, c]])
        for k, (b, off) in enumerate(zip(self.block_ids, self.scene["block_offsets"],
                                         strict=True)):
            xy = centre[:2] + rack @ np.asarray(off, dtype=float)
            pos = np.array([xy[0], xy[1], self.table_z + self.block_half_h])
            set_free_pose(self.model, data, b, pos, _yaw_quat(yaw))
            self.block_start[k] = pos

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        c = self.success_cfg
        rot = data.xmat[self.platform].reshape(3, 3)
        centre = rot.T @ (data.geom_xpos[self.disc] - data.xpos[self.platform])
        half = self.scene["platform_half_size"]
        on_top = abs(centre[0]) <= half[0] and abs(centre[1]) <= half[1]
        height = float(centre[2])
        normal = data.xmat[self.plate].reshape(3, 3)[:, 1]
        tilt = _tilt_from_vertical(normal)
        lying = tilt <= float(c["max_tilt_deg"])
        resting = float(c["min_height"]) <= height <= float(c["max_height"])
        shifts = np.linalg.norm(data.xpos[self.block_ids] - self.block_start, axis=1)
        block_tilts = [_tilt_from_vertical(data.xmat[b].reshape(3, 3)[:, 2])
                       for b in self.block_ids]
        blocks_ok = bool(shifts.max() <= float(c["max_block_shift"])
                         and max(block_tilts) <= float(c["max_block_tilt_deg"]))
        released = not grasp.held(data)
        ok = bool(released and on_top and lying and resting and blocks_ok)
        return ok, {"plate_tilt_deg": tilt, "plate_height": height, "on_platform": bool(on_top),
                    "max_block_shift": float(shifts.max()), "blocks_in_place": blocks_ok}

    def scene_state(self) -> dict[str, Any]:
        return {"block_start": self.block_start.copy()}

    def restore_scene_state(self, state: dict[str, Any]) -> None:
        self.block_start = np.asarray(state["block_start"], dtype=float).copy()


class PouringScene(Scene):
    """A cup holding `n_beans` free spheres; a square container where the demos pour. Success:
    at least `min_fraction` of the beans end inside the container."""

    object_bodies = ("cup",)

    def __init__(self, doc: dict[str, Any]):
        super().__init__(doc)
        self.n_beans = int(self.scene["n_beans"])
        self.bean_radius = float(self.scene["bean_radius"])
        if self.n_beans < 1:
            raise ValueError(f"pouring needs n_beans >= 1, got {self.n_beans}")
        self.bean_names = tuple(f"bean{i}" for i in range(self.n_beans))
        self.object_bodies = ("cup",) + self.bean_names

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        cont = spec.body("container")
        cont.pos = list(s["container_floor"])
        cont.quat = list(_yaw_quat(np.radians(s.get("container_yaw_deg", 0.0))))
        a, h, t = float(s["container_half_size"]), float(s["container_height"]), 0.005
        floor = spec.geom("container_floor")
        floor.size = [a + 2 * t, a + 2 * t, 0.004]
        for i, (px, py, sx, sy) in enumerate([(a + t, 0, t, a + 2 * t), (-a - t, 0, t, a + 2 * t),
                                               (0, a + t, a, t), (0, -a - t, a, t)]):
            g = cont.add_geom()
            g.name = f"container_wall{i}"
            g.type = mujoco.mjtGeom.mjGEOM_BOX
            g.size = [sx, sy, h / 2]
            g.pos = [px, py, h / 2]
            g.rgba = [0.45, 0.45, 0.5, 1.0]
        opt = self.doc.get("solver", {})
        if opt:
            spec.option.solver = getattr(mujoco.mjtSolver, f"mjSOL_{opt['solver'].upper()}")
            spec.option.iterations = int(opt["iterations"])
            spec.option.ls_iterations = int(opt.get("ls_iterations", 10))
            spec.option.tolerance = float(opt.get("tolerance", 1e-8))
            if opt.get("cone"):
                spec.option.cone = getattr(mujoco.mjtCone, f"mjCONE_{opt['cone'].upper()}")
        for name in self.bean_names:
            b = spec.worldbody.add_body()
            b.name = name
            b.add_freejoint()
            g = b.add_geom()
            g.name = f"{name}_geom"
            g.type = mujoco.mjtGeom.mjGEOM_SPHERE
            g.size = [self.bean_radius, 0.0, 0.0]
            g.mass = float(s.get("bean_mass", 0.002))
            g.rgba = [0.35, 0.2, 0.1, 1.0]
            g.friction = [0.6, 0.005, 0.0001]

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.cup = _id(model, mujoco.mjtObj.mjOBJ_BODY, "cup")
        self.container = _id(model, mujoco.mjtObj.mjOBJ_BODY, "container")
        self.bean_ids = np.array([_id(model, mujoco.mjtObj.mjOBJ_BODY, n)
                                  for n in self.bean_names])
        self.bean_local = self._bean_layout()

    def _bean_layout(self) -> np.ndarray:
        """[n_beans, 3] bean centres in the cup frame: close-packed hexagonal layers from the
        cup's floor up, 1 mm apart (no two beans touch at reset)."""
        r = self.bean_radius
        inner = float(self.scene.get("cup_inner_radius", 0.036)) - r - 0.001
        floor = float(self.scene.get("cup_floor", -0.042)) + r + 0.001
        s = 2 * r + 0.001
        n = int(inner // s) + 2
        i, j = np.meshgrid(np.arange(-n, n + 1), np.arange(-n, n + 1))
        grid = np.stack([(i + 0.5 * (j % 2)) * s, j * s * np.sqrt(3) / 2], -1).reshape(-1, 2)
        pts: list[np.ndarray] = []
        layer = 0
        while len(pts) < self.n_beans:
            shift = np.array([s / 2, s / (2 * np.sqrt(3))]) if layer % 2 else np.zeros(2)
            xy = grid + shift
            xy = xy[np.linalg.norm(xy, axis=1) <= inner]
            if len(xy) == 0:
                raise ValueError(f"beans of radius {r} m do not fit in the cup")
            z = floor + layer * s * np.sqrt(2.0 / 3.0)
            pts.extend(np.column_stack([xy, np.full(len(xy), z)]))
            layer += 1
        return np.array(pts[: self.n_beans])

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.place_held_prop(data, grasp)
        mujoco.mj_kinematics(self.model, data)
        cup_pos = data.xpos[self.cup]
        cup_rot = data.xmat[self.cup].reshape(3, 3)
        for b, local in zip(self.bean_ids, self.bean_local, strict=True):
            set_free_pose(self.model, data, b, cup_pos + cup_rot @ local, np.array([1.0, 0, 0, 0]))

    def bean_fraction(self, data: mujoco.MjData) -> float:
        """Fraction of beans inside the container (below its rim, within its walls)."""
        rot = data.xmat[self.container].reshape(3, 3)
        local = (data.xpos[self.bean_ids] - data.xpos[self.container]) @ rot
        a, h = float(self.scene["container_half_size"]), float(self.scene["container_height"])
        inside = ((np.abs(local[:, 0]) <= a) & (np.abs(local[:, 1]) <= a)
                  & (local[:, 2] >= -0.01) & (local[:, 2] <= h))
        return float(inside.mean())

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        frac = self.bean_fraction(data)
        return frac >= float(self.success_cfg["min_fraction"]), {"bean_fraction": frac}


SCENES: dict[str, type[Scene]] = {
    "openbox": OpenBoxScene,
    "bottle2shelf": BottleScene,
    "platestandingtolying": PlateScene,
    "pouring": PouringScene,
}


def make_scene(task: str, doc: dict[str, Any]) -> Scene:
    """The scene of a RoboTasks task, configured by its spec."""
    if task not in SCENES:
        raise KeyError(f"no RoboTasks scene {task!r}; valid: {sorted(SCENES)}")
    return SCENES[task](doc)
