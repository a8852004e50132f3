"""WineGlass's success predicate (the rules: `doc.RULES`)."""

from __future__ import annotations

from typing import Any

from clfd_bench.envs.checks import Check
from clfd_bench.envs.robotasks.predicates import knock_checks, release_checks, rest_checks

__all__ = ["checks"]


def checks(release_reason: str | None, held: bool, release_height: float | None,
           release_offset: float | None, tray_shift: float, tray_tilt: float, on_shelf: bool,
           tilt: float, height: float, cfg: dict[str, Any]) -> list[Check]:
    """The drying tray never knocked; the glass let go by the gripper, low and near demo j's
    release point; standing upright on the shelf.

    Args:
        release_reason, held, release_height, release_offset: as
            `predicates.release_checks`.
        tray_shift, tray_tilt: the tray's largest shift (m) and tilt (deg) at any step.
        on_shelf: the foot's bottom is over the shelf's top.
        tilt: the glass's axis from upright (deg; 180: upside down).
        height: the foot's bottom above the shelf's top (m).
        cfg: the spec's `[success]`.
    """
    return (knock_checks("tray", tray_shift, tray_tilt, cfg)
            + release_checks(release_reason, held, release_height, release_offset, cfg)
            + rest_checks("shelf", on_shelf, tilt,
                          "the glass's axis from upright (180: upside down)", height,
                          "the foot's bottom above the shelf's top", cfg))
