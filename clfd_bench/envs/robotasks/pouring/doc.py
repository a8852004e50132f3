"""Pouring's words: its paragraphs of `RoboTaskEnv`'s docstring and of tasks/README.md.
The success rules are written here once (`RULES`); the numbers they quote come from the task
spec (`numbers`), so they stay in step with it."""

from __future__ import annotations

from typing import Any

#: What the task is, in tasks/README.md's table.
WHAT = (
    'cup of beans (free spheres), container where simulated beans land')

#: The scene and the task, in the env's Description (str.format fields: `numbers`).
DESCRIPTION = """\
a cup of {n_beans} beans (free spheres of {bean_diameter_cm} cm, {bean_mass_g} g:
hazelnut-sized; real coffee beans would take hundreds of bodies) is tipped over a container
centred where the demos' beans land.
"""

#: The success rules (str.format fields: `numbers`): the env's Rewards section and
#: tasks/README.md show them.
RULES = """\
the cup never slipped; it was emptied where a demo empties it (the cup's mouth, on average
as the beans left it, within {pour_radius_cm:.1f} cm of where demo j's was: as far as two
demos' pour points lie apart); at least {min_fraction_pct:.0f} % of the beans are in the
container and at most {max_spill_pct:.0f} % ever landed outside it (on the table, the
container's rim, ...).
"""

#: The bodies of the observation's `objects` (str.format fields: `numbers`).
OBJECTS = '`cup`, `bean0..{last_bean}`'

#: The task's quantities in `info`.
INFO = (
    '`bean_fraction`, `spilled_fraction`, `pour_offset`')

#: What the motion-limit check of a task added after the calibration of `clfd_bench.sim.limits`
#: found (`clfd_bench.execution.limit_calibration.ADDED_AFTER_CALIBRATION`), or None: the task
#: is part of the calibration.
CALIBRATION: str | None = None


def numbers(spec: dict[str, Any]) -> dict[str, Any]:
    """The numbers the texts quote, from the task spec (`specs.load_task_spec`)."""
    s, sc = spec["success"], spec["scene"]
    return {"n_beans": int(sc["n_beans"]), "bean_diameter_cm": f"{200 * sc['bean_radius']:.1f}",
            "bean_mass_g": f"{1000 * sc['bean_mass']:.1f}", "last_bean": int(sc["n_beans"]) - 1,
            "pour_radius_cm": 100 * s.get("pour_radius", float("nan")),
            "min_fraction_pct": 100 * s["min_fraction"],
            "max_spill_pct": 100 * s["max_spilled_fraction"]}
