"""MatFolding's own right and wrong trajectories, beyond the generic perturbation families
(`clfd_bench.execution.task_variants` runs them; `python eval/own_variants.py`), and the generic
families whose outcome can be a valid alternative here (`VALID_ALTERNATIVES`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from clfd_bench.envs.robotasks.matfolding.success import MAT_FOLD_CHECKS
from clfd_bench.envs.robotasks.variants import (
    Variant,
    bumped,
    shortened,
    stop_at,
)

#: (name, what an observer would say: "succeed", "fail" or "either", the variant).
VARIANTS: list[tuple[str, str, Variant]] = [
    ("the arc 2 cm higher", "succeed", bumped(0.02)),
    ("the arc 5 cm higher", "succeed", bumped(0.05)),
    ("laid down at 80 % of the way (short of the far edge)", "fail", shortened(0.8)),
    ("the arc 10 cm lower (the edge dragged over the mat)", "fail", bumped(-0.10)),
    ("stopped at 90 %", "either", stop_at(0.9)),
    ("stopped at 75 %", "either", stop_at(0.75)),
]


def _folded(info: Mapping[str, Any]) -> bool:
    """Whether every check of `MAT_FOLD_CHECKS` is in `info["checks"]` and passed."""
    passed = {c["name"]: bool(c["passed"]) for c in info.get("checks") or ()}
    return all(passed.get(n, False) for n in MAT_FOLD_CHECKS)


#: Generic perturbation families that are no wrong trajectory for this task when their outcome
#: holds (`clfd_bench.execution.replay.VALID_ALTERNATIVES`): family -> (outcome, reason).
VALID_ALTERNATIVES: dict[str, tuple[Callable[[Mapping[str, Any]], bool], str]] = {
    "shortcut": (
        _folded,
        "a straight pull from demo j's start to its end pose that folds the mat in half (the "
        "far half flat, the strips turned over onto it) is another way of folding it, as a "
        "mirrored Pouring is another way of pouring: a mat lifted by one edge slides towards "
        "the hand whatever the path, so the criterion judges the mat relative to itself, and "
        "a folded mat is the outcome an observer signs. A shortcut that does not fold it (the "
        "edge slips out of the fingers) is still counted, and fails."),
}
