"""BoxOpening's own right and wrong trajectories, beyond the generic perturbation families
(`clfd_bench.execution.task_variants` runs them with the `NEARBY` edits every scene gets;
`python eval/own_variants.py`)."""

from __future__ import annotations

from clfd_bench.envs.robotasks.variants import (
    Variant,
    and_back,
    stop_at,
)

#: (name, what an observer would say: "succeed", "fail" or "either", the variant).
VARIANTS: list[tuple[str, str, Variant]] = [
    ("the lid opened, then pushed shut again along the same arc", "fail", and_back(0.3)),
    ("stopped at 80 % of the way (the lid part open)", "either", stop_at(0.8)),
]
