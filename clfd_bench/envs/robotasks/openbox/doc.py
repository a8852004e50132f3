"""BoxOpening's words: its paragraphs of `RoboTaskEnv`'s docstring and of tasks/README.md.
The success rules are written here once (`RULES`); the numbers they quote come from the task
spec (`numbers`), so they stay in step with it."""

from __future__ import annotations

from typing import Any

import numpy as np

#: What the task is, in tasks/README.md's table.
WHAT = (
    'storage box on a table, lid on friction hinges fitted to the arcs the demos trace')

#: The scene and the task, in the env's Description (str.format fields: `numbers`).
DESCRIPTION = """\
the gripper pinches the front edge of a storage box's lid and swings it open. The hinge axis
is fitted to the arcs the nine demos' grasp points trace. The lid ({lid_mass} kg) turns on
friction hinges ({hinge_friction} Nm): it stays wherever it is left, it only opens as far as
the gripper takes it.
"""

#: The success rules (str.format fields: `numbers`): the env's Rewards section and
#: tasks/README.md show them.
RULES = """\
while holding the lid, the grasp opened it as far as another demo opens it (the least of the
demos' final angles, each less what 1.5 cm of arc turn it: {open_min:.1f} deg); then the
gripper opened (the lid never slipped out); the lid is still open (at most {stay_tol:g} deg
below that angle).
"""

#: The bodies of the observation's `objects` (str.format fields: `numbers`).
OBJECTS = '`lid`, `lid_handle` (the edge between the fingers)'

#: The task's quantities in `info`.
INFO = (
    '`lid_angle_deg`, `lid_max_held_angle_deg`, `lid_open_needed_deg`, `lid_opened_by_grasp`')

#: What the motion-limit check of a task added after the calibration of `clfd_bench.sim.limits`
#: found (`clfd_bench.execution.limit_calibration.ADDED_AFTER_CALIBRATION`), or None: the task
#: is part of the calibration.
CALIBRATION: str | None = None


def numbers(spec: dict[str, Any]) -> dict[str, Any]:
    """The numbers the texts quote, from the task spec (`specs.load_task_spec`)."""
    need = np.asarray(spec["success"]["min_open_angle_deg"], dtype=float)
    return {"lid_mass": 0.42, "hinge_friction": 0.8, "open_min": float(need.min()),
            "stay_tol": spec["success"]["stay_open_tolerance_deg"]}
