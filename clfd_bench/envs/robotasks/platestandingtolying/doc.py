"""PlateStacking's words: its paragraphs of `RoboTaskEnv`'s docstring and of tasks/README.md.
The success rules are written here once (`RULES`); the numbers they quote come from the task
spec (`numbers`), so they stay in step with it."""

from __future__ import annotations

from typing import Any

#: What the task is, in tasks/README.md's table.
WHAT = (
    '14 cm plate standing in a dish rack, platform where the demos end')

#: The scene and the task, in the env's Description (str.format fields: `numbers`).
DESCRIPTION = """\
a 14 cm plate ({plate_mass} kg) standing in a dish rack (a base and four pegs, 1.5 cm clear
of where the demos move the plate's rim) is lifted out and laid on a platform 1.5 cm under
the plate's lowest point near the demos' ends.
"""

#: The success rules (str.format fields: `numbers`): the env's Rewards section and
#: tasks/README.md show them.
RULES = """\
the dish rack was never moved more than {block_shift_cm:g} cm or tilted more than
{block_tilt:g} deg (at any step of the episode); the plate was held until the gripper
opened, at most {plate_drop_cm:.1f} cm above the platform and within {plate_radius_cm:.1f}
cm of where demo j lets it go; now it lies on the platform (normal within {plate_tilt:g} deg
of vertical).
"""

#: The bodies of the observation's `objects` (str.format fields: `numbers`).
OBJECTS = '`plate`, `rack`'

#: The task's quantities in `info`.
INFO = (
    '`plate_tilt_deg`, `plate_height`, `on_platform`, `max_rack_shift`, `max_rack_tilt_deg`, '
    '`rack_in_place`')

#: What the motion-limit check of a task added after the calibration of `clfd_bench.sim.limits`
#: found (`clfd_bench.execution.limit_calibration.ADDED_AFTER_CALIBRATION`), or None: the task
#: is part of the calibration.
CALIBRATION: str | None = None


def numbers(spec: dict[str, Any]) -> dict[str, Any]:
    """The numbers the texts quote, from the task spec (`specs.load_task_spec`)."""
    s = spec["success"]
    return {"plate_mass": 0.2, "block_shift_cm": 100 * s["max_rack_shift"],
            "block_tilt": s["max_rack_tilt_deg"], "plate_drop_cm": 100 * s["max_release_height"],
            "plate_radius_cm": 100 * s["place_radius"], "plate_tilt": s["max_tilt_deg"]}
