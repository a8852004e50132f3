"""Scoop's own right and wrong trajectories, beyond the generic perturbation families
(`clfd_bench.execution.task_variants` runs them; `python eval/own_variants.py`), and the generic
families whose outcome can be a valid alternative here (`VALID_ALTERNATIVES`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from clfd_bench.envs.robotasks.variants import (
    Variant,
    bumped,
    rolled_at_the_end,
    stop_at,
    tilt_kept_from_lowest,
    up_then_across,
)

#: (name, what an observer would say: "succeed", "fail" or "either", the variant).
VARIANTS: list[tuple[str, str, Variant]] = [
    ("from the lowest point straight up 8 cm, then across to the end", "succeed",
     up_then_across(0.08)),
    ("carried 12 cm over the beans", "fail", bumped(0.12)),
    ("the dip's tilt kept to the end (never levelled)", "fail", tilt_kept_from_lowest),
    ("the bowl turned over at the end (hand rolled 120 deg)", "fail",
     rolled_at_the_end(120.0)),
    ("stopped at 90 %", "either", stop_at(0.9)),
    ("stopped at 75 %", "either", stop_at(0.75)),
]


#: Generic perturbation families that are no wrong trajectory for this task when their outcome
#: holds (`clfd_bench.execution.replay.VALID_ALTERNATIVES`): family -> (outcome, reason).
VALID_ALTERNATIVES: dict[str, tuple[Callable[[Mapping[str, Any]], bool], str]] = {
    "drift": (
        lambda info: True,
        "nothing in the scene marks where demo j ends (no container: a scoopful held level out "
        "of the bin is the task done wherever the hand holds it), so no check judges the end "
        "point; a path offset by up to 5 cm that still dips into the bin and lifts a level "
        "scoopful out is the task done, and one that touches the bin or loses its beans fails "
        "those checks, not for the offset. The family tests nothing this task asks."),
}
