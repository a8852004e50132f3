"""PlateStacking's derivation (build time only: `clfd_bench.envs.robotasks.derive.derive_spec`
runs it for `eval/make_task_specs.py`; no env imports it): its design constants over the shared
defaults (`DESIGN`), the observer's argument for each design constant of a criterion
(`OBSERVER`), and `derive`, its scene and thresholds from the demonstrations, each with its
procedure as a comment.

What is derived: the table 3 mm under the lowest point the plate reaches in the first fifth of
the demos (where it stands in the rack), the rack's pegs 1.5 cm clear of where the plate's rim
passes in that fifth, the platform top 1 cm under the lowest point of the plate in the last
fifth of the demos, centred under the plates' end positions; the release height and place radius
bounds.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.robotasks.derive_common import (
    KNOCK_SHIFT,
    PLACE_CENTRE_COMMENT,
    POSITION_MARGIN,
    REPLAYED,
    TABLE_COMMENT,
    design,
    draft,
    held_prop_lows,
    knock_argument,
    lower_until_clear,
    place_body,
    place_bounds,
    release_points,
    table_below,
    task_model,
    weld_grasp,
)
from clfd_bench.sim.scene_fit import grasp_points, prop_pose

#: The task's design constants: the shared defaults (`derive_common.design`, `weld_grasp`)
#: and what differs.
DESIGN = design(
    grasp=weld_grasp("plate", 0.005),
    scene={"platform_half_size": [0.13, 0.08], "clearance": POSITION_MARGIN,
           "place_fraction": 0.2, "table_clearance": POSITION_MARGIN,
           "block_clearance": POSITION_MARGIN, "block_x": 0.045, "block_rise": 0.024,
           "rack_base_thickness": 0.005, "rack_fraction": 0.2},
    success={"max_tilt_deg": 25.0, "min_height": 0.0, "max_height": 0.03,
             "max_rack_shift": KNOCK_SHIFT, "max_rack_tilt_deg": 10.0},
    camera={"distance": 1.25, "azimuth": 140.0, "elevation": -24.0})

#: The observer's argument for each design constant of a success criterion (why an observer
#: would sign the verdicts at that bound), written next to the value in the spec.
OBSERVER: dict[str, dict[str, str]] = {"success": {
    "max_tilt_deg": (
        "observer: lying on the platform. The plate's face at most this far (deg) from "
        "horizontal at the end. Design. Why an observer signs it: lying on the flat "
        f"platform it is level (0.01 deg {REPLAYED}); 25 deg lifts the far rim of the "
        "14 cm plate 5.9 cm: propped (on the rack, a finger), not lying; standing is 90 deg"),
    "min_height": (
        "observer: resting on the platform. The plate's centre must be at least this high "
        "(m) above the platform's top at the end: below it, it has sunk into the board (a "
        "physics failure)"),
    "max_height": (
        "the plate's centre at most this high (m) above the platform's top at the end. "
        "Design. Why an observer signs it: lying on the board its centre is half its 1 cm "
        f"thickness above it (0.49 cm {REPLAYED}); 3 cm is 2.5 cm more, resting on "
        "something else, and below the 7 cm of a plate standing on its rim"),
    "max_rack_shift": knock_argument(
        "dish rack", f"{REPLAYED} the rack moves at most 0.2 mm (settling)",
        "(shortcut, rush-wait) move it 7-24 cm", "2 cm is 15 % of the 13 x 14.5 cm rack; "
        "learned executions (the RoboTasks fast grid) that bump it 1.2-1.9 cm while "
        "laying the plate flat leave it in place in the closing frame (FT after task 2, "
        "demo 2: 1.23 cm) and pass; from 2.3 cm it is pushed aside and they fail "
        "(docs/execution.md, 'Learned executions nearest the bounds')"),
    "max_rack_tilt_deg": (
        "observer: the rack is not tipped. It may tilt at most this far (deg) at any step. "
        f"Design. Why an observer signs it: it stays level ({REPLAYED} 0.0 deg); 10 deg "
        "lifts one side of its 13 cm base 2.3 cm off the table; executions that run into "
        "it tilt it 10-90 deg"),
}}


def derive(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    n_rack = int(task.positions.shape[1] * d["rack_fraction"])
    # The plate stands 1.5 cm above the rack's base, the base on the table.
    table_z, rack_lows = table_below(task, "platestandingtolying", "plate", grasp,
                                     d["rack_fraction"],
                                     d["table_clearance"] + d["rack_base_thickness"])
    n_place = int(task.positions.shape[1] * d["place_fraction"])
    lows_end, coms_end = held_prop_lows("platestandingtolying", "plate",
                                        task.positions[:, -n_place:],
                                        task.quaternions[:, -n_place:], grasp)
    top = float(lows_end.min() - d["clearance"])
    centre = coms_end[:, -1, :2].mean(0)
    provisional = {"table_z": table_z, "block_offsets": [[0.0, 9.0]] * 4, "block_height": 0.02,
                   "platform_top": [float(centre[0]), float(centre[1]), top],
                   "platform_half_size": d["platform_half_size"], "platform_yaw_deg": 0.0,
                   "place_centre": coms_end[:, -1, :2]}
    top, gaps = lower_until_clear(task, draft("platestandingtolying", design, provisional, {},
                                              starts),
                                  "plate", "platform_top", ("platform_top", "platform_support"),
                                  d["clearance"])
    end_lows, coms_end, lows_end = lows_end[:, -1], coms_end[:, -1], lows_end.min(1)
    model, _ = task_model("platestandingtolying")
    block_half = model.geom_size[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM,
                                                   "rack_peg1")]
    bx = d["block_x"]
    # The blocks reach `block_rise` up the plate from its lowest point at the start.
    block_height = float(rack_lows.max() + d["block_rise"] - table_z)
    extent = _rack_gap(task, grasp, table_z + block_height, n_rack, bx + block_half[0])
    by_lo = extent[0] - d["block_clearance"] - block_half[1]
    by_hi = extent[1] + d["block_clearance"] + block_half[1]
    offsets = [[-bx, by_lo], [bx, by_lo], [-bx, by_hi], [bx, by_hi]]
    scene = {"table_z": table_z, "block_offsets": offsets, "block_height": block_height,
             "rack_base_thickness": d["rack_base_thickness"],
             "platform_top": [float(centre[0]), float(centre[1]), top],
             "platform_half_size": d["platform_half_size"], "platform_yaw_deg": 0.0,
             "place_centre": coms_end[:, :2]}
    released = release_points(task, draft("platestandingtolying", design, scene, {}, starts))
    place = place_bounds(end_lows, coms_end, top, released)
    return {
        "scene": scene,
        "success": place["success"],
        "derived": {"start_lowest_z": rack_lows, "plate_end_lowest_z": lows_end,
                    "plate_end_centre": coms_end, "platform_path_clearance": gaps,
                    "rack_plate_extent_y": extent,
                    **place["derived"]},
        "comments": {"scene": {
            "table_z": TABLE_COMMENT,
            "block_height": "the rack's pegs reach 2.4 cm (design) up every demo's plate "
                            "from its lowest point at the start ([derived] start_lowest_z, "
                            "max): the demos lift the rim ~3 cm before they move it sideways",
            "block_offsets": "the rack's pegs (rack frame: x along the plate, y across it, "
                             "origin under the plate's start centre): 1.5 cm clear of where the "
                             "demos move the plate's rim below the blocks' top in their first "
                             "fifth ([derived] rack_plate_extent_y)",
            "platform_top": "under the mean of the plate's final centres, 1.5 cm under the "
                            "lowest point of the plate in the demos' last fifth, and lower if "
                            "needed until every demo's plate stays 1.5 cm clear of the "
                            "platform on its way ([derived] platform_path_clearance)",
            "place_centre": PLACE_CENTRE_COMMENT},
            "success": place["comments"]},
    }


def _rack_gap(task, grasp: dict[str, Any], top: float, n_samples: int,
              x_half: float) -> np.ndarray:
    """[2] the extent (min, max) along the rack's y axis (the plate normal's horizontal
    direction, origin under the plate's start centre) of the plate's rim below the blocks' top
    and within `x_half` of the rack's middle, over the first `n_samples` of every demo: where
    the blocks must not be."""
    model, data = task_model("platestandingtolying")
    disc = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "plate_disc")
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "plate")
    radius, half_t = model.geom_size[disc][:2]
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
            place_body(model, data, "plate", p, q)
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
