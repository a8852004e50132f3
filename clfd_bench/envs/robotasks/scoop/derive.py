"""Scoop's derivation (build time only: `clfd_bench.envs.robotasks.derive.derive_spec`
runs it for `eval/make_task_specs.py`; no env imports it): its design constants over the shared
defaults (`DESIGN`), the observer's argument for each design constant of a criterion
(`OBSERVER`), and `derive`, its scene and thresholds from the demonstrations, each with its
procedure as a comment.

What is derived: the beans' level 3.5 cm over the highest of the demos' lowest points of the
bowl's lip; the bin's floor 1.5 cm under the scoop's lowest point, its walls 1.5 cm outside the
scoop below the rim, moved out until every demo's scoop and arm clear them by 1.5 cm (replayed
with the bin a ghost); from the demos replayed (as they are, 2x slower, 1.5x faster) the beans
they end with, the beans they spill and how level the bowl ends.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from clfd_bench.envs.robotasks.derive_common import (
    POSITION_MARGIN,
    TURN_MARGIN_DEG,
    design,
    draft,
    extent_below,
    ghost_clearance,
    held_prop_lows,
    prop_points,
    replay_demos,
    weld_grasp,
)

#: The task's design constants: the shared defaults (`derive_common.design`, `weld_grasp`)
#: and what differs.
DESIGN = design(
    task={"release_after": False},
    grasp=weld_grasp("scoop", 0.008, contact="line_x", contact_radius=0.008),
    scene={"n_beans": 6, "bean_radius": 0.012, "bean_mass": 0.002, "grain_spacing": 0.01,
           # the bowl of tasks/scoop.xml in the scoop's frame: inside its walls and
           # floor, from the opening (low z) up; and its outside
           "bowl_cavity": [[0.214, -0.031, -0.02], [0.286, 0.031, 0.016]],
           "bowl_outer": [[0.21, -0.035, -0.02], [0.29, 0.035, 0.02]],
           "dip": 0.035, "rim_above": 0.0, "clearance": POSITION_MARGIN,
           "bin_wall_thickness": 0.008},
    solver={"solver": "newton", "iterations": 20, "ls_iterations": 10, "tolerance": 1e-8,
            "cone": "pyramidal"},
    camera={"distance": 1.1, "azimuth": 145.0, "elevation": -26.0})

#: (Its design constants' arguments are written with their procedure in `derive`.)
OBSERVER: dict[str, dict[str, str]] = {}


_BIN_GEOMS = ("bin_floor", "bin_wall_back", "bin_wall_front", "bin_wall_right", "bin_wall_left")


def derive(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    c = float(d["clearance"])
    lows, _ = held_prop_lows("scoop", "scoop", task.positions, task.quaternions, grasp)
    dips = lows.min(1)  # the scoop's lowest point per demo
    # the bowl's lip (the edge of its opening) at its lowest per demo: beans flow in over it
    lo, hi = np.asarray(d["bowl_cavity"], dtype=float)
    lip = np.array([[x, y, lo[2]] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])])
    lips = prop_points(task.positions, task.quaternions, grasp, lip)[..., 2].min((1, 2))
    surface = float(lips.max() + d["dip"])
    rim = surface + float(d["rim_above"])
    floor = float(dips.min() - c)
    ext = extent_below("scoop", "scoop", task.positions, task.quaternions, grasp, rim)
    walls = [float(ext[0] - c), float(ext[1] + c), float(ext[2] - c), float(ext[3] + c)]
    scene = {"bin_walls": walls, "bin_floor_z": floor, "bin_rim_z": rim, "surface_z": surface,
             **{k: d[k] for k in ("n_beans", "bean_radius", "bean_mass", "grain_spacing",
                                  "bowl_cavity",
                                  "bowl_outer", "bin_wall_thickness")}}
    loose = {"min_beans": 0, "max_spilled": 10 ** 6, "max_tilt_deg": 180.0}
    # The bin's walls and floor moved out until every demo's scoop and arm stay `clearance`
    # away from them (replayed, the bin a ghost): the hand may come down lower than the scoop.
    for _ in range(12):
        gaps, where, which = ghost_clearance(task, draft("scoop", design, scene, loose, starts),
                                             _BIN_GEOMS)
        j = int(np.argmin(gaps))
        deficit = c - float(gaps[j])
        if deficit <= 5e-4:
            break
        step = deficit + 1e-3
        if which[j] == "bin_floor":
            scene["bin_floor_z"] = float(scene["bin_floor_z"] - step)
        else:  # against a wall, or over its top: that wall goes out
            k = _BIN_GEOMS.index(which[j]) - 1
            scene["bin_walls"][k] += -step if k in (0, 2) else step
    else:
        raise RuntimeError("scoop: the bin did not clear the demos in 12 steps")
    doc = draft("scoop", design, scene, loose, starts)
    infos = replay_demos(task, doc)
    beans = np.array([i["beans_in_scoop"] for i in infos])
    spilled = np.array([i["beans_spilled"] for i in infos])
    scooped = np.array([i["beans_scooped"] for i in infos])
    # Replayed 2x slower and 1.5x faster (the same path): how much that changes the scoopful.
    timed = [replay_demos(task, doc, time_scale=f) for f in (2.0, 1.0 / 1.5)]
    timed_beans = np.array([[i["beans_in_scoop"] for i in infos_f] for infos_f in timed])
    tilts = np.array([i["bowl_tilt_deg"] for i in infos])
    return {
        "scene": scene,
        "success": {"min_beans": int(max(1, min(beans.min(), timed_beans.min()) - 1)),
                    "max_spilled": int(spilled.max() + 1),
                    "max_tilt_deg": float(tilts.max() + TURN_MARGIN_DEG)},
        "derived": {"scoop_lowest_z": dips, "lip_lowest_z": lips, "bin_clearance": gaps,
                    "beans_scooped_demos": scooped, "beans_in_scoop_demos": beans,
                    "beans_spilled_demos": spilled, "beans_in_scoop_slower": timed_beans[0],
                    "beans_in_scoop_faster": timed_beans[1], "end_bowl_tilt_deg": tilts},
        "comments": {
            "scene": {
                "bin_walls": "the bin's inner faces (x0, x1, y0, y1). Procedure: the extent of "
                             "the scoop's surface below the rim over the demos, 1.5 cm out, then "
                             "moved out where a demo's scoop or arm came within 1.5 cm of a wall "
                             "(the demos replayed with the bin a ghost; [derived] "
                             "bin_clearance)",
                "bin_floor_z": "the bin's inner floor: 1.5 cm under the lowest point the scoop "
                               "reaches in the demos ([derived] scoop_lowest_z)",
                "surface_z": "the level of the beans: `dip` (design, 3.5 cm) over the highest of "
                             "the demos' lowest lip points (the edge of the bowl's opening; "
                             "[derived] lip_lowest_z), so that in every demo the beans flow "
                             "into the bowl over its lip",

                "n_beans": "design: the pool of beans the scoop can hold at once (free "
                           "spheres; the bin's contents are grain sites, see "
                           "clfd_bench.envs.robotasks.scoop.scene.ScoopScene)"},
            "success": {
                "min_beans": "beans that must be in the scoop at the end (after 1 s holding "
                             "still). Procedure: the demos replayed as they are, 2x slower and "
                             "1.5x faster ([derived] beans_in_scoop_*): one fewer than the "
                             "fewest, at least 1",
                "max_spilled": "beans that may land outside the bin (table, stand, rim). "
                               "Procedure: the demos replayed ([derived] beans_spilled_demos): "
                               "one more than the worst demo",
                "max_tilt_deg": "at the end the bowl's opening must face up within this "
                                "(deg). Procedure: the demos replayed ([derived] "
                                "end_bowl_tilt_deg): the largest + 10 deg. Where the scoop "
                                "ends is not judged: nothing in the scene marks demo j's end "
                                "(no container)"},
        },
    }
