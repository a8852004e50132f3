"""BottleShelving's success predicate (the rules: `doc.RULES`)."""

from __future__ import annotations

from typing import Any

from clfd_bench.envs.checks import Check
from clfd_bench.envs.robotasks.predicates import release_checks, rest_checks

__all__ = ["checks"]


def checks(release_reason: str | None, held: bool, release_height: float | None,
           release_offset: float | None, on_shelf: bool, tilt: float, height: float,
           cfg: dict[str, Any]) -> list[Check]:
    """Let go by the gripper, low and near demo j's release point; lying on the shelf.

    Args:
        release_reason, held, release_height, release_offset: as
            `predicates.release_checks`.
        on_shelf: the bottle's centre is over the shelf's top.
        tilt: the bottle's axis from horizontal (deg).
        height: the bottle's centre above the shelf's top (m).
        cfg: the spec's `[success]`.
    """
    return (release_checks(release_reason, held, release_height, release_offset, cfg)
            + rest_checks("shelf", on_shelf, tilt, "the bottle's axis from horizontal", height,
                          "the bottle's centre above the shelf's top", cfg))
