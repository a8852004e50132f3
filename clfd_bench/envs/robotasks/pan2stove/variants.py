"""PanToStove's own right and wrong trajectories, beyond the generic perturbation families
(`clfd_bench.execution.task_variants` runs them; `python eval/own_variants.py`)."""

from __future__ import annotations

import numpy as np

from clfd_bench.envs.robotasks.variants import (
    Variant,
    stop_at,
    turned_extra,
    turned_fraction,
    turned_the_long_way,
    waypoints,
)

#: (name, what an observer would say: "succeed", "fail" or "either", the variant).
VARIANTS: list[tuple[str, str, Variant]] = [
    ("pull back 12 cm, rise, carry above the stove, descend", "succeed", waypoints(
        lambda p0, p1: [p0 + [0.12, 0.0, 0.0], np.r_[p0[:2] + [0.12, 0.0], p1[2] + 0.1],
                        p1 + [0.0, 0.0, 0.1]])),
    ("pull back 12 cm, lift 6 cm, then a straight line down to the stove", "fail",
     waypoints(lambda p0, p1: [p0 + [0.12, 0.0, 0.06]])),
    ("turned the other way round", "fail", turned_the_long_way),
    ("turned 30 deg too far", "fail", turned_extra(30.0)),
    ("turned half as far", "fail", turned_fraction(0.5)),
    ("stopped at 90 %", "either", stop_at(0.9)),
    ("stopped at 75 %", "either", stop_at(0.75)),
]
