"""What the RoboTasks derivations share (build time only: `eval/make_task_specs.py` runs them
through `clfd_bench.envs.robotasks.derive.derive_spec`; no env imports this module): the margins,
the design defaults every task starts from (`WELD_GRASP`, `TASK_DEFAULTS`: a task's `DESIGN`
states only what differs), and the geometry and replay helpers the tasks' `derive` use.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.robotasks.env import RoboTaskEnv
from clfd_bench.resources import resource_path
from clfd_bench.sim.robot import ROBOT_BODIES, robot_model
from clfd_bench.sim.scene_fit import grasp_points, lowest_point, prop_pose
from clfd_bench.sim.start_configs import (
    backward_start_configs,
    solve_configuration,
    tracking_errors,
)

#: A start configuration "tracks" when forward IK stays within these of the demo.
TRACK_TOL_POS = 1e-3
TRACK_TOL_ROT = 1e-2
#: Added to a position bound measured on the demos: 1 cm of noise / offset an execution must
#: survive + 5 mm of servo lag and IK error (m).
POSITION_MARGIN = 0.015
#: Added to an orientation bound measured on the demos (deg): the 1.5 cm position margin moves
#: the lid's angle by up to 4 deg at the demos' smallest grasp radius (0.21 m), + 6 deg.
TURN_MARGIN_DEG = 10.0

#: How far (m) a rack or tray a prop is taken out of may move before it counts as knocked: the
#: 1.5 cm position margin + 5 mm, the distance a placed prop may be off too (`PLACE_RADIUS`).
#: Argued in `knock_argument`: the rack's walls / pegs stand 1.5 cm clear of the demos' prop,
#: so a good execution that far off the demos' path touches them and pushes the rack up to that.
KNOCK_SHIFT = POSITION_MARGIN + 0.005
#: The least radius (m) around where demo j lets the prop go within which an execution may let
#: it go: the 1.5 cm position margin + 5 mm for the prop's swing while the gripper opens. The
#: radius itself is derived (`place_bounds`): at least this, or as far as two demos' release
#: points lie apart.
PLACE_RADIUS = POSITION_MARGIN + 0.005

IDENTITY = [1.0, 0.0, 0.0, 0.0]
#: The cup's axis (its z) along minus the hand's x axis: a -90 deg turn about the hand's y.
CUP_IN_GRASP = [float(np.sqrt(0.5)), 0.0, -float(np.sqrt(0.5)), 0.0]

#: The Franka Hand's grip, shared by every task (clfd_bench.sim.grasp): 70 N continuous grasp
#: force (datasheet), friction coefficient 0.5 (stock fingertips on PET/ceramic/wood), 17 x 17
#: mm pads; the load ratio is averaged over 6 control steps (0.1 s) before it breaks the grasp.
GRIP = {"grip_force": 70.0, "mu": 0.5, "filter_steps": 6}

#: The grasp every task holds its prop by (`weld_grasp`), in the order the spec writes it: a
#: weld with the Franka Hand's grip (`GRIP`), a flat pad contact (`contact = "patch"`; a line
#: contact also gives `contact_radius`), the weld's own slip bounds (3 cm, 30 deg), the prop at
#: the grasp site. A task states its prop (`body`), how far the fingers close on it
#: (`closed_opening`) and only what differs.
WELD_GRASP: dict[str, Any] = {
    "kind": "weld", "body": None, **GRIP, "contact": "patch", "contact_radius": None,
    "max_slip": 0.03, "max_slip_angle_deg": 30.0, "closed_opening": None, "exclude": None,
    "prop_pos": [0.0, 0.0, 0.0], "prop_quat": IDENTITY,
}

#: Design constants every task shares (`design`). Physics steps of 2 ms (8 per 60 Hz control
#: step): the arm's stiff position servos, at their torque limits while a held prop swings,
#: track the demos only as well as the step lets them. Worst hand position error over the
#: replays (eval/measure_limits.py; PlateStacking demo 0 2x slower / Pouring demo 7 1.5x
#: faster) with 4, 5, 6, 8, 12 physics steps per control step: 23.8 / 21.1, 11.6 / 8.2, 8.3 /
#: 7.4, 3.8 / 1.4, 1.3 / 1.2 mm. 4 ms steps (tried for speed) made tracking errors a simulation
#: artefact; 2 ms is within ~2.5 mm of the finest step, at ~80 % of 4 ms's speed.
TASK_DEFAULTS: dict[str, Any] = {"physics_dt": 0.002}

#: The tray / rack a held prop is taken out of (wineglass, pan2stove): its walls derived from
#: the first `tray_fraction` of the demos, `tray_clearance` clear of the prop below their top,
#: which is `tray_rise` up the prop from its lowest start point; base and wall thickness (m).
TRAY = {"tray_fraction": 0.2, "tray_clearance": POSITION_MARGIN, "tray_base_thickness": 0.005,
        "tray_wall_thickness": 0.008, "tray_rise": 0.024}


def weld_grasp(body: str, closed_opening: float, **overrides: Any) -> dict[str, Any]:
    """The `[grasp]` design of a task: `WELD_GRASP` with its prop `body`, the fingers' opening
    on it and `overrides` (e.g. `contact="line_x", contact_radius=0.008`, `exclude=[...]`,
    `prop_quat=...`); entries left None are not written.

    Raises:
        KeyError: an override `WELD_GRASP` does not know.
    """
    unknown = set(overrides) - set(WELD_GRASP)
    if unknown:
        raise KeyError(f"unknown grasp entries {sorted(unknown)}; valid: {list(WELD_GRASP)}")
    values = {**WELD_GRASP, "body": body, "closed_opening": closed_opening, **overrides}
    return {k: v for k, v in values.items() if v is not None}


def design(grasp: dict[str, Any], camera: dict[str, float], scene: dict[str, Any] | None = None,
           success: dict[str, Any] | None = None, task: dict[str, Any] | None = None,
           solver: dict[str, Any] | None = None) -> dict[str, Any]:
    """A task's design constants (documented choices, not derived from the data): `[task]`
    (`TASK_DEFAULTS` and `task`), `[grasp]` (`weld_grasp`), what its derivation reads of
    `scene`, the design entries of `[success]`, `[solver]` if it has one, and its camera's
    angles and distance."""
    out = {"task": {**TASK_DEFAULTS, **(task or {})}, "grasp": grasp, "scene": scene or {},
           "success": success or {}, "camera": camera}
    if solver is not None:
        out["solver"] = solver
    return out


#: Where the observer arguments' measurements come from.
REPLAYED = "in every must-succeed replay of `clfd-bench replay --perturb all` (2026-12-05)"


def knock_argument(what: str, replayed: str, hit: str, size: str) -> str:
    """The observer's argument for a rack's or tray's `max_<name>_shift`."""
    return (f"observer: the {what} is not knocked. It may move at most this far (m) from where "
            "it was put, at any step. Design: the 1.5 cm position margin + 5 mm (the distance "
            "a placed prop may be off too). The walls stand 1.5 cm clear of where the demos "
            "move the prop, so a good execution up to 1.5 cm off the demos' path may touch "
            "them and push the rack that far; what an observer sees as a knock is the rack "
            f"shoved out of place or tipped. Why an observer signs it: {replayed}; executions "
            f"that run into it {hit}; {size}")


def task_model(task: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_path(str(resource_path("tasks", f"{task}.xml")))
    return model, mujoco.MjData(model)


def place_body(model: mujoco.MjModel, data: mujoco.MjData, body: str, pos: np.ndarray,
               quat: np.ndarray) -> None:
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    adr = model.jnt_qposadr[model.body_jntadr[bid]]
    data.qpos[adr:adr + 3] = pos
    data.qpos[adr + 3:adr + 7] = quat
    mujoco.mj_kinematics(model, data)


def held_prop_lows(task: str, body: str, positions: np.ndarray, quaternions: np.ndarray,
                   grasp: dict[str, Any], geom: str | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Lowest z [...] and centre of mass [..., 3] (with `geom`: that geom's centre) of a held
    prop at hand poses [..., 3|4] (held at `grasp["prop_pos"]`, `grasp["prop_quat"]` in the
    grasp-site frame)."""
    model, data = task_model(task)
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    gid = None if geom is None else mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    shape = positions.shape[:-1]
    pos = positions.reshape(-1, 3)
    quat = quaternions.reshape(-1, 4)
    lows = np.empty(len(pos))
    coms = np.empty((len(pos), 3))
    sites = grasp_points(pos, quat)
    for i in range(len(pos)):
        p, q = prop_pose(sites[i], quat[i], grasp["prop_pos"], grasp["prop_quat"])
        place_body(model, data, body, p, q)
        lows[i] = lowest_point(model, data, body)
        coms[i] = data.xipos[bid] if gid is None else data.geom_xpos[gid]
    return lows.reshape(shape), coms.reshape(shape + (3,))


def path_clearance(task, doc: dict[str, Any], body: str, support_geoms: tuple[str, ...],
                   every: int = 3) -> np.ndarray:
    """[N] the smallest distance (m) between the held prop's geoms and `support_geoms` along
    each demo (every `every`-th sample), in the scene of the provisional spec `doc`."""
    env = RoboTaskEnv(doc["task"]["name"], spec=doc, limits=None)
    m, d = env.model, env.data
    bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)
    mine = [g for g in range(m.ngeom) if m.geom_bodyid[g] == bid and m.geom_contype[g]]
    theirs = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n) for n in support_geoms]
    grasp = doc["grasp"]
    out = np.full(len(task.positions), np.inf)
    fromto = np.zeros(6)
    for n in range(len(task.positions)):
        env.reset(options={"demo": n})
        g = grasp_points(task.positions[n], task.quaternions[n])
        for t in range(0, task.positions.shape[1], every):
            p, q = prop_pose(g[t], task.quaternions[n, t], grasp["prop_pos"], grasp["prop_quat"])
            place_body(m, d, body, p, q)
            for a in mine:
                for b in theirs:
                    out[n] = min(out[n], mujoco.mj_geomDistance(m, d, a, b, 0.1, fromto))
    env.close()
    return out


def lower_until_clear(task, doc: dict[str, Any], body: str, key: str,
                      support_geoms: tuple[str, ...], clearance: float
                      ) -> tuple[float, np.ndarray]:
    """Lowers the support top `doc["scene"][key]` (its z) until every demo's held prop stays
    `clearance` away from it along its whole path. Returns (top z, clearance per demo [N])."""
    for _ in range(4):
        gaps = path_clearance(task, doc, body, support_geoms)
        deficit = clearance - float(gaps.min())
        if deficit <= 5e-4:
            break
        top = list(doc["scene"][key])
        top[2] -= deficit
        doc["scene"][key] = top
    return float(doc["scene"][key][2]), gaps


def start_configurations(positions: np.ndarray, quaternions: np.ndarray
                         ) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Per-demo start configurations [N, 7], how each was found ("backward" or "home"), and
    the max kinematic forward-tracking position error [N] (m) from each."""
    model = robot_model()
    starts = backward_start_configs(model, positions, quaternions)
    methods, errors = [], np.empty(len(starts))
    for n in range(len(starts)):
        pe, re = tracking_errors(model, starts[n], positions[n], quaternions[n])
        method = "backward"
        if pe.max() > TRACK_TOL_POS or re.max() > TRACK_TOL_ROT:
            q, _, _ = solve_configuration(model, positions[n, 0], quaternions[n, 0])
            pe2, re2 = tracking_errors(model, q, positions[n], quaternions[n])
            if pe2.max() < pe.max():
                starts[n], pe, method = q, pe2, "home"
        methods.append(method)
        errors[n] = pe.max()
    return starts, methods, errors


def camera_from_demos(task, design) -> dict[str, Any]:
    """A camera looking at the middle of the demos' grasp points (design angles/distance)."""
    g = grasp_points(task.positions, task.quaternions).reshape(-1, 3)
    centre = (g.min(0) + g.max(0)) / 2
    return {"lookat": [float(v) for v in centre], **design["camera"]}


def largest_gap(points: np.ndarray) -> float:
    """The largest distance between two of `points` [N, k]."""
    points = np.asarray(points, dtype=float)
    return float(np.linalg.norm(points[:, None] - points[None], axis=-1).max())


def release_points(task, doc: dict[str, Any]) -> np.ndarray:
    """[N, 2] where each demo, replayed in the scene of the provisional spec `doc`, lets its
    prop go (the prop's centre (x, y) when the gripper opens; the scene's `release_point`)."""
    _, recs = replay_demos(task, doc, records=True)
    missing = [j for j, r in enumerate(recs) if r.get("release_point") is None]
    if missing:
        raise RuntimeError(f"{doc['task']['name']}: demos {missing} never let the prop go when "
                           "replayed; the scene cannot derive its place radius (check the "
                           "scene's support and grasp)")
    return np.array([r["release_point"] for r in recs], dtype=float)


def place_bounds(lows: np.ndarray, coms: np.ndarray, top: float,
                 released: np.ndarray) -> dict[str, Any]:
    """Release-height and place bounds from the held prop at the demos' end poses (lowest
    points [N], centres [N, 3]) and where the demos, replayed, let it go ([N, 2]:
    `_release_points`)."""
    drop = lows - top
    spread = largest_gap(released)
    return {
        "success": {"max_release_height": float(drop.max() + POSITION_MARGIN),
                    "place_radius": float(max(PLACE_RADIUS, spread))},
        "place_centre": coms[:, :2],
        "derived": {"release_height_demos": drop, "release_point_demos": released,
                    "release_spread": spread},
        "comments": {
            "max_release_height": (
                "the prop's lowest point may be at most this high above the support's top when "
                "the gripper opens. Procedure: the held prop at each demo's last pose "
                "([derived] release_height_demos), max + 1.5 cm"),
            "place_radius": (
                "when the gripper opens, the prop must be within this horizontal distance (m) "
                "of where demo j lets it go ([scene] place_centre[j]): let go as far from demo "
                "j's point as another demo lets it go, and no further. Procedure: the demos "
                "replayed in this scene, where each lets the prop go ([derived] "
                "release_point_demos); the largest distance between two of them ([derived] "
                "release_spread), at least 2 cm (the 1.5 cm position margin + 5 mm for the "
                "prop's swing as the fingers open). A must-fail execution that lets go within "
                "it is within the demos' own spread: `clfd-bench replay` counts such a drift "
                "n/a (clfd_bench.execution.replay.within_demo_spread)"),
        },
    }


PLACE_CENTRE_COMMENT = ("per demo j: where the prop's centre (x, y) is when demo j lets it go "
                         "(the held prop at demo j's last pose)")


def table_below(task, name: str, body: str, grasp: dict[str, Any], fraction: float,
                clearance: float) -> tuple[float, np.ndarray]:
    """The table height: `clearance` under the lowest point the held prop reaches in the first
    `fraction` of the demos (where it starts, near the table), at most 0 (the robot's base).
    Returns (table_z, lowest point per demo [N])."""
    n = int(task.positions.shape[1] * fraction)
    lows, _ = held_prop_lows(name, body, task.positions[:, :n], task.quaternions[:, :n], grasp)
    return float(min(0.0, lows.min() - clearance)), lows.min(1)


TABLE_COMMENT = (
    "the table top (m, robot base frame). Procedure: the lowest point the held prop reaches in "
    "the first fifth of the demos ([derived] start_lowest_z), less a clearance of 1.5 cm (a 1 cm "
    "start offset in any direction must not push the prop into the table; plate: + the rack's "
    "base), at most 0 (lower: the robot stands on a mount)")


def surface_points(model: mujoco.MjModel, body: str, n: int = 24) -> np.ndarray:
    """[P, 3] points on the surface of `body`'s cylinder, capsule and box geoms (rings at the
    ends of cylinders and capsules, capsules' hemispheres in rings too; boxes' corners, edge
    midpoints and face centres), in the body's frame."""
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    ang = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1)
    out = []
    for g in np.flatnonzero(model.geom_bodyid == bid):
        r, h = model.geom_size[g][:2]
        kind = model.geom_type[g]
        if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
            local = [r * ring + [0.0, 0.0, z] for z in (-h, h)]
        elif kind == mujoco.mjtGeom.mjGEOM_BOX:
            grid = np.stack(np.meshgrid(*[[-1.0, 0.0, 1.0]] * 3, indexing="ij"), -1)
            grid = grid.reshape(-1, 3)
            local = [grid[np.abs(grid).max(1) == 1.0] * model.geom_size[g]]
        elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            local = []
            for phi in np.linspace(0.0, np.pi / 2, 5):
                for side in (-1.0, 1.0):
                    local.append(r * np.cos(phi) * ring
                                 + [0.0, 0.0, side * (h + r * np.sin(phi))])
        else:
            raise ValueError(f"surface_points supports cylinders, capsules and boxes; {body!r} "
                             f"has geom type {mujoco.mjtGeom(kind).name}")
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[g])
        out.append(np.concatenate(local) @ rot.reshape(3, 3).T + model.geom_pos[g])
    return np.concatenate(out)


def tray_extent(task, name: str, body: str, axis: int, grasp: dict[str, Any], top: float,
                n_samples: int) -> np.ndarray:
    """[4] the extent (x_lo, x_hi, y_lo, y_hi) in the tray frame (origin under the grasp point
    at the start, x along the held prop's axis `axis`, horizontal) of the surface of `body`
    (task `name`'s held prop) below `top` (world z) over the first `n_samples` of every demo:
    where the tray's walls must not be."""
    model, _ = task_model(name)
    pos, quat = task.positions[:, :n_samples], task.quaternions[:, :n_samples]
    pts = prop_points(pos, quat, grasp, surface_points(model, body))
    g = grasp_points(pos, quat)
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    rot = np.empty(9)
    for n in range(len(g)):
        _, q = prop_pose(g[n, 0], quat[n, 0], grasp["prop_pos"], grasp["prop_quat"])
        mujoco.mju_quat2Mat(rot, q)
        yaw = np.arctan2(rot[3 + axis], rot[axis])  # the prop's axis at the start, seen from above
        ex = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        ey = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        near = pts[n][pts[n][..., 2] <= top] - g[n, 0]
        if len(near):
            xy = np.stack([near @ ex, near @ ey], axis=1)
            lo, hi = np.minimum(lo, xy.min(0)), np.maximum(hi, xy.max(0))
    return np.array([lo[0], hi[0], lo[1], hi[1]])


def tray_walls(task, name: str, body: str, axis: int, grasp: dict[str, Any],
               d: dict[str, Any], floor: Callable[[float], float]
               ) -> tuple[np.ndarray, float, float, np.ndarray, list[float]]:
    """The tray (or rack) a held prop is taken out of, from the first `d["tray_fraction"]` of
    the demos: the prop's lowest point per demo there [N]; what the tray stands on (`floor`
    of the height `d["tray_clearance"]` + the base under the lowest of them); the walls' height
    above the base (`d["tray_rise"]` up the prop from its highest lowest point); the prop's
    extent below the walls' top in the tray frame [4] (`_tray_extent`, the prop's axis `axis`)
    and the walls' inner faces, `d["tray_clearance"]` outside it."""
    n = int(task.positions.shape[1] * d["tray_fraction"])
    lows, _ = held_prop_lows(name, body, task.positions[:, :n], task.quaternions[:, :n], grasp)
    lows = lows.min(1)
    base, c = float(d["tray_base_thickness"]), float(d["tray_clearance"])
    floor_z = floor(float(lows.min() - c - base))
    wall_height = float(lows.max() + d["tray_rise"] - (floor_z + base))
    extent = tray_extent(task, name, body, axis, grasp, floor_z + base + wall_height, n)
    walls = [float(extent[0] - c), float(extent[1] + c), float(extent[2] - c),
             float(extent[3] + c)]
    return lows, floor_z, wall_height, extent, walls


def ghost_clearance(task, doc: dict[str, Any], geoms: tuple[str, ...], every: int = 3
                    ) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Each demo replayed (no motion-limit checks) in the scene of `doc` with its geoms `geoms`
    made ghosts (no contacts): the smallest distance (m, negative: into it) between any of them
    and the held prop or any robot geom [N], the point of the ghost's surface where it is
    smallest [N, 3], and which ghost that is [N]."""
    env = RoboTaskEnv(doc["task"]["name"], spec=doc, limits=None)
    m, d = env.model, env.data
    ghosts = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in geoms]
    for g in ghosts:  # the demos follow their own paths; the distance says how far in they go
        m.geom_contype[g] = m.geom_conaffinity[g] = 0
    robot = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n) for n in ROBOT_BODIES}
    prop = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, doc["grasp"]["body"])
    solid = [g for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]]
    movers = [g for g in solid if m.geom_bodyid[g] in robot or m.geom_bodyid[g] == prop]
    n = len(task.positions)
    gaps, where, which = np.full(n, np.inf), np.zeros((n, 3)), [geoms[0]] * n
    fromto = np.zeros(6)
    for j in range(n):
        actions = demo_actions(env, task, j, settle_steps=0)
        env.reset(options={"demo": j, "horizon": len(actions)})
        for k, a in enumerate(actions):
            env.step(a)
            if k % every:
                continue
            for ghost, name in zip(ghosts, geoms, strict=True):
                for g in movers:
                    dist = mujoco.mj_geomDistance(m, d, ghost, g, 0.1, fromto)
                    if dist < gaps[j]:
                        gaps[j], where[j], which[j] = dist, fromto[:3], name
    env.close()
    return gaps, where, which


def prop_points(positions: np.ndarray, quaternions: np.ndarray, grasp: dict[str, Any],
                local: np.ndarray, every: int = 1) -> np.ndarray:
    """[N, T', P, 3] the held prop's points `local` [P, 3] (prop frame) in the world at the hand
    poses [N, T, 3|4] (every `every`-th sample), the prop held at `grasp["prop_pos"]`,
    `grasp["prop_quat"]` in the grasp-site frame."""
    g = grasp_points(positions, quaternions)
    steps = range(0, g.shape[1], every)
    out = np.empty((len(g), len(steps), len(local), 3))
    rot = np.empty(9)
    for n in range(len(g)):
        for i, t in enumerate(steps):
            p, q = prop_pose(g[n, t], quaternions[n, t], grasp["prop_pos"], grasp["prop_quat"])
            mujoco.mju_quat2Mat(rot, q)
            out[n, i] = p + local @ rot.reshape(3, 3).T
    return out


def extent_below(name: str, body: str, positions: np.ndarray, quaternions: np.ndarray,
                 grasp: dict[str, Any], top: float, every: int = 2) -> np.ndarray:
    """[4] the world extent (x_lo, x_hi, y_lo, y_hi) of the surface of `body` (task `name`'s
    held prop) below `top` (world z) at the hand poses [N, T, 3|4] (every `every`-th sample);
    NaN where nothing is below."""
    model, _ = task_model(name)
    pts = prop_points(positions, quaternions, grasp, surface_points(model, body), every)
    near = pts[pts[..., 2] <= top]
    if not len(near):
        return np.full(4, np.nan)
    lo, hi = near[:, :2].min(0), near[:, :2].max(0)
    return np.array([lo[0], hi[0], lo[1], hi[1]])


def hand_x(quat: np.ndarray) -> np.ndarray:
    """[3] the hand's x axis in the world for a hand quaternion [4] (w, x, y, z)."""
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, dtype=float) / np.linalg.norm(quat))
    return rot.reshape(3, 3)[:, 0]


def draft(task_name: str, design: dict[str, Any], scene: dict[str, Any],
          success: dict[str, Any], starts: np.ndarray) -> dict[str, Any]:
    """A provisional spec (for replaying the demos while deriving)."""
    doc = {"task": {"name": task_name, **design["task"]}, "grasp": dict(design["grasp"]),
           "scene": scene, "success": {**design["success"], **success},
           "start": {"qpos": starts}}
    if "solver" in design:
        doc["solver"] = dict(design["solver"])
    return doc


def demo_actions(env: RoboTaskEnv, task, j: int, settle_steps: int = 60,
                 time_scale: float = 1.0) -> np.ndarray:
    """Demo j's actions [T, 8] (its duration scaled by `time_scale`: positions interpolated,
    orientations slerped), then `settle_steps` of `env.settle_actions`."""
    from clfd_bench.data.resample import resample

    traj = np.concatenate([task.positions[j], task.quaternions[j]], axis=1)
    if time_scale != 1.0:
        traj = resample(traj, int(round((len(traj) - 1) * time_scale)) + 1)
    actions = env.trajectory_to_actions(traj)
    return np.concatenate([actions, env.settle_actions(actions[-1], settle_steps)])


def replay_demos(task, doc: dict[str, Any], records: bool = False, time_scale: float = 1.0):
    """The env's final info of each demo replayed (trajectory + 1 s of settling) in the scene
    of `doc` (no motion-limit checks: the scene alone), the demos' durations scaled by
    `time_scale` (positions interpolated, orientations slerped). With `records`, also the
    scene's episode records: (infos, records)."""
    env = RoboTaskEnv(doc["task"]["name"], spec=doc, limits=None)
    infos, recs = [], []
    for j in range(len(task.positions)):
        actions = demo_actions(env, task, j, time_scale=time_scale)
        env.reset(options={"demo": j, "horizon": len(actions)})
        for a in actions:
            env.step(a)
        infos.append(env.evaluate())
        recs.append(env.scene.scene_state()["record"])
    env.close()
    return (infos, recs) if records else infos
