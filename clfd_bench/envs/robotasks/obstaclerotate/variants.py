"""ObstacleRotate's own right and wrong trajectories, beyond the generic perturbation families
(`clfd_bench.execution.task_variants` runs them; `python eval/own_variants.py`)."""

from __future__ import annotations

from clfd_bench.envs.robotasks.variants import (
    Variant,
    over_the_top,
    yaw_at_the_end,
    yaw_kept,
    yaw_mirrored,
)

#: (name, what an observer would say: "succeed", "fail" or "either", the variant).
VARIANTS: list[tuple[str, str, Variant]] = [
    ("the turn about the vertical mirrored", "fail", yaw_mirrored),
    ("turned as the demo, never back", "fail", yaw_kept),
    ("carried unturned, turned and back over the shelf", "fail", yaw_at_the_end),
    ("straight across, over the obstacle's top", "either", over_the_top(0.28)),
]
