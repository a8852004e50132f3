"""ObstacleRotate's words: its paragraphs of `RoboTaskEnv`'s docstring and of tasks/README.md.
The success rules are written here once (`RULES`); the numbers they quote come from the task
spec (`numbers`), so they stay in step with it."""

from __future__ import annotations

from typing import Any

#: What the task is, in tasks/README.md's table.
WHAT = (
    "20 cm box carried low from the table around an obstacle (a block where every demo's path"
    " bends, shrunk until the demos' box and arm clear it by 1.5 cm), shelf where the demos "
    'end')

#: The scene and the task, in the env's Description (str.format fields: `numbers`).
DESCRIPTION = """\
a 20 cm box ({box_mass} kg) is carried low from the table at the robot's right around an
obstacle (a block standing where every demo's path bends, {obstacle_cm} cm tall, shrunk
until every demo's box and arm keep 1.5 cm clear of it), turned {min_turn:.0f}+ deg about
the vertical on the way and back, and put down on a shelf at the robot's left. Nothing in
the scene forces the turn (no gate that only a turned box passes was found in the data): the
criterion asks for it, as the task's name does.
"""

#: The success rules (str.format fields: `numbers`): the env's Rewards section and
#: tasks/README.md show them.
RULES = """\
the obstacle was never touched (by the box or the robot, at any step); while held, the box
turned at least {min_turn:.1f} deg about the vertical in the demos' direction and, when let
go, was back within {end_turn:.1f} deg of its start heading; it was let go at most
{box_drop_cm:.1f} cm above the shelf and within {box_radius_cm:.1f} cm of where demo j lets
it go; now it lies on the shelf.
"""

#: The bodies of the observation's `objects` (str.format fields: `numbers`).
OBJECTS = '`object`'

#: The task's quantities in `info`.
INFO = (
    '`object_tilt_deg`, `object_height`, `on_shelf`, `obstacle_touched_by`, '
    '`object_max_turn_deg`, `object_release_turn_deg`')

#: What the motion-limit check of a task added after the calibration of `clfd_bench.sim.limits`
#: found (`clfd_bench.execution.limit_calibration.ADDED_AFTER_CALIBRATION`), or None: the task
#: is part of the calibration.
CALIBRATION: str | None = (
    '2026-12-04: 27 replays all successful; worst hand position error 7.4 mm = 0.61 x '
    'TRACKING_POSITION (demo 7 1.5x faster), rotation 0.0238 rad (0.47 x); no robot-scene '
    'contact; filtered rotation / joint accelerations 0.64 x at 6 Hz / 0.37 x at 3 Hz. With '
    'it in the measurement TRACKING_POSITION would be 14.7 mm.')


def numbers(spec: dict[str, Any]) -> dict[str, Any]:
    """The numbers the texts quote, from the task spec (`specs.load_task_spec`)."""
    s, sc = spec["success"], spec["scene"]
    return {"box_mass": 0.3, "obstacle_cm": f"{100 * (sc['obstacle_top'] - sc['table_z']):.0f}",
            "min_turn": s["min_turn_deg"], "end_turn": s["max_end_turn_deg"],
            "box_drop_cm": 100 * s["max_release_height"],
            "box_radius_cm": 100 * s["place_radius"]}
