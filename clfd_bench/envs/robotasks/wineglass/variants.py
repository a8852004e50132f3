"""WineGlass's own right and wrong trajectories, beyond the generic perturbation families
(`clfd_bench.execution.task_variants` runs them; `python eval/own_variants.py`)."""

from __future__ import annotations

from clfd_bench.envs.robotasks.variants import (
    Variant,
    lift_then_line,
    stop_at,
    turned_extra,
    turned_the_long_way,
)

#: (name, what an observer would say: "succeed", "fail" or "either", the variant).
VARIANTS: list[tuple[str, str, Variant]] = [
    ("lift 8 cm, then a straight line, turning on it", "succeed", lift_then_line(0.08)),
    ("turned the other way round (bowl down on the way)", "fail", turned_the_long_way),
    ("turned 30 deg too far", "fail", turned_extra(30.0)),
    ("stopped at 90 % (upright, over the shelf)", "either", stop_at(0.9)),
    ("stopped at 75 %", "either", stop_at(0.75)),
]
