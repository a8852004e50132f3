"""Scoop's success predicate (the rules: `doc.RULES`)."""

from __future__ import annotations

from typing import Any

from clfd_bench.envs.checks import Check

__all__ = ["checks"]


def checks(held: bool, bin_touched_by: str | None, bowl_above_rim: float, bowl_tilt_deg: float,
           beans_in_scoop: int, beans_spilled: int, cfg: dict[str, Any]) -> list[Check]:
    """Scoop's success checks, in the order they are judged (success: every one passes).

    Args:
        held: the scoop is still held (it never slipped out of the fingers).
        bin_touched_by: the first body other than a bean that touched the bin (the scoop, a
            part of the robot), or None.
        bowl_above_rim: the bowl's lowest point above the bin's rim (m), now.
        bowl_tilt_deg: the bowl's opening's angle from straight up (deg), now.
        beans_in_scoop: beans in the bowl now; beans_spilled: beans that ever landed outside
            the bin.
        cfg: the spec's `[success]`: `max_tilt_deg`, `min_beans`, `max_spilled`.

    Returns:
        `held` (flag), `bin_untouched` (flag), `bowl_above_rim` >= 0 (m), `bowl_tilt` <=
        `max_tilt_deg` (deg), `beans_in_scoop` >= `min_beans`, `beans_spilled` <=
        `max_spilled`.
    """
    return [
        Check.flag("held", held, "the scoop never slipped"),
        Check.flag("bin_untouched", bin_touched_by is None,
                   f"touched by {bin_touched_by}" if bin_touched_by else "the bin untouched"),
        Check("bowl_above_rim", float(bowl_above_rim), 0.0, ">=", "m",
              "the bowl's lowest point above the bin's rim"),
        Check("bowl_tilt", float(bowl_tilt_deg), float(cfg["max_tilt_deg"]), "<=", "deg",
              "the bowl's opening from straight up"),
        Check("beans_in_scoop", float(beans_in_scoop), float(cfg["min_beans"]), ">=", ""),
        Check("beans_spilled", float(beans_spilled), float(cfg["max_spilled"]), "<=", ""),
    ]
