"""PanToStove's derivation (build time only: `clfd_bench.envs.robotasks.derive.derive_spec`
runs it for `eval/make_task_specs.py`; no env imports it): its design constants over the shared
defaults (`DESIGN`), the observer's argument for each design constant of a criterion
(`OBSERVER`), and `derive`, its scene and thresholds from the demonstrations, each with its
procedure as a comment.

What is derived: the table 1.5 cm + the rack's base under the lowest point the pan reaches in
the first fifth of the demos; the rack's walls as the glass tray's; the stove as the bottle's
shelf, under the pan at the demos' ends; the release height and place radius bounds.
"""

from __future__ import annotations

from typing import Any

from clfd_bench.envs.robotasks.derive_common import (
    KNOCK_SHIFT,
    POSITION_MARGIN,
    REPLAYED,
    TABLE_COMMENT,
    TRAY,
    design,
    draft,
    held_prop_lows,
    knock_argument,
    lower_until_clear,
    place_bounds,
    release_points,
    tray_walls,
    weld_grasp,
)

#: The task's design constants: the shared defaults (`derive_common.design`, `weld_grasp`)
#: and what differs.
DESIGN = design(
    grasp=weld_grasp("pan", 0.004),
    scene={"stove_half_size": [0.15, 0.15], "clearance": POSITION_MARGIN, **TRAY},
    success={"max_tilt_deg": 15.0, "min_height": -0.005, "max_height": 0.01,
             "max_rack_shift": KNOCK_SHIFT, "max_rack_tilt_deg": 10.0},
    camera={"distance": 1.3, "azimuth": 150.0, "elevation": -24.0})

#: The observer's argument for each design constant of a success criterion (why an observer
#: would sign the verdicts at that bound), written next to the value in the spec.
OBSERVER: dict[str, dict[str, str]] = {"success": {
    "max_tilt_deg": (
        "observer: lying flat, bottom down. The pan's bottom at most this far (deg) from "
        "facing down at the end. Design. Why an observer signs it: flat on the stove it is "
        f"level (0.02 deg {REPLAYED}); 15 deg lifts the far side of the 16 cm bottom "
        "4.1 cm: resting on its rim or handle, not flat; must-fail executions that let it "
        "go leave it 19-90 deg"),
    "min_height": (
        "observer: on the stove. The bottom's outer centre at least this far (m) above the "
        "stove's top at the end (negative: the contact's give; deeper, it has sunk in: a "
        "physics failure)"),
    "max_height": (
        "the bottom's outer centre at most this high (m) above the stove's top at the end. "
        f"Design. Why an observer signs it: flat on the stove it touches it (-0.07 mm "
        f"{REPLAYED}); 1 cm up, the pan rests on something else"),
    "max_rack_shift": knock_argument(
        "pan rack", "the demos drag the pan 9-26 cm along the rack's floor and move the "
        "rack at most 0.7 mm; 1 cm noise and start offsets rub the pan along a wall and "
        "nudge it up to 8.4 mm (0.1 deg): the one knock bound a good execution comes "
        "within 1.2 cm of", "(shortcut, rush-wait) move it 2.8-35 cm",
        "2 cm is 5 % of the 26 x 39 cm rack: a nudge, not a knock, up to it; the mirror "
        "rollouts that move it 1.3 cm fail by their collision"),
    "max_rack_tilt_deg": (
        "observer: the rack is not tipped. It may tilt at most this far (deg) at any step. "
        f"Design. Why an observer signs it: it stays level (0.1 deg at most {REPLAYED}); "
        "10 deg lifts one side of its 26 cm base 4.5 cm off the table; executions that run "
        "into it tilt it up to 32 deg"),
}}


def derive(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    base = float(d["tray_base_thickness"])
    # the rack on the table, at most at the robot's base (lower: the robot on a mount)
    start_lows, table_z, wall_height, extent, walls = tray_walls(
        task, "pan2stove", "pan", 1, grasp, d, lambda z: min(0.0, z))
    lows, bottoms = held_prop_lows("pan2stove", "pan", task.positions[:, -1],
                                   task.quaternions[:, -1], grasp, geom="pan_bottom")
    centre = bottoms[:, :2].mean(0)
    scene = {"table_z": table_z, "tray_walls": walls, "tray_wall_height": wall_height,
             "tray_base_thickness": base, "tray_wall_thickness": d["tray_wall_thickness"],
             "stove_top": [float(centre[0]), float(centre[1]),
                           float(lows.min() - d["clearance"])],
             "stove_half_size": d["stove_half_size"], "stove_yaw_deg": 0.0,
             "place_centre": bottoms[:, :2]}
    top, gaps = lower_until_clear(task, draft("pan2stove", design, scene, {}, starts), "pan",
                                  "stove_top", ("stove_top", "stove_support"), d["clearance"])
    released = release_points(task, draft("pan2stove", design, scene, {}, starts))
    place = place_bounds(lows, bottoms, top, released)
    return {
        "scene": scene,
        "success": place["success"],
        "derived": {"start_lowest_z": start_lows, "pan_end_lowest_z": lows,
                    "pan_end_bottom_centre": bottoms, "stove_path_clearance": gaps,
                    "rack_pan_extent": extent, **place["derived"]},
        "comments": {"scene": {
            "table_z": TABLE_COMMENT,
            "tray_walls": "the inner faces of the pan rack's walls (rack frame: origin on the "
                          "table under the grasp point at the start, x along the pan's y axis, "
                          "horizontal in its plane; x_lo, x_hi, y_lo, y_hi): 1.5 cm clear of "
                          "where the demos move the pan below the walls' top in their first "
                          "fifth ([derived] rack_pan_extent)",
            "tray_wall_height": "the walls' top above the rack's base: 2.4 cm (design) up "
                                "every demo's pan from its lowest point at the start",
            "stove_top": "centre of the stove's top: under the mean of the pan's bottom centre "
                         "at the demos' last poses, 1.5 cm under the lowest point the pan "
                         "reaches there, and lower if needed until every demo's pan stays "
                         "1.5 cm clear of the stove on its way ([derived] "
                         "stove_path_clearance)",
            "place_centre": "per demo j: where the pan's bottom centre (x, y) is when demo j "
                            "lets it go (the held pan at demo j's last pose)"},
            "success": place["comments"]},
    }
