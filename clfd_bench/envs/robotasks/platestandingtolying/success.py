"""PlateStacking's success predicate (the rules: `doc.RULES`)."""

from __future__ import annotations

from typing import Any

from clfd_bench.envs.checks import Check
from clfd_bench.envs.robotasks.predicates import knock_checks, release_checks, rest_checks

__all__ = ["checks"]


def checks(rack_shift: float, rack_tilt: float, release_reason: str | None, held: bool,
           release_height: float | None, release_offset: float | None, on_platform: bool,
           tilt: float, height: float, cfg: dict[str, Any]) -> list[Check]:
    """The rack never knocked; the plate let go by the gripper, low and near demo j's release
    point; lying on the platform.

    Args:
        rack_shift, rack_tilt: the dish rack's largest shift (m) and tilt (deg) at any step.
        release_reason, held, release_height, release_offset: as
            `predicates.release_checks`.
        on_platform: the plate's centre is over the platform's top.
        tilt: the plate's face from horizontal (deg).
        height: the plate's centre above the platform's top (m).
        cfg: the spec's `[success]`.
    """
    return (knock_checks("rack", rack_shift, rack_tilt, cfg)
            + release_checks(release_reason, held, release_height, release_offset, cfg)
            + rest_checks("platform", on_platform, tilt, "the plate's face from horizontal",
                          height, "the plate's centre above the platform's top", cfg))
