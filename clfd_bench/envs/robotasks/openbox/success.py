"""BoxOpening's success predicate (the rules: `doc.RULES`)."""

from __future__ import annotations

from typing import Any

from clfd_bench.envs.checks import Check

__all__ = ["checks"]


def checks(held_max_angle: float, need: float, release_reason: str | None, angle: float,
           cfg: dict[str, Any]) -> list[Check]:
    """The lid opened by the grasp, let go by the gripper, still open.

    Args:
        held_max_angle: the largest lid angle while the grasp held it (deg).
        need: the angle the grasp must reach (deg): demo j's row of `min_open_angle_deg`.
        release_reason: how the edge left the fingers: "opened", "slipped", None (never).
        angle: the lid's angle now (deg).
        cfg: the spec's `[success]`: `stay_open_tolerance_deg`.

    Returns:
        `lid_opened` (`held_max_angle` >= `need`), `let_go` (flag: the gripper opened),
        `lid_stays_open` (`angle` >= `need` - `stay_open_tolerance_deg`).
    """
    return [
        Check("lid_opened", held_max_angle, need, ">=", "deg",
              "largest lid angle while the grasp held it, vs demo j's end less 1.5 cm of arc"),
        Check.flag("let_go", release_reason == "opened",
                   "the gripper opened (the lid's edge did not slip out)"),
        Check("lid_stays_open", angle, need - float(cfg["stay_open_tolerance_deg"]), ">=",
              "deg", "lid angle at the end"),
    ]
