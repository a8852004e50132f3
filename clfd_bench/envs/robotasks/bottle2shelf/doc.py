"""BottleShelving's words: its paragraphs of `RoboTaskEnv`'s docstring and of tasks/README.md.
The success rules are written here once (`RULES`); the numbers they quote come from the task
spec (`numbers`), so they stay in step with it."""

from __future__ import annotations

from typing import Any

#: What the task is, in tasks/README.md's table.
WHAT = (
    '250 ml bottle, shelf under where the demos end')

#: The scene and the task, in the env's Description (str.format fields: `numbers`).
DESCRIPTION = """\
a full 250 ml bottle ({bottle_mass} kg), held upright by its neck just above the table, is
laid on a shelf whose top is 1.5 cm under the lowest point the bottle reaches at the demos'
ends (and lower where a demo passes closer).
"""

#: The success rules (str.format fields: `numbers`): the env's Rewards section and
#: tasks/README.md show them.
RULES = """\
the bottle was held until the gripper opened; at that moment its lowest point was at most
{bottle_drop_cm:.1f} cm above the shelf (the demos let it go
{bottle_demo_drop_min:.1f}-{bottle_demo_drop_max:.1f} cm above it) and its centre within
{bottle_radius_cm:.1f} cm of where demo j lets it go; now it lies on the shelf (axis within
{bottle_tilt:g} deg of horizontal, at rest on the top).
"""

#: The bodies of the observation's `objects` (str.format fields: `numbers`).
OBJECTS = '`bottle`'

#: The task's quantities in `info`.
INFO = (
    '`release_height`, `release_offset`, `bottle_tilt_deg`, `bottle_height`, `on_shelf`')

#: What the motion-limit check of a task added after the calibration of `clfd_bench.sim.limits`
#: found (`clfd_bench.execution.limit_calibration.ADDED_AFTER_CALIBRATION`), or None: the task
#: is part of the calibration.
CALIBRATION: str | None = None


def numbers(spec: dict[str, Any]) -> dict[str, Any]:
    """The numbers the texts quote, from the task spec (`specs.load_task_spec`)."""
    s, d = spec["success"], spec["derived"]
    return {"bottle_mass": 0.26, "bottle_drop_cm": 100 * s["max_release_height"],
            "bottle_radius_cm": 100 * s["place_radius"],
            "bottle_demo_drop_min": 100 * min(d["release_height_demos"]),
            "bottle_demo_drop_max": 100 * max(d["release_height_demos"]),
            "bottle_tilt": s["max_tilt_deg"]}
