"""Pouring's success predicate (the rules: `doc.RULES`)."""

from __future__ import annotations

import math
from typing import Any

from clfd_bench.envs.checks import Check

__all__ = ["checks"]


def checks(release_reason: str | None, pour_offset: float | None, has_pour_centre: bool,
           n_beans: int, bean_fraction: float, spilled_fraction: float,
           cfg: dict[str, Any]) -> list[Check]:
    """The cup never slipped; emptied near where demo j empties it; enough beans in the
    container, few ever landed outside it.

    Args:
        release_reason: "slipped" if the cup slipped out of the fingers.
        pour_offset: distance (m) between where the cup's mouth was, on average, as its beans
            left it and where demo j's was; None: no bean has left the cup.
        has_pour_centre: the scene has demo j's pour point (`[scene] pour_centre`; a
            provisional spec while deriving has none: then nothing is judged of where).
        n_beans: the beans in the cup at the start.
        bean_fraction: the fraction of them in the container now.
        spilled_fraction: the fraction that ever landed outside the container.
        cfg: the spec's `[success]`: `pour_radius` (without it, only that a bean left the
            cup), `min_fraction`, `max_spilled_fraction` (rounded to 10 digits in the spec:
            compared as bean counts, 1e-9 of slack).

    Returns:
        `cup_held` (flag), `pour_offset` <= `pour_radius` (or `poured`, a flag),
        `beans_in_container` >= ceil(n * `min_fraction`), `beans_spilled` <=
        floor(n * `max_spilled_fraction`).
    """
    n = n_beans
    eps = 1e-9  # the spec's fractions are rounded to 10 digits
    out = [Check.flag("cup_held", release_reason != "slipped",
                      "the cup never slipped out of the fingers")]
    if has_pour_centre and "pour_radius" in cfg:
        out.append(Check("pour_offset", pour_offset, float(cfg["pour_radius"]), "<=", "m",
                         "where the cup's mouth is, on average, as its beans leave it, "
                         "from where demo j's is"))
    elif has_pour_centre:
        out.append(Check.flag("poured", pour_offset is not None, "a bean left the cup"))
    out += [
        Check("beans_in_container", round(bean_fraction * n),
              math.ceil(n * (float(cfg["min_fraction"]) - eps)), ">=", "",
              f"beans (of {n}) in the container at the end"),
        Check("beans_spilled", round(spilled_fraction * n),
              math.floor(n * (float(cfg["max_spilled_fraction"]) + eps)), "<=", "",
              f"beans (of {n}) that ever landed outside the container"),
    ]
    return out
