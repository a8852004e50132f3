"""What the RoboTasks scenes share: the table, supports and walls, solver options, the grasp of
a spec, and `Scene`, the base every task's scene class extends (`<task>/scene.py`).

A scene reads its numbers from the task spec (`tasks/<task>.toml`, see
`clfd_bench.envs.robotasks.specs`), edits the composed `MjSpec` (table, poses and sizes the spec
derives from the demonstrations), places the props at `reset` for demo j (the held prop at the
grasp point, the rest where demo j needs them), follows the episode step by step (`track`) and
decides success from what happened in the whole episode, as an observer would, not from the
end state alone. The rules of each task are written once, in its `doc.py` (`RULES`, shown in
`RoboTaskEnv`'s docstring); its `success.py` is the predicate that decides them from the
measured quantities.

Every scene stands on a table (`[scene] table_z`, the height of its top in the robot base frame;
the robot stands on it, on a mount when the table is lower than the robot's base). The table top
is a collision plane (the Menagerie floor, moved and hidden in geom group 3) drawn as a wooden
top on four legs above the room's floor.

`success` only reads the records `track` keeps, so it is cheap at every step. Every scene
returns its criteria as `info["checks"]`: one `clfd_bench.envs.checks.Check` (as JSON) per
criterion, with its measured value and bound in m, deg or counts; its success is all of them
passing (`docs/execution.md`, "Where every bound comes from").
`clfd_bench.execution.rollout.rollout` decides after the trajectory and the settling time.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces

from clfd_bench.sim.grasp import Grasp, GraspSpec, grip_capacity
from clfd_bench.sim.robot import GRASP_SITE

__all__ = ["DEFAULT_TABLE_XY", "TABLE_HEIGHT", "Scene", "add_table", "apply_solver_options",
           "bean_pool", "box_walls", "first_toucher", "grasp_spec_from", "obj_id",
           "set_free_pose", "size_support", "tilt_from_vertical", "yaw_quat"]

#: Height of the table top above the room's floor (m): a standard 0.75 m table.
TABLE_HEIGHT = 0.75
#: Table top extent (x0, x1, y0, y1) in the robot base frame (m) when the spec gives none.
DEFAULT_TABLE_XY = (-0.3, 0.9, -1.0, 0.45)


def obj_id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise ValueError(f"task scene has no {kind.name[6:].lower()} {name!r}; "
                         "is the task MJCF in tasks/ complete?")
    return i


def yaw_quat(yaw: float) -> np.ndarray:
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


def tilt_from_vertical(v: np.ndarray) -> float:
    """Angle (deg) between a unit vector's line and the world z axis (in [0, 90])."""
    return float(np.degrees(np.arccos(min(1.0, abs(float(v[2]))))))


def size_support(spec: mujoco.MjSpec, body: str, top: list[float], half_xy: list[float],
                 yaw: float, table_z: float, board: str, column: str) -> None:
    """Sizes a static support (board on a column down to the table), top centre at `top`."""
    b = spec.body(body)
    b.pos = list(top)
    b.quat = list(yaw_quat(yaw))
    spec.geom(board).size = [half_xy[0], half_xy[1], 0.01]
    spec.geom(board).pos = [0.0, 0.0, -0.01]
    half_h = max(0.005, (top[2] - 0.02 - table_z) / 2)
    spec.geom(column).size = [max(0.01, half_xy[0] - 0.02), max(0.01, half_xy[1] - 0.02), half_h]
    spec.geom(column).pos = [0.0, 0.0, -0.02 - half_h]


def _visual_box(parent: mujoco.MjsBody, name: str, size, pos, rgba) -> None:
    g = parent.add_geom()
    g.name = name
    g.type = mujoco.mjtGeom.mjGEOM_BOX
    g.size = list(size)
    g.pos = list(pos)
    g.rgba = list(rgba)
    g.contype = g.conaffinity = 0
    g.mass = 0.0


def box_walls(spec: mujoco.MjSpec, prefix: str, faces: tuple[float, float, float, float],
              bottom: float, height: float, half_thick: float
              ) -> tuple[float, float, float, float]:
    """Sizes the four walls `<prefix>_wall_{back,front,right,left}` of a tray or bin: inner
    faces at `faces` (x0, x1, y0, y1, in its body's frame), from z `bottom` up by `height`,
    `2 * half_thick` thick; back and front span the corners. Returns the inside's centre and
    half sizes (cx, cy, hx, hy)."""
    x0, x1, y0, y1 = faces
    w = half_thick
    cx, cy, hx, hy = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 2, (y1 - y0) / 2
    zc, hz = bottom + height / 2, height / 2
    for side, pos, size in (("back", [x0 - w, cy, zc], [w, hy + 2 * w, hz]),
                            ("front", [x1 + w, cy, zc], [w, hy + 2 * w, hz]),
                            ("right", [cx, y0 - w, zc], [hx, w, hz]),
                            ("left", [cx, y1 + w, zc], [hx, w, hz])):
        g = spec.geom(f"{prefix}_wall_{side}")
        g.pos, g.size = pos, size
    return cx, cy, hx, hy


def add_table(spec: mujoco.MjSpec, table_z: float,
              xy: tuple[float, float, float, float] = DEFAULT_TABLE_XY) -> None:
    """Makes the Menagerie floor the table's collision surface at `table_z` (hidden, geom group
    3) and draws a table (top, legs), the room's floor `TABLE_HEIGHT` below it, and a mount
    under the robot when the table is lower than the robot's base."""
    floor = spec.geom("floor")
    floor.pos = [0.0, 0.0, table_z]
    floor.group = 3
    x0, x1, y0, y1 = xy
    cx, cy, hx, hy = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 2, (y1 - y0) / 2
    world = spec.worldbody
    _visual_box(world, "table_top", [hx, hy, 0.02], [cx, cy, table_z - 0.02],
                [0.62, 0.47, 0.33, 1.0])
    leg_h = (TABLE_HEIGHT - 0.04) / 2
    for i, (sx, sy) in enumerate([(-1, -1), (-1, 1), (1, -1), (1, 1)]):
        _visual_box(world, f"table_leg{i}", [0.03, 0.03, leg_h],
                    [cx + sx * (hx - 0.06), cy + sy * (hy - 0.06), table_z - 0.04 - leg_h],
                    [0.45, 0.33, 0.22, 1.0])
    room = world.add_geom()
    room.name = "room_floor"
    room.type = mujoco.mjtGeom.mjGEOM_PLANE
    room.size = [0.0, 0.0, 0.05]
    room.pos = [0.0, 0.0, table_z - TABLE_HEIGHT]
    room.material = "groundplane"
    room.contype = room.conaffinity = 0
    if table_z < 0.0:
        _visual_box(world, "robot_mount", [0.13, 0.13, -table_z / 2],
                    [-0.04, 0.0, table_z / 2], [0.3, 0.3, 0.32, 1.0])


def apply_solver_options(spec: mujoco.MjSpec, opt: dict[str, Any]) -> None:
    """Applies a spec's `[solver]` table: `solver` ("newton", "cg", "pgs"), `iterations`,
    `ls_iterations`, `tolerance`, `cone` ("pyramidal", "elliptic"), `jacobian` ("dense",
    "sparse", "auto": MuJoCo's default, sparse from 60 dofs on). (MuJoCo's island sleeping
    would make a resting rack cheaper, but which bodies sleep is not part of the
    physics state `mj_getState` saves, so a pickled env would not continue exactly.)"""
    if not opt:
        return
    if "solver" in opt:
        spec.option.solver = getattr(mujoco.mjtSolver, f"mjSOL_{opt['solver'].upper()}")
    if "iterations" in opt:
        spec.option.iterations = int(opt["iterations"])
    if "ls_iterations" in opt:
        spec.option.ls_iterations = int(opt["ls_iterations"])
    if "tolerance" in opt:
        spec.option.tolerance = float(opt["tolerance"])
    if opt.get("cone"):
        spec.option.cone = getattr(mujoco.mjtCone, f"mjCONE_{opt['cone'].upper()}")
    if opt.get("jacobian"):
        spec.option.jacobian = getattr(mujoco.mjtJacobian, f"mjJAC_{opt['jacobian'].upper()}")


class Scene:
    """Base of the RoboTasks scenes (one instance per env).

    Args:
        doc: the task spec (parsed TOML, see `clfd_bench.envs.robotasks.specs.load_task_spec`).
    """

    #: names of the bodies reported in the observation's `objects` [K, 7] (pos, quat).
    object_bodies: tuple[str, ...] = ()
    #: success needs the prop let go (by opening the gripper) first.
    needs_release = True

    def __init__(self, doc: dict[str, Any]):
        self.doc = doc
        self.scene = doc["scene"]
        self.success_cfg = doc["success"]
        self.grasp_spec = grasp_spec_from(doc["grasp"])
        self.table_z = float(self.scene.get("table_z", 0.0))
        self.record: dict[str, Any] = {}
        self.demo = 0

    # -- composition
    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        add_table(spec, self.table_z, tuple(self.scene.get("table_xy", DEFAULT_TABLE_XY)))
        apply_solver_options(spec, self.doc.get("solver", {}))

    def bind(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.grasp_site = obj_id(model, mujoco.mjtObj.mjOBJ_SITE, GRASP_SITE)
        self.object_ids = [obj_id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in self.object_bodies]

    # -- episode
    def place_held_prop(self, data: mujoco.MjData, grasp: Grasp) -> None:
        """Puts the held prop (a free body) where the grasp holds it: at the spec's
        `[grasp] prop_pos`, `prop_quat` in the grasp-site frame."""
        pos, quat = grasp.held_pose(data)
        set_free_pose(self.model, data, grasp.body_id, pos, quat)

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        """Places the props for `demo` (robot already placed, kinematics current)."""
        raise NotImplementedError

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        """Starts the episode's record (after `reset` and the grasp's `attach`)."""
        self.record = {}

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        """Updates the episode's record after a control step's physics."""

    def on_release(self, data: mujoco.MjData, grasp: Grasp) -> None:
        """Records the moment the prop is let go (`grasp.release_reason` says why)."""

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        """(success, task info) from the episode's record and the current state."""
        raise NotImplementedError

    def _demo_row(self, rows: np.ndarray) -> np.ndarray:
        """Demo j's row of a per-demo reference [N, ...] (its only row when it has one)."""
        return rows[self.demo if len(rows) > 1 else 0]

    def scene_state(self) -> dict[str, Any]:
        """Episode state beyond the physics state (for pickling)."""
        return {"demo": self.demo,
                "record": {k: (v.copy() if isinstance(v, np.ndarray) else v)
                           for k, v in self.record.items()}}

    def restore_scene_state(self, state: dict[str, Any]) -> None:
        self.demo = int(state.get("demo", 0))
        self.record = {k: (v.copy() if isinstance(v, np.ndarray) else v)
                       for k, v in state.get("record", {}).items()}

    def observation_space(self) -> dict[str, spaces.Space]:
        return {"objects": spaces.Box(-np.inf, np.inf, (len(self.object_bodies), 7), np.float64)}

    def observation(self, data: mujoco.MjData) -> dict[str, np.ndarray]:
        ids = self.object_ids
        return {"objects": np.concatenate([data.xpos[ids], data.xquat[ids]], axis=1)}


def first_toucher(model: mujoco.MjModel, data: mujoco.MjData, targets: np.ndarray,
                  ignore: np.ndarray) -> str | None:
    """The body (name) of the first geom in contact (touching or penetrating) with a geom of
    `targets`, skipping geoms of `ignore` (both boolean masks [ngeom]); None if there is none.
    (Scenes call it every control step until it finds one: the common answer, no contact with
    a target at all, takes one lookup of the contacts' geom pairs.)"""
    if data.ncon == 0:
        return None
    contact = data.contact
    pairs = contact.geom  # [ncon, 2]: geom1, geom2
    on_pair = targets[pairs]
    if not on_pair.any():
        return None
    g1, g2 = pairs[:, 0], pairs[:, 1]
    on = on_pair[:, 0] | on_pair[:, 1]
    other = np.where(on_pair[:, 0], g2, g1)
    hit = on & ~ignore[other] & (contact.dist <= 0.0)
    if not hit.any():
        return None
    g = int(other[np.flatnonzero(hit)[0]])
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.geom_bodyid[g])


def grasp_spec_from(g: dict[str, Any]) -> GraspSpec:
    """The `GraspSpec` of a spec's `[grasp]` table (grip: `contact`, `mu`, `grip_force`,
    `contact_radius`; compliant directions: `slip_joints` = [[name, lower, upper], ...])."""
    capacity = None
    if g.get("contact"):
        capacity = grip_capacity(g["contact"], mu=float(g.get("mu", 0.5)),
                                 grip_force=float(g.get("grip_force", 70.0)),
                                 radius=float(g.get("contact_radius", 0.0)))
    return GraspSpec(
        kind=g["kind"], body=g["body"], solref=tuple(g.get("solref", (0.01, 1.0))),
        capacity=capacity, filter_steps=int(g.get("filter_steps", 3)),
        max_slip=float(g.get("max_slip", 0.03)),
        max_slip_angle=float(np.radians(g.get("max_slip_angle_deg", 30.0))),
        slip_joints=tuple((str(n), float(lo), float(hi)) for n, lo, hi in
                          g.get("slip_joints", ())),
        closed_opening=float(g.get("closed_opening", 0.0)),
        exclude=tuple(g.get("exclude", ())),
        prop_pos=tuple(float(v) for v in g.get("prop_pos", (0.0, 0.0, 0.0))),
        prop_quat=tuple(float(v) for v in g.get("prop_quat", (1.0, 0.0, 0.0, 0.0))))


def bean_pool(scene: dict[str, Any], task: str) -> tuple[int, float, tuple[str, ...]]:
    """The beans of a scene's `[scene]` table: how many (`n_beans`, at least 1), their radius
    (m) and body names `bean0..`."""
    n = int(scene["n_beans"])
    if n < 1:
        raise ValueError(f"{task} needs n_beans >= 1, got {n}")
    return n, float(scene["bean_radius"]), tuple(f"bean{i}" for i in range(n))
