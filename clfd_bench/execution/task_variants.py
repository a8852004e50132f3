"""Task-specific wrong and right trajectories for the RoboTasks and RoboTasks9 scenes, beyond
the generic families of `clfd_bench.execution.perturb` (which every env gets), and the
`NEARBY` edits (5 mm, 3 degrees, another clock) every scene must survive. Each task lists its own in
its folder (`clfd_bench/envs/robotasks/<task>/variants.py`, built from the trajectory edits of
`clfd_bench.envs.robotasks.variants`).

A success criterion is only as good as the wrong trajectories it rejects and the good ones it
keeps; the generic families cannot know a task's valid alternatives (a glass lifted first and
then carried straight) or its typical mistakes (a box carried unturned and turned at the end).
`VARIANTS` lists them per env with what an observer would say ("succeed", "fail", or "either":
an observer could accept it or not); `run_variants` executes each on every demo.
`python eval/own_variants.py` prints the table (docs/execution.md).
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym

from clfd_bench.envs.robotasks.variants import NEARBY, Variant
from clfd_bench.execution.rollout import rollout

__all__ = ["VARIANTS", "VariantRow", "run_variants"]


def _variants() -> dict[str, list[tuple[str, str, Variant]]]:
    from clfd_bench.envs.registration import env_id_for
    from clfd_bench.envs.robotasks.registry import TASKS, task_module

    out = {}
    for task in TASKS:
        own = task_module(task.name, "variants", optional=True)
        out[env_id_for(task.dataset, task.name)] = [
            *NEARBY, *([] if own is None else own.VARIANTS)]
    return out


#: env -> [(variant, expect, build)]; expect: "succeed", "fail", "either": the `NEARBY` edits
#: every scene must survive, then the task's own (its `variants.VARIANTS`,
#: `clfd_bench.envs.robotasks.registry`).
VARIANTS: dict[str, list[tuple[str, str, Variant]]] = _variants()


def _why(info: dict) -> str:
    """The kind of a failed rollout's failure."""
    reason = info.get("failure_reason")
    if reason:
        return str(reason).split(" with")[0].split(" at step")[0].split(":")[0]
    if info.get("release_reason") == "slipped":
        return "slipped"
    return "task"



@dataclasses.dataclass(frozen=True)
class VariantRow:
    """One variant on every demo of an env: how many succeeded and why the others failed
    ({reason: count}: "reflex", "collision", "tracking", ..., "slipped", "task")."""

    env_id: str
    name: str
    expect: str
    succeeded: int
    demos: int
    failures: dict[str, int]


def run_variants(env_id: str, names: list[str] | None = None,
                 demos: list[int] | None = None) -> list[VariantRow]:
    """Executes the variants of `env_id` (all, or those named) on its demos (all, or those
    given), with the env's motion-limit checks.

    Raises:
        KeyError: no variants for `env_id`, or an unknown variant name (lists the valid ones).
    """
    import clfd_bench.envs  # noqa: F401 - registers the ids

    if env_id not in VARIANTS:
        raise KeyError(f"no variants for {env_id!r}; valid: {list(VARIANTS)}")
    known = {name: (expect, build) for name, expect, build in VARIANTS[env_id]}
    for name in names or []:
        if name not in known:
            raise KeyError(f"{env_id} has no variant {name!r}; valid: {list(known)}")
    env = gym.make(env_id, disable_env_checker=True)
    rows = []
    try:
        base = env.unwrapped
        demo_ids = list(range(base.num_demos)) if demos is None else list(demos)
        for name in names or list(known):
            expect, build = known[name]
            ok, why = 0, {}
            for j in demo_ids:
                r = rollout(env, build(base.demo_trajectory(j)), demo=j)
                ok += bool(r.success)
                if not r.success:
                    key = _why(r.info)
                    why[key] = why.get(key, 0) + 1
            rows.append(VariantRow(env_id, name, expect, ok, len(demo_ids), why))
    finally:
        env.close()
    return rows
