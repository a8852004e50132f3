"""MatFolding's success predicate (the rules: `doc.RULES`)."""

from __future__ import annotations

from typing import Any

from clfd_bench.envs.checks import Check

__all__ = ["MAT_FOLD_CHECKS", "checks"]


#: The checks that say the mat is folded in half (`checks`); a path that passes them folds
#: the mat, whatever else it does (`variants.VALID_ALTERNATIVES`).
MAT_FOLD_CHECKS = ("far_half_height", "turned_strips")


def checks(release_reason: str | None, release_offset: float | None, far_half_height: float,
           turned_strips: int, drag: float, cfg: dict[str, Any]) -> list[Check]:
    """MatFolding's success checks, in the order they are judged (success: every one passes).

    Args:
        release_reason: how the edge left the fingers: "opened" (the gripper let it go),
            "slipped", or None (still held).
        release_offset: distance (m) from the near edge's middle, when the gripper opened, to
            where demo j lets it go in the room; None when it was never let go.
        far_half_height: the far half's middle plane above the table top (m), now.
        turned_strips: strips of the near half lying turned over on the far half, now.
        drag: the far half's largest horizontal shift from where it lay at the start (m).
        cfg: the spec's `[success]`: `place_radius`, `max_layer_height`, `min_turned_strips`,
            `max_drag`.

    Returns:
        `held_until_opened` (flag), `release_offset` <= `place_radius` (m), `far_half_height`
        <= `max_layer_height` (m), `turned_strips` >= `min_turned_strips`, `drag` <=
        `max_drag` (m).
    """
    return [
        Check.flag("held_until_opened", release_reason == "opened",
                   f"released: {release_reason}"),
        Check("release_offset", release_offset, float(cfg["place_radius"]), "<=", "m",
              "the edge let go from where demo j lets it go, in the room"),
        Check("far_half_height", float(far_half_height), float(cfg["max_layer_height"]), "<=",
              "m", "the far half flat on the table"),
        Check("turned_strips", float(turned_strips), float(cfg["min_turned_strips"]), ">=", "",
              "strips turned over onto the far half"),
        Check("drag", float(drag), float(cfg["max_drag"]), "<=", "m",
              "the far half's largest shift on the table"),
    ]
