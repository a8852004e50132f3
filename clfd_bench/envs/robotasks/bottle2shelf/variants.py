"""BottleShelving's own right and wrong trajectories, beyond the generic perturbation families
(`clfd_bench.execution.task_variants` runs them with the `NEARBY` edits every scene gets;
`python eval/own_variants.py`)."""

from __future__ import annotations

from clfd_bench.envs.robotasks.variants import (
    Variant,
    and_back,
    end_raised,
    turned_fraction,
)

#: (name, what an observer would say: "succeed", "fail" or "either", the variant).
VARIANTS: list[tuple[str, str, Variant]] = [
    ("carried to the shelf, then back to the start and let go there", "fail", and_back(0.3)),
    ("let go 10 cm higher than the demo (dropped)", "fail", end_raised(0.10)),
    ("turned only half way (the bottle let go at 45 deg)", "fail", turned_fraction(0.5)),
]
