"""Pouring's own right and wrong trajectories, beyond the generic perturbation families
(`clfd_bench.execution.task_variants` runs them with the `NEARBY` edits every scene gets;
`python eval/own_variants.py`)."""

from __future__ import annotations

from clfd_bench.envs.robotasks.variants import (
    Variant,
    shifted,
    turned_extra,
    turned_fraction,
)

#: (name, what an observer would say: "succeed", "fail" or "either", the variant).
VARIANTS: list[tuple[str, str, Variant]] = [
    ("tilted only half as far (the beans stay in the cup)", "fail", turned_fraction(0.5)),
    ("tilted 20 deg further", "either", turned_extra(20.0)),
    ("poured from 5 cm higher (every bean still lands in the container)", "succeed",
     shifted((0.0, 0.0, 0.05))),
]
