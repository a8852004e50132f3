"""MatFolding's derivation (build time only: `clfd_bench.envs.robotasks.derive.derive_spec`
runs it for `eval/make_task_specs.py`; no env imports it): its design constants over the shared
defaults (`DESIGN`), the observer's argument for each design constant of a criterion
(`OBSERVER`), and `derive`, its scene and thresholds from the demonstrations, each with its
procedure as a comment.

What is derived: the table 1.5 cm under the lowest start grasp point, lowered until every demo's
hand clears it by 1.5 cm; the bound of the pinched edge's turn in the fingers (the demos'
largest + 10 deg); from the demos replayed, where each lets the edge go in the room (its radius
from how much replaying the demos 2x slower and 1.5x faster moves it), the strips they turn over
and how far they drag the mat (the largest + the demos' spread).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from clfd_bench.envs.robotasks.derive_common import (
    POSITION_MARGIN,
    TURN_MARGIN_DEG,
    demo_actions,
    design,
    ghost_clearance,
    weld_grasp,
)
from clfd_bench.envs.robotasks.env import RoboTaskEnv
from clfd_bench.sim.scene_fit import grasp_points

#: The task's design constants: the shared defaults (`derive_common.design`, `weld_grasp`)
#: and what differs.
DESIGN = design(
    grasp=weld_grasp("mat_pinch", 0.0015, exclude=["mat10", "mat9", "mat8"]),
    scene={"table_clearance": POSITION_MARGIN, "table_xy": [-0.3, 0.9, -1.0, 0.6],
           "jitter_factor": 1.3},
    success={"max_layer_height": 0.01},
    camera={"distance": 1.3, "azimuth": 60.0, "elevation": -30.0})

#: (Its design constants' arguments are written with their procedure in `derive`.)
OBSERVER: dict[str, dict[str, str]] = {}


def derive(task, design, starts) -> dict[str, Any]:
    d = design["scene"]
    grasp = dict(design["grasp"])
    g0 = grasp_points(task.positions[:, 0], task.quaternions[:, 0])
    table_z = float(min(0.0, g0[:, 2].min() - d["table_clearance"]))
    n = len(task.positions)
    scene = {"table_z": table_z, "table_xy": d["table_xy"], "release_edge": np.zeros((n, 3))}
    # nothing judged while deriving
    lenient = {"place_radius": 1.0, "min_turned_strips": 0, "max_drag": 10.0}
    # the pinch's turn with no bound
    free = {**grasp, "slip_joints": [["pinch_turn", 0.0, float(np.pi)]]}
    provisional = {"task": {"name": "matfolding", **design["task"]}, "grasp": free,
                   "scene": scene, "success": {**design["success"], **lenient},
                   "start": {"qpos": starts}}
    # lower the table until the hand clears it by 1.5 cm in every demo (the hand is tilted
    # 35-60 deg at the end: it comes lower than the fingertips)
    hand_gaps, _, _ = ghost_clearance(task, provisional, ("floor",))
    deficit = float(d["table_clearance"] - hand_gaps.min())
    if deficit > 0:
        scene["table_z"] = table_z = table_z - deficit
    free_runs = _mat_replays(task, provisional)
    bound = float(np.radians(np.degrees(free_runs["turn"].max()) + TURN_MARGIN_DEG))
    slip = {"slip_joints": [["pinch_turn", 0.0, bound]]}
    # where each demo lets the edge go and how it leaves the mat, in the scene with that bound;
    # and how much replaying the same paths 2x slower and 1.5x faster moves it
    doc = {**provisional, "grasp": {**grasp, **slip}}
    runs = _mat_replays(task, doc)
    if not np.isfinite(runs["release_edge"]).all():
        raise RuntimeError("matfolding: a demo replay never let the mat go")
    timed = [_mat_replays(task, doc, time_scale=f) for f in (2.0, 1.0 / 1.5)]
    jitter = [np.linalg.norm(r["release_edge"] - runs["release_edge"], axis=1) for r in timed]
    if not all(np.isfinite(v).all() for v in jitter):
        raise RuntimeError("matfolding: a slower / faster demo replay never let the mat go")
    k = float(d["jitter_factor"])
    scene["release_edge"] = runs["release_edge"]
    drags = runs["root_shift"]
    success = {
        "place_radius": max(POSITION_MARGIN, k * float(np.max(jitter))),
        "min_turned_strips": int(min(r.min() for r in [runs["turned"]] + [t["turned"]
                                                                          for t in timed]) - 1),
        # the demos' largest drag + the demos' own spread of drag (largest - smallest)
        "max_drag": float(2.0 * drags.max() - drags.min())}
    return {
        "scene": scene,
        "grasp": slip,
        "success": success,
        "derived": {"start_grasp_z": g0[:, 2], "hand_table_gap": hand_gaps,
                    "pinch_turn_max_deg": np.degrees(free_runs["turn"]),
                    "root_shift_max": drags,
                    "root_shift_max_slower": timed[0]["root_shift"],
                    "root_shift_max_faster": timed[1]["root_shift"],
                    "turned_strips": runs["turned"],
                    "turned_strips_slower": timed[0]["turned"],
                    "turned_strips_faster": timed[1]["turned"],
                    "release_edge_jitter_slower": jitter[0],
                    "release_edge_jitter_faster": jitter[1]},
        "comments": {
            "scene": {
                "table_z": "the table top: the lowest grasp point at the demos' starts "
                           "([derived] start_grasp_z) less 1.5 cm, lowered until the hand "
                           "clears it by 1.5 cm in every demo ([derived] hand_table_gap, at "
                           "the table before lowering); the mat lies on it and its last strips "
                           "ramp up to each demo's start grasp",
                "release_edge": "per demo j: where the middle of the mat's near edge is in the "
                                "world when the gripper lets it go in demo j's replay (where "
                                "the trajectory ends: it does not depend on how far the mat "
                                "was dragged)"},
            "grasp": {"slip_joints": (
                "how far the pinched edge may turn between the pads (the ball joint "
                "pinch_turn's angle since the grasp, rad) before it slips out. Procedure: the "
                "demos replayed with no bound ([derived] pinch_turn_max_deg), max + 10 deg")},
            "success": {
                "place_radius": (
                    "when the gripper opens, the near edge's middle must be within this "
                    "distance (3-D, world) of where demo j lets it go ([scene] release_edge). "
                    "Procedure: the 1.5 cm position margin (1 cm of noise and start offset an "
                    "execution must survive + 5 mm of servo lag and IK error), or 1.3 x the "
                    "largest shift the demos replayed 2x slower and 1.5x faster show "
                    "([derived] release_edge_jitter_*) if that is larger"),
                "min_turned_strips": (
                    "after the settling, at least this many strips of the near half must lie "
                    "turned over on the far half, in one layer (upside down within 25 deg, "
                    "over the far plate, at most max_layer_height above it): the mat folded in "
                    "half. Procedure: the fewest in the demos' replays, 2x slower and 1.5x "
                    "faster ([derived] turned_strips*), less one (in some demos the last "
                    "strips fold back at the near edge: the edge strip flips back when the "
                    "hand, tilted 35-60 deg back, lets it go 5-8 cm above the mat)"),
                "max_drag": (
                    "the far half's largest shift on the table over the episode (m) must be at "
                    "most this. Procedure: the largest in the demos' replays ([derived] "
                    "root_shift_max) + a margin of the demos' own spread (their largest less "
                    "their smallest). Argument for the margin: a mat lifted by one edge slides "
                    "towards the hand, and how far depends on the path (the strip chain "
                    "exaggerates it: 8-14 cm on the demos' paths where a flexcomp cloth "
                    "slides 1-3 cm; raising the demo's arc 5 cm mid-way drags the chain up to "
                    "6 cm further), so a valid path may drag it as much further as the demos' own "
                    "paths differ among themselves; more is a mat pulled across the table"),
                "max_layer_height": (
                    "observer: lying, not in the air. The far plate's middle plane at most "
                    "this high (m) above the table, a turned-over strip's hinge at most this "
                    "high above the far plate's. Design. Why an observer signs it: the mat is "
                    "3 mm thick, so a strip folded onto the far half lies 3 mm up and one "
                    "folded over another 6 mm; in every must-succeed replay (demo, 2x slower, "
                    "1.5x faster, noise, start offset; 45 rollouts, 2026-12-06) each counted "
                    "strip lies at most 6.0 mm up and the far plate at most 3.5 mm, while the "
                    "upside-down strips a stop-early leaves over the far half arch 1.1-2.0 cm "
                    "above it: in the air, not folded onto it")}},
    }


def _mat_replays(task, doc: dict[str, Any], time_scale: float = 1.0) -> dict[str, np.ndarray]:
    """Each demo replayed (+ 1 s settling, no motion-limit checks) in the scene of `doc`, its
    duration scaled by `time_scale` (as `_replay_demos`), [N] or [N, 3] per quantity:
    `turn`, the largest turn of the pinched edge between the pads while held (rad);
    `release_edge`, where the near edge's middle is in the world when the gripper lets it go
    (NaN: never let go); after the settling `turned`, the strips turned over onto the far half
    (`MatScene.turned_strips`), `root_shift`, the far plate's largest shift on the table (m)
    and `success`."""
    env = RoboTaskEnv("matfolding", spec=doc, limits=None)
    n = len(task.positions)
    out = {"turn": np.zeros(n), "release_edge": np.full((n, 3), np.nan),
           "turned": np.zeros(n, dtype=int), "root_shift": np.zeros(n),
           "success": np.zeros(n, dtype=bool)}
    for j in range(n):
        actions = demo_actions(env, task, j, time_scale=time_scale)
        env.reset(options={"demo": j, "horizon": len(actions)})
        for a in actions:
            env.step(a)
            if env.grasp.held(env.data):
                out["turn"][j] = max(out["turn"][j],
                                     env.grasp.slips(env.data).get("pinch_turn", 0.0))
        rec, scene = env.scene.record, env.scene
        if rec["release_edge"] is not None:
            out["release_edge"][j] = rec["release_edge"]
        out["turned"][j] = scene.turned_strips(env.data)
        info = env.evaluate()
        out["root_shift"][j] = info["max_root_shift"]
        out["success"][j] = info["is_success"]
    env.close()
    return out
