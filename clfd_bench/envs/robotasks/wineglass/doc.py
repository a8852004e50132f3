"""WineGlass's words: its paragraphs of `RoboTaskEnv`'s docstring and of tasks/README.md.
The success rules are written here once (`RULES`); the numbers they quote come from the task
spec (`numbers`), so they stay in step with it."""

from __future__ import annotations

from typing import Any

#: What the task is, in tasks/README.md's table.
WHAT = (
    '20 cm wine glass lying in a drying tray on a stand, shelf under where the demos end')

#: The scene and the task, in the env's Description (str.format fields: `numbers`).
DESCRIPTION = """\
a 20 cm wine glass ({glass_mass} kg) lying on its side in a drying tray is taken by the
stem, lifted out, turned upright and stood on its foot on a shelf. The tray's walls stand
1.5 cm clear of where the demos move the glass below the walls' top ({tray_wall_cm:.1f} cm):
the demos lift the glass out before they carry and turn it. What the task is was inferred
from the poses alone (the object's axis is horizontal at the start and vertical at the end);
see docs/design/robotasks9.
"""

#: The success rules (str.format fields: `numbers`): the env's Rewards section and
#: tasks/README.md show them.
RULES = """\
the drying tray was never moved more than {tray_shift_cm:g} cm or tilted more than
{tray_tilt:g} deg; the glass was held until the gripper opened, its lowest point at most
{glass_drop_cm:.1f} cm above the shelf and its foot within {glass_radius_cm:.1f} cm of where
demo j lets it go; now it stands upright on the shelf (axis within {glass_tilt:g} deg of
vertical, bowl up, its foot on the shelf's top).
"""

#: The bodies of the observation's `objects` (str.format fields: `numbers`).
OBJECTS = '`glass`, `tray`'

#: The task's quantities in `info`.
INFO = (
    '`glass_tilt_deg`, `glass_foot_height`, `on_shelf`, `max_tray_shift`, '
    '`max_tray_tilt_deg`, `tray_in_place`')

#: What the motion-limit check of a task added after the calibration of `clfd_bench.sim.limits`
#: found (`clfd_bench.execution.limit_calibration.ADDED_AFTER_CALIBRATION`), or None: the task
#: is part of the calibration.
CALIBRATION: str | None = (
    '2026-12-04: 27 replays (demo, slower, faster) all successful; worst hand position error '
    '9.8 mm = 0.81 x TRACKING_POSITION (demo 8 1.5x faster, joint 6 at its 12 Nm torque limit'
    ' while the glass is turned), rotation 0.30 x; no robot-scene contact; filtered rotation '
    "/ joint accelerations 0.58 x / 0.23 x at the filters' 8 Hz / 3 Hz (stricter ones are in "
    'use). With it in the measurement TRACKING_POSITION would be 19.5 mm for every env.')


def numbers(spec: dict[str, Any]) -> dict[str, Any]:
    """The numbers the texts quote, from the task spec (`specs.load_task_spec`)."""
    s = spec["success"]
    return {"glass_mass": 0.15, "tray_wall_cm": 100 * spec["scene"]["tray_wall_height"],
            "tray_shift_cm": 100 * s["max_tray_shift"], "tray_tilt": s["max_tray_tilt_deg"],
            "glass_drop_cm": 100 * s["max_release_height"],
            "glass_radius_cm": 100 * s["place_radius"], "glass_tilt": s["max_tilt_deg"]}
