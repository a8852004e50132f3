"""BottleShelving's derivation (build time only: `clfd_bench.envs.robotasks.derive.derive_spec`
runs it for `eval/make_task_specs.py`; no env imports it): its design constants over the shared
defaults (`DESIGN`), the observer's argument for each design constant of a criterion
(`OBSERVER`), and `derive`, its scene and thresholds from the demonstrations, each with its
procedure as a comment.

What is derived: the shelf top 1 cm under the lowest point the held bottle reaches at the demos'
end poses, centred under the bottles' end positions; the release height and place radius bounds.
"""

from __future__ import annotations

from typing import Any

from clfd_bench.envs.robotasks.derive_common import (
    PLACE_CENTRE_COMMENT,
    POSITION_MARGIN,
    REPLAYED,
    TABLE_COMMENT,
    design,
    draft,
    held_prop_lows,
    lower_until_clear,
    place_bounds,
    release_points,
    table_below,
    weld_grasp,
)

#: The task's design constants: the shared defaults (`derive_common.design`, `weld_grasp`)
#: and what differs.
DESIGN = design(
    grasp=weld_grasp("bottle", 0.0135, contact="line_z", contact_radius=0.0135),
    scene={"shelf_half_size": [0.12, 0.09], "clearance": POSITION_MARGIN, "table_fraction": 0.2,
           "table_clearance": POSITION_MARGIN},
    success={"max_tilt_deg": 20.0, "min_height": 0.0, "max_height": 0.045},
    camera={"distance": 1.15, "azimuth": 140.0, "elevation": -24.0})

#: The observer's argument for each design constant of a success criterion (why an observer
#: would sign the verdicts at that bound), written next to the value in the spec.
OBSERVER: dict[str, dict[str, str]] = {"success": {
    "max_tilt_deg": (
        "observer: lying on the shelf. The bottle's axis at most this far (deg) from "
        "horizontal at the end. Design. Why an observer signs it: on the flat board the "
        f"axis is horizontal (0.04 deg {REPLAYED}); it rests tilted only on something "
        "else, and 20 deg lifts one end of the 14.5 cm bottle 5 cm off the board: propped, "
        "not lying; a standing bottle is at 90 deg"),
    "min_height": (
        "observer: resting on the board. The bottle's centre must be at least this high "
        "(m) above the shelf's top at the end: below it, it has sunk into the board (a "
        "physics failure)"),
    "max_height": (
        "the bottle's centre at most this high (m) above the shelf's top at the end. "
        f"Design. Why an observer signs it: lying on the board its centre is its radius, "
        f"2.8 cm, above it ({REPLAYED}); 4.5 cm is 1.7 cm more, resting on something "
        "else, and below the 7 cm of a standing bottle"),
}}


def derive(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    table_z, start_lows = table_below(task, "bottle2shelf", "bottle", grasp,
                                      d["table_fraction"], d["table_clearance"])
    lows, coms = held_prop_lows("bottle2shelf", "bottle", task.positions[:, -1],
                                task.quaternions[:, -1], grasp)
    centre = coms[:, :2].mean(0)
    scene = {"table_z": table_z,
             "shelf_top": [float(centre[0]), float(centre[1]), float(lows.min() - d["clearance"])],
             "shelf_half_size": d["shelf_half_size"], "shelf_yaw_deg": 0.0,
             "place_centre": coms[:, :2]}
    top, gaps = lower_until_clear(task, draft("bottle2shelf", design, scene, {}, starts),
                                  "bottle", "shelf_top", ("shelf_board", "shelf_support"),
                                  d["clearance"])
    released = release_points(task, draft("bottle2shelf", design, scene, {}, starts))
    place = place_bounds(lows, coms, top, released)
    return {
        "scene": scene,
        "success": place["success"],
        "derived": {"start_lowest_z": start_lows, "bottle_end_lowest_z": lows,
                    "bottle_end_com": coms, "shelf_path_clearance": gaps, **place["derived"]},
        "comments": {"success": place["comments"], "scene": {
            "table_z": TABLE_COMMENT,
            "shelf_top": "centre of the shelf's top: under the mean of the bottle's centres at "
                         "the demos' last poses, 1.5 cm under the lowest point the bottle "
                         "reaches there, and lower if needed until every demo's bottle stays "
                         "1.5 cm clear of the shelf on its way ([derived] "
                         "shelf_path_clearance)",
            "place_centre": PLACE_CENTRE_COMMENT}},
    }
