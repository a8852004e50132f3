"""Derives the RoboTasks task specs (`tasks/<task>.toml`) from the demonstrations.

`derive_spec(task)` recomputes every data-derived number of a scene and the per-demo start
configurations; `eval/make_task_specs.py` writes the results. What is derived:

- openbox: the hinge (a horizontal axis fitted to the arcs the grasp points trace,
  `clfd_bench.sim.scene_fit.fit_hinge`), placed as the box's hinge frame;
- bottle2shelf: the shelf top 1 cm under the lowest point the held bottle reaches at the
  demos' end poses, centred under the bottles' end positions;
- platestandingtolying: the table 3 mm under the lowest point the plate reaches in the first
  fifth of the demos (where it stands in the rack), the rack blocks 8 mm clear of where the
  plate's rim passes in that fifth, the platform top 1 cm under the lowest point of the plate
  in the last fifth of the demos, centred under the plates' end positions;
- pouring: the container centred on the median of where the beans first reach the table when
  the demos are replayed over a flat tray, wide enough for 95 % of them (+ a bean radius +
  1 cm), its rim 2 cm under the lowest point the cup reaches in the demos;
- every task: start configurations by backward IK tracking from the common end pose
  (`clfd_bench.sim.start_configs.backward_start_configs`), each checked by kinematic forward
  tracking; a demo whose backward start does not track (platestandingtolying: the goal
  configuration's branch hits joint 5's limit for some demos) gets the IK solution of its
  first pose from `home` instead, if that tracks.

Design constants (not data-derived) sit in the `DESIGN` table below and in the task MJCF.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from clfd_bench.data import load_dataset
from clfd_bench.envs.robotask_specs import load_task_spec
from clfd_bench.envs.robotasks import RoboTaskEnv
from clfd_bench.resources import resource_path
from clfd_bench.sim.robot import robot_model
from clfd_bench.sim.scene_fit import (
    fit_hinge,
    grasp_points,
    hinge_angles,
    lowest_point,
    prop_pose,
)
from clfd_bench.sim.start_configs import (
    backward_start_configs,
    solve_configuration,
    tracking_errors,
)

#: A start configuration "tracks" when forward IK stays within these of the demo.
TRACK_TOL_POS = 1e-3
TRACK_TOL_ROT = 1e-2

IDENTITY = [1.0, 0.0, 0.0, 0.0]
#: The cup's axis (its z) along minus the hand's x axis: a -90 deg turn about the hand's y.
CUP_IN_GRASP = [float(np.sqrt(0.5)), 0.0, -float(np.sqrt(0.5)), 0.0]

#: Design constants per task (documented choices, not derived from the data).
DESIGN: dict[str, dict[str, Any]] = {
    "openbox": {
        "task": {"physics_dt": 0.002},
        "grasp": {"kind": "connect", "body": "lid_handle", "exclude": ["lid"], "max_slip": 0.03,
                  "solref": [0.03, 1.0],
                  "max_slip_angle_deg": 30.0, "closed_opening": 0.006},
        "success": {"min_lid_angle_deg": 100.0},
    },
    "bottle2shelf": {
        "task": {"physics_dt": 0.002},
        "grasp": {"kind": "weld", "body": "bottle", "max_slip": 0.03,
                  "max_slip_angle_deg": 30.0, "closed_opening": 0.014,
                  "prop_pos": [0.0, 0.0, 0.0], "prop_quat": IDENTITY},
        "scene": {"shelf_half_size": [0.12, 0.09], "clearance": 0.01},
        "success": {"max_tilt_deg": 20.0, "min_height": 0.0, "max_height": 0.045},
    },
    "platestandingtolying": {
        "task": {"physics_dt": 0.002},
        "grasp": {"kind": "weld", "body": "plate", "max_slip": 0.03,
                  "max_slip_angle_deg": 30.0, "closed_opening": 0.005,
                  "prop_pos": [0.0, 0.0, 0.0], "prop_quat": IDENTITY},
        "scene": {"platform_half_size": [0.13, 0.08], "clearance": 0.01, "place_fraction": 0.2,
                  "table_clearance": 0.003, "block_clearance": 0.008, "block_x": 0.045,
                  "rack_fraction": 0.2},
        "success": {"max_tilt_deg": 25.0, "min_height": 0.0, "max_height": 0.03,
                    "max_block_shift": 0.02, "max_block_tilt_deg": 15.0},
    },
    "pouring": {
        "task": {"physics_dt": 0.004, "release_after": False},
        "grasp": {"kind": "weld", "body": "cup", "max_slip": 0.03,
                  "max_slip_angle_deg": 30.0, "closed_opening": 0.04,
                  "prop_pos": [0.0, 0.0, 0.0], "prop_quat": CUP_IN_GRASP},
        "scene": {"n_beans": 9, "bean_radius": 0.011, "bean_mass": 0.0025,
                  "cup_inner_radius": 0.036, "cup_floor": -0.042,
                  "rim_clearance": 0.02, "landing_quantile": 0.95, "margin": 0.01,
                  "min_half_size": 0.05},
        "solver": {"solver": "newton", "iterations": 20, "ls_iterations": 10,
                   "tolerance": 1e-8, "cone": "pyramidal"},
        "success": {"min_fraction": 0.7},
    },
}


def _task_model(task: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_path(str(resource_path("tasks", f"{task}.xml")))
    return model, mujoco.MjData(model)


def _place(model: mujoco.MjModel, data: mujoco.MjData, body: str, pos: np.ndarray,
           quat: np.ndarray) -> None:
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    adr = model.jnt_qposadr[model.body_jntadr[bid]]
    data.qpos[adr:adr + 3] = pos
    data.qpos[adr + 3:adr + 7] = quat
    mujoco.mj_kinematics(model, data)


def _held_prop_lows(task: str, body: str, positions: np.ndarray, quaternions: np.ndarray,
                    grasp: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """Lowest z [...] and centre of mass [..., 3] of a held prop at hand poses [..., 3|4]
    (held at `grasp["prop_pos"]`, `grasp["prop_quat"]` in the grasp-site frame)."""
    model, data = _task_model(task)
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    shape = positions.shape[:-1]
    pos = positions.reshape(-1, 3)
    quat = quaternions.reshape(-1, 4)
    lows = np.empty(len(pos))
    coms = np.empty((len(pos), 3))
    sites = grasp_points(pos, quat)
    for i in range(len(pos)):
        p, q = prop_pose(sites[i], quat[i], grasp["prop_pos"], grasp["prop_quat"])
        _place(model, data, body, p, q)
        lows[i] = lowest_point(model, data, body)
        coms[i] = data.xipos[bid]
    return lows.reshape(shape), coms.reshape(shape + (3,))


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


def _derive_openbox(task, design, starts) -> dict[str, Any]:
    g = grasp_points(task.positions, task.quaternions)
    fit = fit_hinge(g)
    ang = np.degrees(hinge_angles(g, fit))
    half = ang.shape[1] // 2
    return {
        "scene": {"hinge_pos": fit.point, "hinge_yaw_deg": float(np.degrees(fit.yaw))},
        "derived": {
            "hinge_axis": fit.axis, "grasp_radii": fit.radii, "grasp_axial_offsets": fit.axial,
            "radial_residual_max": fit.radial_residual,
            "axial_residual_max": fit.axial_residual,
            "grasp_angle_start_deg": ang[:, 0], "grasp_angle_half_deg": ang[:, half],
            "grasp_angle_end_deg": ang[:, -1],
        },
    }


def _derive_bottle(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    lows, coms = _held_prop_lows("bottle2shelf", "bottle", task.positions[:, -1],
                                 task.quaternions[:, -1], grasp)
    top = float(lows.min() - d["clearance"])
    centre = coms[:, :2].mean(0)
    return {
        "scene": {"shelf_top": [float(centre[0]), float(centre[1]), top],
                  "shelf_half_size": d["shelf_half_size"], "shelf_yaw_deg": 0.0},
        "derived": {"bottle_end_lowest_z": lows, "bottle_end_com": coms},
    }


def _derive_plate(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    n_rack = int(task.positions.shape[1] * d["rack_fraction"])
    lows_rack, _ = _held_prop_lows("platestandingtolying", "plate", task.positions[:, :n_rack],
                                   task.quaternions[:, :n_rack], grasp)
    table_z = float(min(0.0, lows_rack.min() - d["table_clearance"]))
    n_place = int(task.positions.shape[1] * d["place_fraction"])
    lows_end, coms_end = _held_prop_lows("platestandingtolying", "plate",
                                         task.positions[:, -n_place:],
                                         task.quaternions[:, -n_place:], grasp)
    top = float(lows_end.min() - d["clearance"])
    coms_end, lows_end = coms_end[:, -1], lows_end.min(1)
    centre = coms_end[:, :2].mean(0)
    model, _ = _task_model("platestandingtolying")
    block_half = model.geom_size[model.body_geomadr[
        mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "block1")]]
    bx = d["block_x"]
    extent = _rack_gap(task, grasp, table_z, n_rack, bx + block_half[0])
    by_lo = extent[0] - d["block_clearance"] - block_half[1]
    by_hi = extent[1] + d["block_clearance"] + block_half[1]
    offsets = [[-bx, by_lo], [bx, by_lo], [-bx, by_hi], [bx, by_hi]]
    return {
        "scene": {"table_z": table_z, "block_offsets": offsets,
                  "platform_top": [float(centre[0]), float(centre[1]), top],
                  "platform_half_size": d["platform_half_size"], "platform_yaw_deg": 0.0},
        "derived": {"plate_rack_lowest_z": lows_rack.min(1), "plate_end_lowest_z": lows_end,
                    "plate_end_centre": coms_end, "rack_plate_extent_y": extent},
    }


def _rack_gap(task, grasp: dict[str, Any], table_z: float, n_samples: int,
              x_half: float) -> np.ndarray:
    """[2] the extent (min, max) along the rack's y axis (the plate normal's horizontal
    direction, origin under the plate's start centre) of the plate's rim below the blocks' top
    and within `x_half` of the rack's middle, over the first `n_samples` of every demo: where
    the blocks must not be."""
    model, data = _task_model("platestandingtolying")
    disc = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "plate_disc")
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "plate")
    radius, half_t = model.geom_size[disc][:2]
    block = model.geom_size[model.body_geomadr[
        mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "block1")]]
    top = table_z + 2 * block[2]
    ang = np.linspace(0, 2 * np.pi, 72, endpoint=False)
    rim = np.concatenate([np.stack([radius * np.cos(ang), np.full_like(ang, side),
                                    radius * np.sin(ang)], axis=1) for side in (-half_t, half_t)])
    lo, hi = np.inf, -np.inf
    g = grasp_points(task.positions[:, :n_samples], task.quaternions[:, :n_samples])
    for n in range(len(g)):
        rack_origin, ex, ey = None, None, None
        for t in range(0, n_samples, 2):
            p, q = prop_pose(g[n, t], task.quaternions[n, t], grasp["prop_pos"],
                             grasp["prop_quat"])
            _place(model, data, "plate", p, q)
            rot = data.xmat[bid].reshape(3, 3)
            centre = data.geom_xpos[disc]
            if rack_origin is None:  # the rack is set up around the plate's start pose
                yaw = np.arctan2(rot[1, 0], rot[0, 0])
                ex = np.array([np.cos(yaw), np.sin(yaw), 0.0])
                ey = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
                rack_origin = centre.copy()
            # rim points in plate-local coordinates are offsets from the disc centre
            pts = centre + rim @ rot.T
            near = pts[(pts[:, 2] <= top) & (np.abs((pts - rack_origin) @ ex) <= x_half)]
            if len(near):
                proj = (near - rack_origin) @ ey
                lo, hi = min(lo, proj.min()), max(hi, proj.max())
    return np.array([lo, hi])


def _derive_pouring(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    lows, _ = _held_prop_lows("pouring", "cup", task.positions, task.quaternions, grasp)
    rim = float(lows.min() - d["rim_clearance"])
    scene = {"container_floor": [0.0, 0.0, 0.0], "container_half_size": 0.3,
             "container_height": 0.003, "container_yaw_deg": 0.0, "n_beans": d["n_beans"],
             "bean_radius": d["bean_radius"], "bean_mass": d["bean_mass"],
             "cup_inner_radius": d["cup_inner_radius"], "cup_floor": d["cup_floor"]}
    landing = _bean_landing(task, design, scene, starts)
    ok = np.isfinite(landing[..., 0])
    centre = np.median(landing[ok][:, :2], axis=0)
    spread = np.abs(landing[ok][:, :2] - centre).max(1)
    half = float(np.quantile(spread, d["landing_quantile"]) + d["bean_radius"] + d["margin"])
    half = float(np.ceil(max(half, d["min_half_size"]) / 0.005) * 0.005)
    scene.update({"container_floor": [float(centre[0]), float(centre[1]), 0.0],
                  "container_half_size": half, "container_height": rim})
    return {
        "scene": scene,
        "derived": {"cup_lowest_z": lows.min(1), "bean_landing_median": centre,
                    "bean_landing_spread_quantiles": np.quantile(spread, [0.5, 0.9, 0.95, 1.0]),
                    "beans_landed": ok.sum(1)},
    }


def _bean_landing(task, design, scene, starts) -> np.ndarray:
    """[N, n_beans, 3] where each bean first comes within 3 cm of the table when the demos are
    replayed over a flat tray (NaN: never)."""
    doc = {"task": {"name": "pouring", **design["task"]}, "grasp": dict(design["grasp"]),
           "scene": scene, "success": dict(design["success"]),
           "solver": dict(design.get("solver", {})), "start": {"qpos": starts}}
    env = RoboTaskEnv("pouring", spec=doc)
    n = len(task.positions)
    landing = np.full((n, env.scene.n_beans, 3), np.nan)
    for j in range(n):
        traj = np.concatenate([task.positions[j], task.quaternions[j]], axis=1)
        actions = env.trajectory_to_actions(traj)
        actions = np.concatenate([actions, env.settle_actions(actions[-1], 60)])
        env.reset(options={"demo": j, "horizon": len(actions)})
        for a in actions:
            env.step(a)
            p = env.data.xpos[env.scene.bean_ids]
            new = (p[:, 2] < 0.03) & np.isnan(landing[j, :, 0])
            landing[j, new] = p[new]
    return landing


_DERIVE = {"openbox": _derive_openbox, "bottle2shelf": _derive_bottle,
           "platestandingtolying": _derive_plate, "pouring": _derive_pouring}


def derive_spec(task_name: str, with_starts: bool = True) -> dict[str, dict[str, Any]]:
    """The spec of a RoboTasks task as {table: {key: value}}, from the dataset.

    Args:
        task_name: "openbox", "bottle2shelf", "platestandingtolying" or "pouring".
        with_starts: compute the start configurations (~20 s per task); False keeps those of
            the existing `tasks/<task>.toml`.
    """
    if task_name not in DESIGN:
        raise KeyError(f"no RoboTasks task {task_name!r}; valid: {sorted(DESIGN)}")
    ds = load_dataset("robotasks")
    task = ds.tasks[ds.task_names.index(task_name)]
    design = DESIGN[task_name]
    if with_starts:
        starts, methods, errors = start_configurations(task.positions, task.quaternions)
    else:
        old = load_task_spec(task_name)
        starts = np.asarray(old["start"]["qpos"], dtype=float)
        methods = old["derived"]["start_method"]
        errors = old["derived"]["start_forward_tracking_error_max"]
    derived = _DERIVE[task_name](task, design, starts)
    doc: dict[str, dict[str, Any]] = {
        "task": {"name": task_name, "dataset": "robotasks", **design["task"]},
        "grasp": dict(design["grasp"]),
        "scene": dict(derived["scene"]),
        "success": dict(design["success"]),
    }
    if "solver" in design:
        doc["solver"] = dict(design["solver"])
    doc["derived"] = dict(derived["derived"])
    doc["derived"]["start_method"] = methods
    doc["derived"]["start_forward_tracking_error_max"] = errors
    doc["start"] = {"qpos": starts}
    return doc
