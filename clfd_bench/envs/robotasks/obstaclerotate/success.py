"""ObstacleRotate's success predicate (the rules: `doc.RULES`)."""

from __future__ import annotations

from typing import Any

from clfd_bench.envs.checks import Check
from clfd_bench.envs.robotasks.predicates import release_checks, rest_checks

__all__ = ["checks"]


def checks(touched_by: str | None, max_turn: float, release_turn: float | None,
           release_reason: str | None, held: bool, release_height: float | None,
           release_offset: float | None, on_shelf: bool, tilt: float, height: float,
           cfg: dict[str, Any]) -> list[Check]:
    """The obstacle never touched; the box turned the demos' way beside it and back; let go by
    the gripper, low and near demo j's release point; lying on the shelf.

    Args:
        touched_by: the first body other than the table that touched the obstacle, or None.
        max_turn: the box's largest turn the demos' way while held beside the obstacle (deg).
        release_turn: the box's heading from its start heading when let go (deg, signed),
            None if never let go.
        release_reason, held, release_height, release_offset: as
            `predicates.release_checks`.
        on_shelf: the box's centre is over the shelf's top.
        tilt: the box's top face from level (deg).
        height: the box's lowest point above the shelf's top (m).
        cfg: the spec's `[success]`: `min_turn_deg`, `max_end_turn_deg` and those of the
            release and rest checks.
    """
    return [
        Check.flag("obstacle_untouched", touched_by is None,
                   "nothing but the table touched the obstacle" if touched_by is None
                   else f"touched by {touched_by}"),
        Check("turn", max_turn, float(cfg["min_turn_deg"]), ">=", "deg",
              "the box's largest turn the demos' way while held beside the obstacle"),
        Check("end_turn", None if release_turn is None else abs(float(release_turn)),
              float(cfg["max_end_turn_deg"]), "<=", "deg",
              "the box's heading from its start heading when let go"),
    ] + (release_checks(release_reason, held, release_height, release_offset, cfg)
         + rest_checks("shelf", on_shelf, tilt, "the box's top face from level", height,
                       "the box's lowest point above the shelf", cfg))
