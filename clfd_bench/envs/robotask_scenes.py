"""The RoboTasks scenes: where the props are for a demo and what counts as success.

Each scene reads its numbers from the task spec (`tasks/<task>.toml`, see
`clfd_bench.envs.robotask_specs`), edits the composed `MjSpec` (table, poses and sizes the spec
derives from the demonstrations), places the props at `reset` for demo j (the held prop at the
grasp point, the rest where demo j needs it), follows the episode step by step (`track`) and
decides success from what happened in the whole episode, as an observer would, not from the
end state alone:

- openbox (held: the lid's edge, welded; it may slide and turn in the fingers as far as the
  demos do): the grasp opens the lid to >= `min_open_angle_deg` (demo j's own) while holding
  it, the gripper then lets go (the lid never slipped out), and the lid is still open at the
  end;
- bottle2shelf (held: the bottle, welded): held until the gripper opens; at that moment its
  lowest point is at most `max_release_height` above the shelf and its centre within
  `place_radius` of where demo j lets it go; at the end it lies on the shelf;
- platestandingtolying (held: the plate): as the bottle, on the platform; and the dish rack is
  never (at any step) moved more than `max_rack_shift` or tilted more than
  `max_rack_tilt_deg`;
- pouring (held: the cup, never let go): the cup never slips; it is emptied where demo j
  empties it (where its mouth is, on average, as the beans leave it: within `pour_radius` of
  demo j's); >= `min_fraction` of the beans are in the container at the end and at most
  `max_spilled_fraction` ever landed outside it (on the table, the container's rim, ...).
- wineglass (held: the glass, by the stem, welded; RoboTasks9): the drying tray it lies in is
  never (at any step) moved more than `max_tray_shift` or tilted more than
  `max_tray_tilt_deg`; held until the gripper opens, at that moment its lowest point at most
  `max_release_height` above the shelf and its foot within `place_radius` of where demo j lets
  it go; at the end it stands upright on the shelf (axis within `max_tilt_deg` of vertical,
  bowl up, the foot's bottom within [`min_height`, `max_height`] of the shelf's top).
- obstaclerotate (held: a box, welded; RoboTasks9): the obstacle is never touched (by the box
  or the robot) at any step; while held and beside the obstacle (its centre lower than the
  obstacle's top), the box was turned about the vertical, in the demos' direction
  (`turn_sign`), by at least `min_turn_deg`, and turned back to within
  `max_end_turn_deg` of its start heading when let go (the task is to turn it on the way: the
  demos turn it 58-72 deg and back; nothing in the scene forces the turn); held until the
  gripper opens, let go low and where demo j lets go (as the bottle); at the end the box lies on
  the shelf (within `max_tilt_deg` of level, its
  lowest point within [`min_height`, `max_height`] of the shelf's top).
- pan2stove (held: the pan, by its handle, welded; RoboTasks9): as the glass, with a pan rack
  (`max_rack_shift`, `max_rack_tilt_deg`) and a stove: at the end the pan lies flat on the
  stove (its bottom down, within `max_tilt_deg` of level).
- matfolding (held: the middle of a mat's near edge, welded, turning between the pads on a ball
  joint as far as the demos turn it; RoboTasks9): the mat is judged relative to itself, as an
  observer sees it (a real mat lifted by one edge slides towards the hand too, so the drag is
  no fault): held until the gripper opens, at that moment the near edge within `place_radius`
  of where demo j lets it go in the room (that point does not depend on the drag); at the end
  the far half lies flat on the table with at least `min_turned_strips` strips of the near half
  turned over onto it in one layer, and the far half was never dragged further than
  `max_drag` from where it lay (`mat_checks`).
- scoop (held: a scoop, by its handle, welded, never let go; RoboTasks9): the scoop never
  slips, and neither it nor the robot ever touches the bin (at any step); at the end (1 s after
  the trajectory) the bowl is out of the bin (its lowest point above the rim), its opening
  within `max_tilt_deg` of facing up, at least `min_beans` beans in it; at most `max_spilled`
  beans ever landed outside the bin (`scoop_checks`). Where the scoop ends is not judged:
  nothing in the scene marks demo j's end.
  The bin's contents are grain sites that become beans as the bowl takes them in over its lip
  (`ScoopScene`).

Every scene stands on a table (`[scene] table_z`, the height of its top in the robot base frame;
the robot stands on it, on a mount when the table is lower than the robot's base). The table top
is a collision plane (the Menagerie floor, moved and hidden in geom group 3) drawn as a wooden
top on four legs above the room's floor.

`success` only reads the records `track` keeps, so it is cheap at every step. The openbox,
bottle2shelf, platestandingtolying, pouring, wineglass, pan2stove and obstaclerotate scenes
return the criteria above as `info["checks"]`: one `clfd_bench.envs.checks.Check` (as JSON) per
criterion, with its measured value and bound in m, deg or counts; their success is exactly all
of them passing (`docs/execution.md`, "Where every bound comes from").
`clfd_bench.execution.rollout.rollout` decides after the trajectory and the settling time.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces

from clfd_bench.envs.checks import Check, checks_json
from clfd_bench.sim.grasp import Grasp, GraspSpec, grip_capacity
from clfd_bench.sim.robot import GRASP_SITE
from clfd_bench.sim.scene_fit import lowest_point

#: Height of the table top above the room's floor (m): a standard 0.75 m table.
TABLE_HEIGHT = 0.75
#: Table top extent (x0, x1, y0, y1) in the robot base frame (m) when the spec gives none.
DEFAULT_TABLE_XY = (-0.3, 0.9, -1.0, 0.45)


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


def _visual_box(parent: mujoco.MjsBody, name: str, size, pos, rgba) -> None:
    g = parent.add_geom()
    g.name = name
    g.type = mujoco.mjtGeom.mjGEOM_BOX
    g.size = list(size)
    g.pos = list(pos)
    g.rgba = list(rgba)
    g.contype = g.conaffinity = 0
    g.mass = 0.0


def _box_walls(spec: mujoco.MjSpec, prefix: str, faces: tuple[float, float, float, float],
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
        doc: the task spec (parsed TOML, see `clfd_bench.envs.robotask_specs.load_task_spec`).
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
    `targets`, skipping geoms of `ignore` (both boolean masks [ngeom]); None if there is none."""
    if data.ncon == 0:
        return None
    g1, g2 = data.contact.geom1, data.contact.geom2
    on = targets[g1] | targets[g2]
    if not on.any():
        return None
    other = np.where(targets[g1], g2, g1)
    hit = on & ~ignore[other] & (data.contact.dist <= 0.0)
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


class OpenBoxScene(Scene):
    """A storage box whose lid turns on friction hinges (it stays where it is left). The gripper
    pinches the lid's front edge (`lid_handle`, welded to the hand): the edge may slide in the
    fingers (radially and along the hinge) and turn between them as far as the demonstrations
    need (`[grasp] slip_joints`), no further: past that it slips out. Placed by `[scene]
    hinge_pos`, `hinge_yaw_deg` (the hinge axis fitted to the demos' arcs)."""

    object_bodies = ("lid", "lid_handle")

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        box = spec.body("box")
        box.pos = list(self.scene["hinge_pos"])
        box.quat = list(_yaw_quat(np.radians(self.scene["hinge_yaw_deg"])))

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.box = _id(model, mujoco.mjtObj.mjOBJ_BODY, "box")
        self.lid = _id(model, mujoco.mjtObj.mjOBJ_BODY, "lid")
        self.handle = _id(model, mujoco.mjtObj.mjOBJ_BODY, "lid_handle")
        j = {n: _id(model, mujoco.mjtObj.mjOBJ_JOINT, n)
             for n in ("lid_hinge", "handle_axial", "handle_radial", "handle_turn")}
        self.qadr = {n: int(model.jnt_qposadr[i]) for n, i in j.items()}
        self.jrange = {n: model.jnt_range[i].copy() for n, i in j.items()}
        self.handle_rest = model.body_pos[self.handle].copy()  # in the lid frame: (x, r, h)

    def lid_angle(self, data: mujoco.MjData) -> float:
        """Lid hinge angle, degrees (0 closed, positive open)."""
        return float(np.degrees(data.qpos[self.qadr["lid_hinge"]]))

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        # The grasp point in the hinge frame decides the lid angle and the edge's place in the
        # fingers (the handle's slides); the handle takes the hand's orientation (ball joint).
        rot = data.xmat[self.box].reshape(3, 3)
        local = rot.T @ (data.site_xpos[self.grasp_site] - data.xpos[self.box])
        x0, r0, h = self.handle_rest
        rho2 = local[1] ** 2 + local[2] ** 2
        r = float(np.sqrt(max(rho2 - h * h, 1e-12)))
        angle = float(np.arctan2(local[2], local[1]) - np.arctan2(h, r))
        lo, hi = self.jrange["lid_hinge"]
        if not lo <= angle <= hi:
            raise ValueError(f"demo {demo}'s start puts the gripper at lid angle "
                             f"{np.degrees(angle):.1f} deg, outside the hinge's range: the openbox "
                             "scene does not fit this demo; regenerate tasks/openbox.toml")
        data.qpos[self.qadr["lid_hinge"]] = angle
        data.qpos[self.qadr["handle_radial"]] = r - r0
        data.qpos[self.qadr["handle_axial"]] = local[0] - x0
        mujoco.mj_kinematics(self.model, data)
        lid_q = data.xquat[self.lid]
        hand_q = data.xquat[grasp.hand_id]
        turn = np.empty(4)
        inv = np.empty(4)
        mujoco.mju_negQuat(inv, lid_q)
        mujoco.mju_mulQuat(turn, inv, hand_q)
        adr = self.qadr["handle_turn"]
        data.qpos[adr:adr + 4] = turn / np.linalg.norm(turn)
        self.demo = demo

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        angle = self.lid_angle(data)
        need = np.atleast_1d(np.asarray(self.success_cfg["min_open_angle_deg"], dtype=float))
        self.record = {"max_held_angle": angle, "release_angle": None,
                       "need": float(self._demo_row(need))}

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        if grasp.held(data):
            angle = self.lid_angle(data)
            if angle > self.record["max_held_angle"]:
                self.record["max_held_angle"] = angle

    def on_release(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.record["release_angle"] = self.lid_angle(data)

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        c = self.success_cfg
        angle = self.lid_angle(data)
        need = self.record["need"]
        held_max = float(self.record["max_held_angle"])
        checks = [
            Check("lid_opened", held_max, need, ">=", "deg",
                  "largest lid angle while the grasp held it, vs demo j's end less 1.5 cm of arc"),
            Check.flag("let_go", grasp.release_reason == "opened",
                       "the gripper opened (the lid's edge did not slip out)"),
            Check("lid_stays_open", angle, need - float(c["stay_open_tolerance_deg"]), ">=",
                  "deg", "lid angle at the end"),
        ]
        ok = all(ch.passed for ch in checks)
        return ok, {"lid_angle_deg": angle, "lid_max_held_angle_deg": held_max,
                    "lid_open_needed_deg": need, "lid_opened_by_grasp": bool(held_max >= need),
                    "checks": checks_json(checks)}


class KnockWatch:
    """Follows a free body that must not be knocked (a dish rack, a drying tray): its largest
    shift (m) from where it was put at reset and its largest tilt (deg) at any step."""

    def __init__(self, body: int):
        self.body = body
        self.start = np.zeros(3)

    def place(self, start: np.ndarray) -> None:
        """Where the body was put at reset (world position [3])."""
        self.start = np.asarray(start, dtype=float).copy()

    def track(self, data: mujoco.MjData, rec: dict[str, Any], name: str) -> None:
        """Updates `rec[f"max_{name}_shift"]` (m) and `rec[f"max_{name}_tilt_deg"]`."""
        p, s0 = data.xpos[self.body], self.start
        shift = math.sqrt((p[0] - s0[0]) ** 2 + (p[1] - s0[1]) ** 2 + (p[2] - s0[2]) ** 2)
        cos_tilt = abs(float(data.xmat[self.body, 8]))  # the body's z axis' world z component
        key_shift, key_tilt = f"max_{name}_shift", f"max_{name}_tilt_deg"
        if shift > rec[key_shift]:
            rec[key_shift] = shift
        tilt = math.degrees(math.acos(min(1.0, cos_tilt)))
        if tilt > rec[key_tilt]:
            rec[key_tilt] = tilt


def knock_checks(name: str, rec: dict[str, Any], cfg: dict[str, Any]) -> list[Check]:
    """`<name>_shift` (m) and `<name>_tilt` (deg) checks of a `KnockWatch` record against the
    spec's `max_<name>_shift`, `max_<name>_tilt_deg`."""
    shift, tilt = f"max_{name}_shift", f"max_{name}_tilt_deg"
    return [Check(f"{name}_shift", float(rec[shift]), float(cfg[shift]), "<=", "m",
                  f"the {name}'s largest shift at any step"),
            Check(f"{name}_tilt", float(rec[tilt]), float(cfg[tilt]), "<=", "deg",
                  f"the {name}'s largest tilt at any step")]


class _PlaceScene(Scene):
    """A held prop laid on a support (shelf, platform): the release and the end state count."""

    prop = ""
    support = ""
    support_half_key = ""
    #: (board, column) geoms of the support, sized from `[scene] <support>_top`,
    #: `support_half_key` and `<support>_yaw_deg`.
    support_geoms: tuple[str, str] = ("", "")

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        _support(spec, self.support, s[self.support + "_top"], s[self.support_half_key],
                 np.radians(s.get(self.support + "_yaw_deg", 0.0)), self.table_z,
                 *self.support_geoms)

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.prop_id = _id(model, mujoco.mjtObj.mjOBJ_BODY, self.prop)
        self.support_id = _id(model, mujoco.mjtObj.mjOBJ_BODY, self.support)

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.demo = demo
        self.place_held_prop(data, grasp)

    def prop_centre(self, data: mujoco.MjData) -> np.ndarray:
        """[3] the prop's centre (what `place_radius` is measured on)."""
        return data.xipos[self.prop_id]

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.record = {"release_height": None, "release_offset": None, "release_point": None}

    def on_release(self, data: mujoco.MjData, grasp: Grasp) -> None:
        mujoco.mj_kinematics(self.model, data)
        top = data.xpos[self.support_id][2]
        self.record["release_height"] = lowest_point(self.model, data, self.prop) - float(top)
        centre = np.asarray(self.scene["place_centre"], dtype=float).reshape(-1, 2)
        centre = self._demo_row(centre)
        point = self.prop_centre(data)[:2].copy()
        # where it is let go (x, y): the derivation's demos' release spread is measured on it
        self.record["release_point"] = point
        self.record["release_offset"] = float(np.linalg.norm(point - centre))

    def _placed(self, data: mujoco.MjData, grasp: Grasp) -> tuple[list[Check], dict[str, Any]]:
        """The release's checks (let go by opening the gripper, not held now; low; near demo
        j's release point) and their info entries."""
        c = self.success_cfg
        h, off = self.record["release_height"], self.record["release_offset"]
        h = None if h is None else float(h)
        off = None if off is None else float(off)
        checks = [
            Check.flag("let_go", grasp.release_reason == "opened" and not grasp.held(data),
                       "the gripper opened (the prop did not slip out) and holds nothing")]
        for name, value, key, note in (
                ("release_height", h, "max_release_height",
                 "the prop's lowest point above the support's top when the gripper opens"),
                ("release_offset", off, "place_radius",
                 "horizontal distance from where demo j lets the prop go")):
            if key in c:
                checks.append(Check(name, value, float(c[key]), "<=", "m", note))
            else:  # a provisional spec while deriving (the prop is never let go there)
                checks.append(Check.flag(name, False, f"the spec has no [success] {key}"))
        return checks, {"release_height": h, "release_offset": off}

    def _rest_checks(self, on_top: bool, tilt: float, tilt_note: str, height: float,
                     height_note: str) -> list[Check]:
        """The end state's checks: on the support, tilt (deg) within `max_tilt_deg`, height
        (m) above the support's top within [`min_height`, `max_height`]."""
        c = self.success_cfg
        return [
            Check.flag(f"on_{self.support}", on_top, f"over the {self.support}'s top"),
            Check("tilt", tilt, float(c["max_tilt_deg"]), "<=", "deg", tilt_note),
            Check("rest_height_min", height, float(c["min_height"]), ">=", "m", height_note),
            Check("rest_height_max", height, float(c["max_height"]), "<=", "m", height_note),
        ]

    def _on_support(self, data: mujoco.MjData, point: np.ndarray) -> tuple[bool, float]:
        rot = data.xmat[self.support_id].reshape(3, 3)
        local = rot.T @ (point - data.xpos[self.support_id])
        half = self.scene[self.support_half_key]
        return bool(abs(local[0]) <= half[0] and abs(local[1]) <= half[1]), float(local[2])


class BottleScene(_PlaceScene):
    """A bottle held upright by its neck; a shelf where the demos end. Success: see the module
    docstring (released by opening, low and where the demos release it; lying on the shelf)."""

    object_bodies = ("bottle",)
    prop, support, support_half_key = "bottle", "shelf", "shelf_half_size"
    support_geoms = ("shelf_board", "shelf_support")

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        checks, info = self._placed(data, grasp)
        on_top, height = self._on_support(data, data.xipos[self.prop_id])
        axis = data.xmat[self.prop_id].reshape(3, 3)[:, 2]
        tilt = 90.0 - _tilt_from_vertical(axis)  # from horizontal
        checks += self._rest_checks(on_top, tilt, "the bottle's axis from horizontal", height,
                                    "the bottle's centre above the shelf's top")
        info.update({"bottle_tilt_deg": tilt, "bottle_height": height, "on_shelf": on_top,
                     "checks": checks_json(checks)})
        return all(ch.passed for ch in checks), info


class PlateScene(_PlaceScene):
    """A plate standing in a dish rack (a base with four pegs, one free body); a platform where
    the demos end. Success: see the module docstring (the rack never knocked; released by
    opening, low and where the demos release it; lying on the platform)."""

    object_bodies = ("plate", "rack")
    prop, support, support_half_key = "plate", "platform", "platform_half_size"
    support_geoms = ("platform_top", "platform_support")
    pegs = ("rack_peg1", "rack_peg2", "rack_peg3", "rack_peg4")

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        # The rack (rack frame: origin on the table under the plate's centre): pegs at
        # `block_offsets`, from the base up to `block_height` above the table; the base spans
        # the pegs' footprint.
        t = float(s.get("rack_base_thickness", 0.005))
        height = float(s.get("block_height", 0.024))
        offsets = np.asarray(s["block_offsets"], dtype=float)
        peg = spec.geom(self.pegs[0]).size
        for name, (x, y) in zip(self.pegs, offsets, strict=True):
            g = spec.geom(name)
            g.size = [peg[0], peg[1], (height - t) / 2]
            g.pos = [float(x), float(y), t + (height - t) / 2]
        lo, hi = offsets.min(0) - [peg[0], peg[1]], offsets.max(0) + [peg[0], peg[1]]
        base = spec.geom("rack_base")
        base.size = [float(hi[0] - lo[0]) / 2, float(hi[1] - lo[1]) / 2, t / 2]
        base.pos = [float(hi[0] + lo[0]) / 2, float(hi[1] + lo[1]) / 2, t / 2]

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.disc = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "plate_disc")
        self.rack = _id(model, mujoco.mjtObj.mjOBJ_BODY, "rack")
        self.rack_watch = KnockWatch(self.rack)

    def prop_centre(self, data: mujoco.MjData) -> np.ndarray:
        return data.geom_xpos[self.disc]

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.demo = demo
        self.place_held_prop(data, grasp)
        mujoco.mj_kinematics(self.model, data)
        # The rack stands on the table under the plate, turned with the plate's plane.
        centre = data.geom_xpos[self.disc]
        in_plane = data.xmat[grasp.body_id].reshape(3, 3)[:, 0]
        yaw = float(np.arctan2(in_plane[1], in_plane[0]))
        pos = np.array([centre[0], centre[1], self.table_z])
        set_free_pose(self.model, data, self.rack, pos, _yaw_quat(yaw))
        self.rack_watch.place(pos)

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        super().start_record(data, grasp)
        self.record.update({"max_rack_shift": 0.0, "max_rack_tilt_deg": 0.0})

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.rack_watch.track(data, self.record, "rack")

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        c = self.success_cfg
        rec = self.record
        knock = knock_checks("rack", rec, c)
        checks, info = self._placed(data, grasp)
        on_top, height = self._on_support(data, data.geom_xpos[self.disc])
        normal = data.xmat[grasp.body_id].reshape(3, 3)[:, 1]
        tilt = _tilt_from_vertical(normal)
        checks = knock + checks + self._rest_checks(
            on_top, tilt, "the plate's face from horizontal", height,
            "the plate's centre above the platform's top")
        info.update({"plate_tilt_deg": tilt, "plate_height": height, "on_platform": on_top,
                     "max_rack_shift": float(rec["max_rack_shift"]),
                     "max_rack_tilt_deg": float(rec["max_rack_tilt_deg"]),
                     "rack_in_place": all(ch.passed for ch in knock),
                     "checks": checks_json(checks)})
        return all(ch.passed for ch in checks), info

    def scene_state(self) -> dict[str, Any]:
        state = super().scene_state()
        state["rack_start"] = self.rack_watch.start.copy()
        return state

    def restore_scene_state(self, state: dict[str, Any]) -> None:
        super().restore_scene_state(state)
        self.rack_watch.place(state["rack_start"])


class _TrayPlaceScene(_PlaceScene):
    """A held prop taken out of a free tray or rack (a base and four walls, one body named
    `tray`: its geoms `<tray>_base`, `<tray>_wall_{back,front,right,left}`) and laid on a
    support. The tray's frame: origin on what it stands on (`[scene]
    stand_top`'s height if the scene has a stand, else the table) under the grasp point at the
    start, x along the held prop's axis `tray_axis` (its horizontal part); the walls' inner
    faces at `[scene] tray_walls` (x_lo, x_hi, y_lo, y_hi), their tops `tray_wall_height` above
    the base. Success needs the tray never knocked (`[success] max_<tray>_shift`,
    `max_<tray>_tilt_deg`) and what `placed_ok` says of the prop."""

    tray = "tray"
    #: the prop body's axis (0 x, 1 y, 2 z) the tray's x follows.
    tray_axis = 0

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        if "stand_top" in s:
            _support(spec, "stand", s["stand_top"], s["stand_half_size"],
                     np.radians(s.get("stand_yaw_deg", 0.0)), self.table_z, "stand_top",
                     "stand_support")
        t = float(s.get("tray_base_thickness", 0.005))
        w = float(s.get("tray_wall_thickness", 0.008)) / 2
        height = float(s["tray_wall_height"])
        faces = tuple(float(v) for v in s["tray_walls"])
        cx, cy, hx, hy = _box_walls(spec, self.tray, faces, t, height, w)
        base = spec.geom(f"{self.tray}_base")
        base.size = [hx + 2 * w, hy + 2 * w, t / 2]
        base.pos = [cx, cy, t / 2]

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.tray_id = _id(model, mujoco.mjtObj.mjOBJ_BODY, self.tray)
        self.tray_watch = KnockWatch(self.tray_id)

    def tray_floor(self) -> float:
        """World z of what the tray stands on."""
        return float(self.scene["stand_top"][2]) if "stand_top" in self.scene else self.table_z

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.demo = demo
        self.place_held_prop(data, grasp)
        mujoco.mj_kinematics(self.model, data)
        grasp_pt = data.site_xpos[self.grasp_site]
        axis = data.xmat[grasp.body_id].reshape(3, 3)[:, self.tray_axis]
        yaw = float(np.arctan2(axis[1], axis[0]))
        pos = np.array([grasp_pt[0], grasp_pt[1], self.tray_floor()])
        set_free_pose(self.model, data, self.tray_id, pos, _yaw_quat(yaw))
        self.tray_watch.place(pos)

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        super().start_record(data, grasp)
        self.record.update({f"max_{self.tray}_shift": 0.0, f"max_{self.tray}_tilt_deg": 0.0})

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.tray_watch.track(data, self.record, self.tray)

    def placed_ok(self, data: mujoco.MjData) -> tuple[list[Check], dict[str, Any]]:
        """The checks that the prop now lies / stands on the support as the task wants
        (`_rest_checks`), and their info entries."""
        raise NotImplementedError

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        rec = self.record
        knock = knock_checks(self.tray, rec, self.success_cfg)
        placed, info = self._placed(data, grasp)
        resting, more = self.placed_ok(data)
        checks = knock + placed + resting
        shift, tilt = f"max_{self.tray}_shift", f"max_{self.tray}_tilt_deg"
        info.update(more)
        info.update({shift: float(rec[shift]), tilt: float(rec[tilt]),
                     f"{self.tray}_in_place": all(ch.passed for ch in knock),
                     "checks": checks_json(checks)})
        return all(ch.passed for ch in checks), info

    def scene_state(self) -> dict[str, Any]:
        state = super().scene_state()
        state["tray_start"] = self.tray_watch.start.copy()
        return state

    def restore_scene_state(self, state: dict[str, Any]) -> None:
        super().restore_scene_state(state)
        self.tray_watch.place(state["tray_start"])


class GlassScene(_TrayPlaceScene):
    """A wine glass lying in a drying tray on a stand; a shelf where the demos stand it.
    Success: see the module docstring (the tray never knocked; released by opening, low and
    where the demos release it; standing upright on the shelf)."""

    object_bodies = ("glass", "tray")
    prop, support, support_half_key = "glass", "shelf", "shelf_half_size"
    support_geoms = ("shelf_board", "shelf_support")

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.foot = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "glass_foot")
        self._foot_half = float(model.geom_size[self.foot][1])

    def prop_centre(self, data: mujoco.MjData) -> np.ndarray:
        """[3] the centre of the glass's foot disc."""
        return data.geom_xpos[self.foot]

    def foot_bottom(self, data: mujoco.MjData) -> np.ndarray:
        """[3] the centre of the foot's bottom face (the glass's axis points from it to the
        bowl, the glass body's x)."""
        axis = data.xmat[self.prop_id].reshape(3, 3)[:, 0]
        return data.geom_xpos[self.foot] - self._foot_half * axis

    def placed_ok(self, data: mujoco.MjData) -> tuple[list[Check], dict[str, Any]]:
        on_top, height = self._on_support(data, self.foot_bottom(data))
        axis = data.xmat[self.prop_id].reshape(3, 3)[:, 0]
        tilt = float(np.degrees(np.arccos(np.clip(axis[2], -1.0, 1.0))))  # 180: upside down
        checks = self._rest_checks(on_top, tilt, "the glass's axis from upright (180: upside "
                                   "down)", height, "the foot's bottom above the shelf's top")
        return checks, {"glass_tilt_deg": tilt, "glass_foot_height": height, "on_shelf": on_top}


class PanScene(_TrayPlaceScene):
    """A pan standing on its rim in a pan rack (a base and four walls, one free body); a stove
    where the demos set it down. Success: see the module docstring (the rack never knocked;
    released by opening, low and where the demos release it; lying flat on the stove, its
    bottom down)."""

    object_bodies = ("pan", "rack")
    prop, support, support_half_key = "pan", "stove", "stove_half_size"
    support_geoms = ("stove_top", "stove_support")
    tray, tray_axis = "rack", 1

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.bottom = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "pan_bottom")
        self._bottom_half = float(model.geom_size[self.bottom][1])

    def prop_centre(self, data: mujoco.MjData) -> np.ndarray:
        """[3] the centre of the pan's bottom."""
        return data.geom_xpos[self.bottom]

    def placed_ok(self, data: mujoco.MjData) -> tuple[list[Check], dict[str, Any]]:
        z = data.xmat[self.prop_id].reshape(3, 3)[:, 2]  # from the rim to the bottom
        outer = data.geom_xpos[self.bottom] + self._bottom_half * z
        on_top, height = self._on_support(data, outer)
        tilt = float(np.degrees(np.arccos(np.clip(-z[2], -1.0, 1.0))))  # 180: upside down
        checks = self._rest_checks(on_top, tilt, "the pan's bottom from facing down (180: "
                                   "upside down)", height,
                                   "the bottom's outer centre above the stove's top")
        return checks, {"pan_tilt_deg": tilt, "pan_bottom_height": height, "on_stove": on_top}


class ObstacleScene(_PlaceScene):
    """A box carried around an obstacle (a static block standing in the demos' bend), turned
    about the vertical on the way, and put down on a shelf. Success: see the module docstring
    (the obstacle never touched by the box or the arm; the box turned as the demos turn it;
    released by opening, low and where the demos release it; lying on the shelf)."""

    object_bodies = ("object",)
    prop, support, support_half_key = "object", "shelf", "shelf_half_size"
    support_geoms = ("shelf_board", "shelf_support")

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        x0, x1, y0, y1 = (float(v) for v in s["obstacle_xy"])
        half_h = (float(s["obstacle_top"]) - self.table_z) / 2
        spec.body("obstacle").pos = [(x0 + x1) / 2, (y0 + y1) / 2, self.table_z]
        g = spec.geom("obstacle_box")
        g.size = [(x1 - x0) / 2, (y1 - y0) / 2, half_h]
        g.pos = [0.0, 0.0, half_h]

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.obstacle_geom = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "obstacle_box")
        self._is_obstacle = np.zeros(model.ngeom, dtype=bool)
        self._is_obstacle[self.obstacle_geom] = True
        self._is_world_geom = model.geom_bodyid == 0  # the table plane it stands on
        self._obstacle_top = float(self.scene["obstacle_top"])
        self._turn_sign = float(self.success_cfg.get("turn_sign", 1.0))

    def _heading(self, data: mujoco.MjData) -> float:
        """Heading (rad) of the box's long axis (its x) seen from above."""
        x = data.xmat[self.prop_id].reshape(3, 3)[:, 0]
        return math.atan2(float(x[1]), float(x[0]))

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        super().start_record(data, grasp)
        self.record.update({"obstacle_touched_by": None, "heading": self._heading(data),
                            "turn": 0.0, "max_turn_deg": 0.0, "release_turn_deg": None})

    def on_release(self, data: mujoco.MjData, grasp: Grasp) -> None:
        super().on_release(data, grasp)
        self.record["release_turn_deg"] = math.degrees(self.record["turn"])

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        """How far the held box has turned about the vertical, in the demos' direction (the
        heading unwrapped step by step), at most while its centre is lower than the obstacle's
        top (beside it, where the demos turn it); the first body that touches the obstacle
        (anything but the table it stands on)."""
        rec = self.record
        if grasp.held(data):  # the turn counts while the box passes beside the obstacle
            heading = self._heading(data)
            step = (heading - rec["heading"] + math.pi) % (2 * math.pi) - math.pi
            rec["heading"] = heading
            rec["turn"] += step
            turned = math.degrees(rec["turn"]) * self._turn_sign
            beside = data.xipos[self.prop_id][2] < self._obstacle_top
            if beside and turned > rec["max_turn_deg"]:
                rec["max_turn_deg"] = turned
        if rec["obstacle_touched_by"] is None:
            rec["obstacle_touched_by"] = first_toucher(self.model, data, self._is_obstacle,
                                                       self._is_world_geom)

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        c = self.success_cfg
        on_top, _ = self._on_support(data, data.xipos[self.prop_id])
        height = lowest_point(self.model, data, self.prop) - float(self.scene["shelf_top"][2])
        z = data.xmat[self.prop_id].reshape(3, 3)[:, 2]
        tilt = _tilt_from_vertical(z)
        touched = self.record["obstacle_touched_by"]
        back = self.record["release_turn_deg"]
        turn = float(self.record["max_turn_deg"])
        checks = [
            Check.flag("obstacle_untouched", touched is None,
                       "nothing but the table touched the obstacle" if touched is None
                       else f"touched by {touched}"),
            Check("turn", turn, float(c["min_turn_deg"]), ">=", "deg",
                  "the box's largest turn the demos' way while held beside the obstacle"),
            Check("end_turn", None if back is None else abs(float(back)),
                  float(c["max_end_turn_deg"]), "<=", "deg",
                  "the box's heading from its start heading when let go"),
        ]
        placed, info = self._placed(data, grasp)
        checks += placed + self._rest_checks(on_top, tilt, "the box's top face from level",
                                             height, "the box's lowest point above the shelf")
        info.update({"object_tilt_deg": tilt, "object_height": height, "on_shelf": on_top,
                     "obstacle_touched_by": touched, "object_max_turn_deg": turn,
                     "object_release_turn_deg": back, "checks": checks_json(checks)})
        return all(ch.passed for ch in checks), info


#: The checks that say the mat is folded in half (`mat_checks`); a path that passes them folds
#: the mat, whatever else it does (`clfd_bench.execution.replay.VALID_ALTERNATIVES`).
MAT_FOLD_CHECKS = ("far_half_height", "turned_strips")


def mat_checks(release_reason: str | None, release_offset: float | None, far_half_height: float,
               turned_strips: int, drag: float, cfg: dict[str, Any]) -> list[Check]:
    """MatFolding's success checks, in the order they are judged (success: every one passes).

    Args:
        release_reason: how the edge left the fingers: "opened" (the gripper let it go),
            "slipped", or None (still held).
        release_offset: distance (m) from the near edge's middle, when the gripper opened, to
            where demo j lets it go in the room; None when it was never let go.
        far_half_height: the far half's middle plane above the table top (m), now.
        turned_strips: strips of the near half lying turned over on the far half, now.
        drag: the far half's largest horizontal shift from where it lay at the start (m).
        cfg: the spec's `[success]`: `place_radius`, `max_layer_height`, `min_turned_strips`,
            `max_drag`.

    Returns:
        `held_until_opened` (flag), `release_offset` <= `place_radius` (m), `far_half_height`
        <= `max_layer_height` (m), `turned_strips` >= `min_turned_strips`, `drag` <=
        `max_drag` (m).
    """
    return [
        Check.flag("held_until_opened", release_reason == "opened",
                   f"released: {release_reason}"),
        Check("release_offset", release_offset, float(cfg["place_radius"]), "<=", "m",
              "the edge let go from where demo j lets it go, in the room"),
        Check("far_half_height", float(far_half_height), float(cfg["max_layer_height"]), "<=",
              "m", "the far half flat on the table"),
        Check("turned_strips", float(turned_strips), float(cfg["min_turned_strips"]), ">=", "",
              "strips turned over onto the far half"),
        Check("drag", float(drag), float(cfg["max_drag"]), "<=", "m",
              "the far half's largest shift on the table"),
    ]


class MatScene(Scene):
    """A mat (a rigid far half `mat0` and a chain of strips hinged about x, `tasks/matfolding.xml`)
    lying on the table, pinched at its near edge (`mat_pinch`, welded to the hand; the edge
    turns between the pads on a ball joint, as far as the grasp's slip bound allows) and folded
    in half. Success: `mat_checks` (held until the gripper opens, let go where demo j lets go in
    the room; at the end folded in half; never dragged further than the demos drag it plus a
    margin). The mat is judged relative to itself, not by where on the table it ends: the demos
    themselves drag it (lifting the edge 8 cm while moving it 1 cm pulls the mat towards it) by
    8-14 cm in the replays (`max_root_shift`), and how far depends on the path (the strip chain
    exaggerates that: a `flexcomp` cloth on the same paths slides 1-3 cm, docs/execution.md). A
    path that folds the mat so is a valid alternative to demo j's."""

    object_bodies = ("mat0", "mat_pinch")

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.strips = []
        k = 0
        while mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"mat{k}") >= 0:
            self.strips.append(_id(model, mujoco.mjtObj.mjOBJ_BODY, f"mat{k}"))
            k += 1
        if len(self.strips) < 4:
            raise ValueError("the matfolding scene needs a plate mat0 and a chain of at least "
                             "3 strips mat1..")
        self.root = self.strips[0]
        self.pinch = _id(model, mujoco.mjtObj.mjOBJ_BODY, "mat_pinch")
        self.hinges = [int(model.jnt_qposadr[_id(model, mujoco.mjtObj.mjOBJ_JOINT,
                                                  f"mat_hinge{k}")])
                       for k in range(1, len(self.strips))]
        self.turn_adr = int(model.jnt_qposadr[_id(model, mujoco.mjtObj.mjOBJ_JOINT,
                                                   "pinch_turn")])
        plate = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "mat0_geom")
        strip = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "mat1_geom")
        self.half_length = 2.0 * float(model.geom_size[plate][1])  # the far half, along y
        self.width = 2.0 * float(model.geom_size[strip][1])  # a strip of the near half
        self.half_thick = float(model.geom_size[plate][2])
        self.root_start = np.zeros(3)

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        """The mat flat on the table along +y from its near edge, whose middle is at the grasp
        point; where the grasp point is above the mat, the last one or two strips ramp up to
        it."""
        self.demo = demo
        mujoco.mj_kinematics(self.model, data)
        g = data.site_xpos[self.grasp_site].copy()
        n, w = len(self.strips) - 1, self.width  # strips of the near half
        rise = float(g[2]) - (self.table_z + self.half_thick)
        ramp = max(1, math.ceil(rise / (0.9 * w)))
        if ramp > n // 2:
            raise ValueError(f"demo {demo}'s grasp point is {rise:.3f} m above the mat: the "
                             "matfolding scene does not fit this demo; regenerate "
                             "tasks/matfolding.toml")
        theta = math.asin(max(0.0, rise) / (ramp * w))
        for adr in self.hinges:
            data.qpos[adr] = 0.0
        data.qpos[self.hinges[n - ramp]] = -theta  # the hinge of strip n - ramp + 1
        # far edge to near edge along y
        reach = self.half_length + (n - ramp) * w + ramp * w * math.cos(theta)
        root = np.array([g[0], g[1] + reach, self.table_z + self.half_thick])
        set_free_pose(self.model, data, self.root, root, np.array([1.0, 0.0, 0.0, 0.0]))
        self.root_start = root
        mujoco.mj_kinematics(self.model, data)
        # the pinch takes the hand's orientation (the weld holds it there)
        turn, inv = np.empty(4), np.empty(4)
        mujoco.mju_negQuat(inv, data.xquat[self.strips[-1]])
        mujoco.mju_mulQuat(turn, inv, data.xquat[grasp.hand_id])
        data.qpos[self.turn_adr:self.turn_adr + 4] = turn / np.linalg.norm(turn)

    def near_edge(self, data: mujoco.MjData) -> np.ndarray:
        """[3] the middle of the mat's near (pinched) edge (world)."""
        return data.xpos[self.pinch]

    def fold_vector(self, data: mujoco.MjData) -> np.ndarray:
        """[3] where the near edge's middle is in the far plate's frame (x along the edge, y
        towards the far edge, z up from the plate's middle plane; origin at the far edge's
        middle): (0, -mat length, 0) when flat, about (0, 0, 2 thicknesses) when folded edge
        on edge."""
        rot = data.xmat[self.root].reshape(3, 3)
        return rot.T @ (self.near_edge(data) - data.xpos[self.root])

    def heading_deg(self, data: mujoco.MjData) -> float:
        """The far plate's heading on the table (deg): the angle of its x axis (along its edges)
        from the world x, about the vertical; 0 as it is laid at reset."""
        rot = data.xmat[self.root].reshape(3, 3)
        return float(np.degrees(np.arctan2(rot[1, 0], rot[0, 0])))

    def turned_strips(self, data: mujoco.MjData) -> int:
        """How many strips of the near half lie turned over on the far half, in one layer: the
        strip upside down (its normal within 25 deg of the far plate's -z), its hinge over the
        far plate (in its frame: y within [-half length, 0]) and at most `[success]
        max_layer_height` above the plate's middle plane."""
        rot = data.xmat[self.root].reshape(3, 3)
        ids = self.strips[1:]
        local = (data.xpos[ids] - data.xpos[self.root]) @ rot
        normal_z = (data.xmat[ids].reshape(-1, 3, 3)[:, :, 2] @ rot)[:, 2]
        layer = float(self.success_cfg["max_layer_height"])
        over = (local[:, 1] >= -self.half_length - 1e-3) & (local[:, 1] <= 1e-3)
        return int(np.count_nonzero((normal_z <= -math.cos(math.radians(25.0))) & over
                                    & (local[:, 2] <= layer)))

    def _ref(self, key: str) -> np.ndarray:
        """Demo j's row of a per-demo `[scene]` reference."""
        ref = np.asarray(self.scene[key], dtype=float)
        return self._demo_row(ref.reshape(len(ref), -1))

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.record = {"max_root_shift": 0.0, "release_edge": None}

    def on_release(self, data: mujoco.MjData, grasp: Grasp) -> None:
        mujoco.mj_kinematics(self.model, data)
        self.record["release_edge"] = self.near_edge(data).copy()

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        p, s0 = data.xpos[self.root], self.root_start
        shift = math.hypot(float(p[0] - s0[0]), float(p[1] - s0[1]))
        if shift > self.record["max_root_shift"]:
            self.record["max_root_shift"] = shift

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        rec = self.record
        edge_off = None
        if rec["release_edge"] is not None:
            edge_off = float(np.linalg.norm(rec["release_edge"] - self._ref("release_edge")))
        turned = self.turned_strips(data)
        height = float(data.xpos[self.root, 2] - self.table_z)
        checks = mat_checks(grasp.release_reason, edge_off, height, turned,
                            float(rec["max_root_shift"]), self.success_cfg)
        passed = {c.name: c.passed for c in checks}
        ok = all(passed.values()) and not grasp.held(data)
        return ok, {"release_offset": edge_off, "fold_end_y": float(self.fold_vector(data)[1]),
                    "turned_strips": turned,
                    "mat_folded": all(passed[n] for n in MAT_FOLD_CHECKS),
                    "mat_heading_deg": self.heading_deg(data),
                    "max_root_shift": float(rec["max_root_shift"]),
                    "checks": checks_json(checks)}

    def scene_state(self) -> dict[str, Any]:
        state = super().scene_state()
        state["root_start"] = self.root_start.copy()
        return state

    def restore_scene_state(self, state: dict[str, Any]) -> None:
        super().restore_scene_state(state)
        self.root_start = np.asarray(state["root_start"], dtype=float).copy()


def _beans(scene: dict[str, Any], task: str) -> tuple[int, float, tuple[str, ...]]:
    """The beans of a scene's `[scene]` table: how many (`n_beans`, at least 1), their radius
    (m) and body names `bean0..`."""
    n = int(scene["n_beans"])
    if n < 1:
        raise ValueError(f"{task} needs n_beans >= 1, got {n}")
    return n, float(scene["bean_radius"]), tuple(f"bean{i}" for i in range(n))


class PouringScene(Scene):
    """A cup holding `n_beans` beans (free spheres); a square container where the demos pour.
    Success: see the module docstring (the cup never slips; enough beans in the container,
    few ever landed outside it)."""

    object_bodies = ("cup",)
    needs_release = False

    def __init__(self, doc: dict[str, Any]):
        super().__init__(doc)
        self.n_beans, self.bean_radius, self.bean_names = _beans(self.scene, "pouring")
        self.object_bodies = ("cup",) + self.bean_names

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        cont = spec.body("container")
        cont.pos = [s["container_floor"][0], s["container_floor"][1], self.table_z]
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
            g.condim = int(s.get("bean_condim", 3))
            g.priority = 1  # a bean's contact takes the bean's condim and friction

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.cup = _id(model, mujoco.mjtObj.mjOBJ_BODY, "cup")
        self.container = _id(model, mujoco.mjtObj.mjOBJ_BODY, "container")
        self.bean_ids = np.array([_id(model, mujoco.mjtObj.mjOBJ_BODY, n)
                                  for n in self.bean_names])
        self.bean_local = self._bean_layout()
        # The container is static: its pose in the compiled model.
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        self._cont_pos = data.xpos[self.container].copy()
        self._cont_rot = data.xmat[self.container].reshape(3, 3).copy()
        self._half = float(self.scene["container_half_size"])
        self._height = float(self.scene["container_height"])
        self._outer = self._half + 0.01  # + the walls' thickness
        self._level = self._height + self.bean_radius
        self._pour_centres = np.asarray(self.scene.get("pour_centre", [[0.0, 0.0, 0.0]]),
                                        dtype=float).reshape(-1, 3)
        #: the cup's mouth along its axis, and how far out of its axis a bean is out of it.
        self._mouth = float(self.scene.get("cup_mouth", 0.05))
        self._cup_outer = float(self.scene.get("cup_inner_radius", 0.036)) + 0.01

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

    def _place_beans(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.place_held_prop(data, grasp)
        mujoco.mj_kinematics(self.model, data)
        cup_pos = data.xpos[self.cup]
        cup_rot = data.xmat[self.cup].reshape(3, 3)
        for b, local in zip(self.bean_ids, self.bean_local, strict=True):
            set_free_pose(self.model, data, int(b), cup_pos + cup_rot @ local,
                          np.array([1.0, 0, 0, 0]))

    def _bean_local(self, data: mujoco.MjData) -> np.ndarray:
        """[n_beans, 3] bean centres in the container frame (static: its pose is the model's)."""
        return (data.xpos[self.bean_ids] - self._cont_pos) @ self._cont_rot

    def bean_fraction(self, data: mujoco.MjData) -> float:
        """Fraction of beans inside the container (below its rim, within its walls)."""
        local = self._bean_local(data)
        a, h = self._half, self._height
        inside = ((np.abs(local[:, 0]) <= a) & (np.abs(local[:, 1]) <= a)
                  & (local[:, 2] >= -0.01) & (local[:, 2] <= h))
        return float(np.count_nonzero(inside)) / self.n_beans

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.demo = demo
        self._place_beans(data, grasp)

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.record = {"spilled": np.zeros(self.n_beans, dtype=bool),
                       "left": np.zeros(self.n_beans, dtype=bool),
                       "pour_sum": np.zeros(3), "pour_count": 0}

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        """A bean has landed outside once it is below the container's rim outside its walls'
        outer faces (on the table, on the rim, on the floor...). When a bean leaves the cup
        (past its mouth or its wall), where the cup's mouth is then is where it was poured."""
        local = self._bean_local(data)
        rec = self.record
        below = local[:, 2] < self._level
        if below.any():
            rec["spilled"] |= below & ((np.abs(local[:, 0]) > self._outer)
                                       | (np.abs(local[:, 1]) > self._outer))
        left = rec["left"]
        if not left.all():
            rot = data.xmat[self.cup].reshape(3, 3)
            in_cup = (data.xpos[self.bean_ids] - data.xpos[self.cup]) @ rot
            out = ((in_cup[:, 2] > self._mouth)
                   | (np.hypot(in_cup[:, 0], in_cup[:, 1]) > self._cup_outer)) & ~left
            if out.any():
                mouth = data.xpos[self.cup] + self._mouth * rot[:, 2]
                k = int(np.count_nonzero(out))
                rec["pour_sum"] = rec["pour_sum"] + k * mouth
                rec["pour_count"] += k
                left |= out

    def pour_offset(self) -> float | None:
        """Distance (m) between where the cup's mouth was, on average, when its beans left it and
        where it was when demo j's did (None: no bean has left the cup)."""
        count = self.record["pour_count"]
        if count == 0:
            return None
        ref = self._demo_row(self._pour_centres)
        return float(np.linalg.norm(self.record["pour_sum"] / count - ref))

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        c = self.success_cfg
        n = self.n_beans
        frac = self.bean_fraction(data)
        spilled = float(self.record["spilled"].mean())
        offset = self.pour_offset() if "pour_centre" in self.scene else 0.0
        eps = 1e-9  # the spec's fractions are rounded to 10 digits
        checks = [Check.flag("cup_held", grasp.release_reason != "slipped",
                             "the cup never slipped out of the fingers")]
        if "pour_centre" in self.scene and "pour_radius" in c:
            checks.append(Check("pour_offset", offset, float(c["pour_radius"]), "<=", "m",
                                "where the cup's mouth is, on average, as its beans leave it, "
                                "from where demo j's is"))
        elif "pour_centre" in self.scene:
            checks.append(Check.flag("poured", offset is not None, "a bean left the cup"))
        checks += [
            Check("beans_in_container", round(frac * n),
                  math.ceil(n * (float(c["min_fraction"]) - eps)), ">=", "",
                  f"beans (of {n}) in the container at the end"),
            Check("beans_spilled", round(spilled * n),
                  math.floor(n * (float(c["max_spilled_fraction"]) + eps)), "<=", "",
                  f"beans (of {n}) that ever landed outside the container"),
        ]
        return all(ch.passed for ch in checks), {
            "bean_fraction": frac, "spilled_fraction": spilled, "pour_offset": offset,
            "checks": checks_json(checks)}


def scoop_checks(held: bool, bin_touched_by: str | None, bowl_above_rim: float,
                 bowl_tilt_deg: float, beans_in_scoop: int, beans_spilled: int,
                 cfg: dict[str, Any]) -> list[Check]:
    """Scoop's success checks, in the order they are judged (success: every one passes).

    Args:
        held: the scoop is still held (it never slipped out of the fingers).
        bin_touched_by: the first body other than a bean that touched the bin (the scoop, a
            part of the robot), or None.
        bowl_above_rim: the bowl's lowest point above the bin's rim (m), now.
        bowl_tilt_deg: the bowl's opening's angle from straight up (deg), now.
        beans_in_scoop: beans in the bowl now; beans_spilled: beans that ever landed outside
            the bin.
        cfg: the spec's `[success]`: `max_tilt_deg`, `min_beans`, `max_spilled`.

    Returns:
        `held` (flag), `bin_untouched` (flag), `bowl_above_rim` >= 0 (m), `bowl_tilt` <=
        `max_tilt_deg` (deg), `beans_in_scoop` >= `min_beans`, `beans_spilled` <=
        `max_spilled`.
    """
    return [
        Check.flag("held", held, "the scoop never slipped"),
        Check.flag("bin_untouched", bin_touched_by is None,
                   f"touched by {bin_touched_by}" if bin_touched_by else "the bin untouched"),
        Check("bowl_above_rim", float(bowl_above_rim), 0.0, ">=", "m",
              "the bowl's lowest point above the bin's rim"),
        Check("bowl_tilt", float(bowl_tilt_deg), float(cfg["max_tilt_deg"]), "<=", "deg",
              "the bowl's opening from straight up"),
        Check("beans_in_scoop", float(beans_in_scoop), float(cfg["min_beans"]), ">=", ""),
        Check("beans_spilled", float(beans_spilled), float(cfg["max_spilled"]), "<=", ""),
    ]


class ScoopScene(Scene):
    """A scoop held by its handle, a bin of beans on a stand. Success: `scoop_checks` (the scoop
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
        self.n_beans, self.bean_radius, self.bean_names = _beans(self.scene, "scoop")
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
        _box_walls(spec, "bin", (-hx, hx, -hy, hy), 0.0, rim - floor, t)
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
        self.scoop = _id(model, mujoco.mjtObj.mjOBJ_BODY, "scoop")
        self.bean_ids = np.array([_id(model, mujoco.mjtObj.mjOBJ_BODY, n)
                                  for n in self.bean_names])
        self.bean_geoms = np.array([_id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{n}_geom")
                                    for n in self.bean_names])
        self.bin_geoms = np.array([_id(model, mujoco.mjtObj.mjOBJ_GEOM, f"bin_{n}") for n in
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
        checks = scoop_checks(grasp.held(data), touched, lowest - self._rim, tilt, beans,
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


SCENES: dict[str, type[Scene]] = {
    "openbox": OpenBoxScene,
    "bottle2shelf": BottleScene,
    "platestandingtolying": PlateScene,
    "pouring": PouringScene,
    "wineglass": GlassScene,
    "pan2stove": PanScene,
    "obstaclerotate": ObstacleScene,
    "matfolding": MatScene,
    "scoop": ScoopScene,
}


def make_scene(task: str, doc: dict[str, Any]) -> Scene:
    """The scene of a RoboTasks task, configured by its spec."""
    if task not in SCENES:
        raise KeyError(f"no RoboTasks scene {task!r}; valid: {sorted(SCENES)}")
    return SCENES[task](doc)
