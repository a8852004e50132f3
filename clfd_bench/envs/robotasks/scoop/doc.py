"""Scoop's words: its paragraphs of `RoboTaskEnv`'s docstring and of tasks/README.md.
The success rules are written here once (`RULES`); the numbers they quote come from the task
spec (`numbers`), so they stay in step with it."""

from __future__ import annotations

from typing import Any

#: What the task is, in tasks/README.md's table.
WHAT = (
    'a scoop (an 8 × 7 × 4 cm bowl 25 cm out along its handle, held across the pads, never '
    'let go) and a 17 × 62 cm bin of beans on a stand, its walls and floor 1.5 cm clear of '
    "every demo's scoop and arm, the beans' level 3.5 cm over the highest of the demos' "
    "lowest lip points. The bin's contents are grain sites 1 cm apart that become beans (a "
    'pool of 6 frictionless 2.4 cm spheres) when the bowl takes them in over its lip')

#: The scene and the task, in the env's Description (str.format fields: `numbers`).
DESCRIPTION = """\
a scoop ({scoop_mass_g:.0f} g; an 8 x 7 x 4 cm bowl 25 cm out along its handle, held across
the pads) is drawn through a bin of beans on a stand and lifted out nearly level, holding a
scoopful. The beans' level is {scoop_dip_cm:.1f} cm over the highest of the demos' lowest
lip points; the bin's walls and floor stand 1.5 cm clear of every demo's scoop and arm. The
bin's contents are not simulated body by body: they are grain sites {grain_mm:.0f} mm apart,
and a grain becomes a bean (one of a pool of {scoop_beans} frictionless spheres of
{scoop_bean_cm:.1f} cm, {scoop_bean_g:g} g) when it passes into the bowl over its lip; from
then on it is physical (it rides in the bowl, rolls out of it when it tips, falls); one that
falls back into the bin rejoins its contents
(`clfd_bench.envs.robotasks.scoop.scene.ScoopScene`).
"""

#: The success rules (str.format fields: `numbers`): the env's Rewards section and
#: tasks/README.md show them.
RULES = """\
the scoop never slipped and neither it nor the robot ever touched the bin; at the end (1 s
after the trajectory, held still) the bowl is out of the bin, its opening within
{scoop_tilt:.0f} deg of facing up, at least {scoop_min_beans} beans in it; at most
{scoop_max_spilled} ever landed outside the bin. Where the scoop ends is not judged (nothing
in the scene marks demo j's end).
"""

#: The bodies of the observation's `objects` (str.format fields: `numbers`).
OBJECTS = (
    "`scoop`, `bean0..{scoop_last_bean}` (a bean still in the bin waits 10 m under the room's"
    ' floor)')

#: The task's quantities in `info`.
INFO = (
    '`beans_in_scoop`, `beans_spilled`, `beans_scooped`, `grip_point`, `bowl_centre`, '
    '`bowl_tilt_deg`, `bowl_out_of_bin`, `bin_touched_by`')

#: What the motion-limit check of a task added after the calibration of `clfd_bench.sim.limits`
#: found (`clfd_bench.execution.limit_calibration.ADDED_AFTER_CALIBRATION`), or None: the task
#: is part of the calibration.
CALIBRATION: str | None = (
    '2026-12-04: 27 replays all successful; worst hand position error 0.6 mm (0.05 x '
    'TRACKING_POSITION; demo 0 1.5x faster), rotation 0.0090 rad (0.18 x; demo 2 1.5x '
    'faster); no robot-scene contact; filtered rotation / joint peaks 0.48 x at 8 Hz / 0.31 x'
    ' at 3 Hz: every value under those of the measurement, so adding it would leave the '
    'constants as they are.')


def numbers(spec: dict[str, Any]) -> dict[str, Any]:
    """The numbers the texts quote, from the task spec (`specs.load_task_spec`)."""
    s, sc = spec["success"], spec["scene"]
    return {"scoop_mass_g": 55, "scoop_dip_cm": 100 * (sc["surface_z"]
                                                   - max(spec["derived"]["lip_lowest_z"])),
            "grain_mm": 1000 * sc["grain_spacing"], "scoop_beans": sc["n_beans"],
            "scoop_last_bean": sc["n_beans"] - 1, "scoop_bean_cm": 200 * sc["bean_radius"],
            "scoop_bean_g": 1000 * sc["bean_mass"], "scoop_min_beans": s["min_beans"],
            "scoop_max_spilled": s["max_spilled"], "scoop_tilt": s["max_tilt_deg"]}
