"""BottleShelving's own wrong trajectories, beyond the generic perturbation families (a placing
task's typical mistakes; `clfd_bench.execution.task_variants` runs them with the `NEARBY` edits
every scene gets; `python eval/own_variants.py`)."""

from __future__ import annotations

from clfd_bench.envs.robotasks.variants import Variant, placing_mistakes

#: (name, what an observer would say: "succeed", "fail" or "either", the variant).
VARIANTS: list[tuple[str, str, Variant]] = placing_mistakes("bottle", "shelf")
