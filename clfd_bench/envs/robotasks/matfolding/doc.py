"""MatFolding's words: its paragraphs of `RoboTaskEnv`'s docstring and of tasks/README.md.
The success rules are written here once (`RULES`); the numbers they quote come from the task
spec (`numbers`), so they stay in step with it."""

from __future__ import annotations

from typing import Any

import numpy as np

#: What the task is, in tasks/README.md's table.
WHAT = (
    '60 × 30 cm mat (1 kg) on the table: its far half one rigid plate, its near half 10 '
    'hinged strips of 3 cm; the gripper pinches the middle of the near edge (turning between '
    'the pads as far as the demos need, + 10°) and folds the mat in half. The demos drag the '
    'mat 8–14 cm and turn it 9–23° as they fold it (a real mat lifted by one edge slides '
    'towards the hand too)')

#: The scene and the task, in the env's Description (str.format fields: `numbers`).
DESCRIPTION = """\
a 60 x 30 cm mat ({mat_mass:g} kg; its far half one rigid plate, its near half {n_strips}
strips of {strip_cm:g} cm hinged to each other) lies on the table; the gripper pinches the
middle of its near edge (which may turn between the pads up to {pinch_turn_deg:.0f} deg, the
demos' largest + 10), lifts it in an arc and lays it on the far edge: the mat folded in
half. The demos themselves drag the mat 8-14 cm and turn it 9-23 deg on the table while they
fold it (lifting the edge pulls the mat towards it).
"""

#: The success rules (str.format fields: `numbers`): the env's Rewards section and
#: tasks/README.md show them.
RULES = """\
judged relative to the mat itself (a mat lifted by one edge slides towards the hand: the
drag is no fault). The mat's edge was held until the gripper opened, at that moment within
{mat_place_radius_cm:.1f} cm of where demo j lets it go in the room; now the far half lies
flat on the table with at least {min_turned} of the {n_strips} strips of the near half
turned over onto it in one layer (folded in half); the far half was never dragged more than
{mat_drag_cm:.1f} cm (the demos drag it
{mat_demo_drag_min_cm:.1f}-{mat_demo_drag_max_cm:.1f} cm).
"""

#: The bodies of the observation's `objects` (str.format fields: `numbers`).
OBJECTS = '`mat0` (the far half), `mat_pinch` (the pinched edge)'

#: The task's quantities in `info`.
INFO = (
    '`release_offset`, `fold_end_y`, `turned_strips`, `mat_folded`, `mat_heading_deg`, '
    '`max_root_shift`')

#: What the motion-limit check of a task added after the calibration of `clfd_bench.sim.limits`
#: found (`clfd_bench.execution.limit_calibration.ADDED_AFTER_CALIBRATION`), or None: the task
#: is part of the calibration.
CALIBRATION: str | None = (
    '2026-12-04: 27 replays all successful; worst hand position error 2.5 mm (0.21 x '
    'TRACKING_POSITION; demo 3), rotation 0.0085 rad (0.17 x; demo 2 1.5x faster); no '
    'robot-scene contact; filtered rotation / joint peaks 0.31 x at 5 Hz / 0.36 x at 2.5 Hz '
    '(0.40 x / 0.37 x at 6 Hz / 3 Hz): every value under those of the measurement, so adding '
    'it would leave the constants as they are.')


def numbers(spec: dict[str, Any]) -> dict[str, Any]:
    """The numbers the texts quote, from the task spec (`specs.load_task_spec`)."""
    s, d = spec["success"], spec["derived"]
    return {"mat_mass": 1.0, "n_strips": 10, "strip_cm": 3,
            "pinch_turn_deg": float(np.degrees(spec["grasp"]["slip_joints"][0][2])),
            "mat_place_radius_cm": 100 * s["place_radius"], "min_turned": s["min_turned_strips"],
            "mat_drag_cm": 100 * s["max_drag"],
            "mat_demo_drag_min_cm": 100 * min(d["root_shift_max"]),
            "mat_demo_drag_max_cm": 100 * max(d["root_shift_max"])}
