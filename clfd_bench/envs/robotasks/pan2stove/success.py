"""PanToStove's success predicate (the rules: `doc.RULES`)."""

from __future__ import annotations

from typing import Any

from clfd_bench.envs.checks import Check
from clfd_bench.envs.robotasks.predicates import knock_checks, release_checks, rest_checks

__all__ = ["checks"]


def checks(release_reason: str | None, held: bool, release_height: float | None,
           release_offset: float | None, rack_shift: float, rack_tilt: float, on_stove: bool,
           tilt: float, height: float, cfg: dict[str, Any]) -> list[Check]:
    """The pan rack never knocked; the pan let go by the gripper, low and near demo j's release
    point; lying flat on the stove, bottom down.

    Args:
        release_reason, held, release_height, release_offset: as
            `predicates.release_checks`.
        rack_shift, rack_tilt: the rack's largest shift (m) and tilt (deg) at any step.
        on_stove: the bottom's outer centre is over the stove's top.
        tilt: the pan's bottom from facing down (deg; 180: upside down).
        height: the bottom's outer centre above the stove's top (m).
        cfg: the spec's `[success]`.
    """
    return (knock_checks("rack", rack_shift, rack_tilt, cfg)
            + release_checks(release_reason, held, release_height, release_offset, cfg)
            + rest_checks("stove", on_stove, tilt,
                          "the pan's bottom from facing down (180: upside down)", height,
                          "the bottom's outer centre above the stove's top", cfg))
