"""ObstacleRotate's derivation (build time only: `clfd_bench.envs.robotasks.derive.derive_spec`
runs it for `eval/make_task_specs.py`; no env imports it): its design constants over the shared
defaults (`DESIGN`), the observer's argument for each design constant of a criterion
(`OBSERVER`), and `derive`, its scene and thresholds from the demonstrations, each with its
procedure as a comment.

What is derived: the table as the bottle's; the obstacle's faces moved in until every demo's box
and arm clear it by 1.5 cm (replayed with the obstacle a ghost); the shelf as the bottle's; the
turn the demos make and undo.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from clfd_bench.envs.robotasks.derive_common import (
    PLACE_CENTRE_COMMENT,
    POSITION_MARGIN,
    REPLAYED,
    TABLE_COMMENT,
    TURN_MARGIN_DEG,
    design,
    draft,
    ghost_clearance,
    hand_x,
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
    grasp=weld_grasp("object", 0.03),
    scene={"shelf_half_size": [0.12, 0.12], "clearance": POSITION_MARGIN,
           "table_fraction": 0.2, "table_clearance": POSITION_MARGIN,
           "obstacle_xy": [0.20, 0.43, -0.24, 0.00], "obstacle_top": 0.30},
    success={"max_tilt_deg": 15.0, "min_height": -0.005, "max_height": 0.01},
    camera={"distance": 1.35, "azimuth": 160.0, "elevation": -30.0})

#: The observer's argument for each design constant of a success criterion (why an observer
#: would sign the verdicts at that bound), written next to the value in the spec.
OBSERVER: dict[str, dict[str, str]] = {"success": {
    "max_tilt_deg": (
        "observer: lying on the shelf. The box's top face at most this far (deg) from "
        "level at the end. Design. Why an observer signs it: on the flat shelf it is level "
        f"(0.0 deg {REPLAYED}); 15 deg lifts one end of the 20 cm box 5.2 cm: propped, "
        "not lying"),
    "min_height": (
        "observer: on the shelf. The box's lowest point at least this far (m) above the "
        "shelf's top at the end (negative: the contact's give; deeper, it has sunk in: a "
        "physics failure)"),
    "max_height": (
        "the box's lowest point at most this high (m) above the shelf's top at the end. "
        f"Design. Why an observer signs it: lying on the board it touches it (-0.07 mm "
        f"{REPLAYED}); 1 cm up, the box rests on something else"),
}}


def derive(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = design["grasp"]
    turns = np.array([_turn_deg(q) for q in task.quaternions])  # [N, T] about world z
    peak = turns[np.arange(len(turns)), np.abs(turns).argmax(1)]
    sign = float(np.sign(np.median(peak)))
    turn = {"turn_sign": sign, "min_turn_deg": float(np.min(sign * peak) - TURN_MARGIN_DEG),
            "max_end_turn_deg": float(np.abs(turns[:, -1]).max() + TURN_MARGIN_DEG)}
    table_z, start_lows = table_below(task, "obstaclerotate", "object", grasp,
                                      d["table_fraction"], d["table_clearance"])
    lows, coms = held_prop_lows("obstaclerotate", "object", task.positions[:, -1],
                                task.quaternions[:, -1], grasp)
    centre = coms[:, :2].mean(0)
    scene = {"table_z": table_z,
             "obstacle_xy": list(d["obstacle_xy"]), "obstacle_top": float(d["obstacle_top"]),
             "shelf_top": [float(centre[0]), float(centre[1]), float(lows.min() - d["clearance"])],
             "shelf_half_size": d["shelf_half_size"], "shelf_yaw_deg": 0.0,
             "place_centre": coms[:, :2]}
    top, shelf_gaps = lower_until_clear(task, draft("obstaclerotate", design, scene, turn,
                                                    starts),
                                        "object", "shelf_top",
                                        ("shelf_board", "shelf_support"), d["clearance"])
    # The obstacle: shrunk (the face nearest to where the demos come closest moved in) until
    # every demo keeps the box and the arm `clearance` away from it.
    c = float(d["clearance"])
    for _ in range(12):
        gaps, where, _ = ghost_clearance(task, draft("obstaclerotate", design, scene, {
            **turn, "max_release_height": 1.0, "place_radius": 1.0}, starts), ("obstacle_box",))
        j = int(np.argmin(gaps))
        deficit = c - float(gaps[j])
        if deficit <= 5e-4:
            break
        x0, x1, y0, y1 = scene["obstacle_xy"]
        p = where[j]
        faces = {"x0": abs(p[0] - x0), "x1": abs(p[0] - x1), "y0": abs(p[1] - y0),
                 "y1": abs(p[1] - y1), "top": abs(p[2] - scene["obstacle_top"])}
        # a witness on the top's edge counts as the top: something passes over the obstacle
        face = "top" if faces["top"] < 1e-3 else min(faces, key=faces.get)
        step = deficit + 1e-3
        if face == "top":
            scene["obstacle_top"] = float(scene["obstacle_top"] - step)
        else:
            box = dict(zip(("x0", "x1", "y0", "y1"), (x0, x1, y0, y1), strict=True))
            box[face] += step if face in ("x0", "y0") else -step
            scene["obstacle_xy"] = [float(box[k]) for k in ("x0", "x1", "y0", "y1")]
    else:
        raise RuntimeError("obstaclerotate: the obstacle did not clear the demos in 12 steps")
    released = release_points(task, draft("obstaclerotate", design, scene, turn, starts))
    place = place_bounds(lows, coms, top, released)
    return {
        "scene": scene,
        "success": {**place["success"], **turn},
        "derived": {"demo_peak_turn_deg": peak, "demo_end_turn_deg": turns[:, -1],
                    "start_lowest_z": start_lows, "object_end_lowest_z": lows,
                    "object_end_com": coms, "shelf_path_clearance": shelf_gaps,
                    "obstacle_clearance": gaps, **place["derived"]},
        "comments": {"scene": {
            "table_z": TABLE_COMMENT,
            "obstacle_xy": "the obstacle's footprint (x0, x1, y0, y1). Procedure: the largest "
                           "box inside the demos' bend that no grasp point comes within 6.5 cm "
                           "of, x [0.20, 0.43] x y [-0.24, 0.00] (docs/design/robotasks9, "
                           "derive_sketch.py), its faces then moved in where a demo's box or "
                           "arm came within 1.5 cm of it ([derived] obstacle_clearance)",
            "obstacle_top": "the obstacle's top: 0.30 m (design: the demos' paths go around "
                            "the footprint, never over it, up to that height), lowered where a "
                            "demo's arm passes over it closer than 1.5 cm",
            "shelf_top": "centre of the shelf's top: under the mean of the box's centres at "
                         "the demos' last poses, 1.5 cm under the lowest point the box "
                         "reaches there, and lower if needed until every demo's box stays "
                         "1.5 cm clear of the shelf on its way ([derived] "
                         "shelf_path_clearance)",
            "place_centre": PLACE_CENTRE_COMMENT},
            "success": {**place["comments"],
                        "turn_sign": "the direction the demos turn the box about the world's "
                                     "z axis (-1: clockwise seen from above): the sign of the "
                                     "demos' largest turns ([derived] demo_peak_turn_deg)",
                        "min_turn_deg": "while held, the box must have turned at least this "
                                        "far in that direction (its long axis' heading seen "
                                        "from above). Procedure: the demos' smallest largest "
                                        "turn less 10 deg",
                        "max_end_turn_deg": "when let go, the box's heading must be back "
                                            "within this of its start heading. Procedure: the "
                                            "demos' largest end turn ([derived] "
                                            "demo_end_turn_deg) + 10 deg"}},
    }


def _turn_deg(quaternions: np.ndarray) -> np.ndarray:
    """[T] how far the hand's x axis has turned about the world's z axis since the first of
    the hand quaternions [T, 4] (its heading seen from above, unwrapped), degrees."""
    heading = np.array([hand_x(q)[:2] for q in quaternions])
    angle = np.unwrap(np.arctan2(heading[:, 1], heading[:, 0]))
    return np.degrees(angle - angle[0])
