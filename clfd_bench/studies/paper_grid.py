"""The paper's full experiment grid as :class:`~clfd_bench.leaderboard.grid.RunSpec` s,
and what it costs.

The paper (Auddy et al., Sec. "Results" and appendix "Robustness to Task Order") trains

* LASA and HelloWorld: SG, FT, REP, SI, MAS, HN, CHN, each with NODE^T and NODE^I;
* RoboTasks: SG, FT, REP, HN, CHN ("We omit SI and MAS because of their poor performance")
  with NODE^T only ("We use only NODE^T for this experiment");

with 5 seeds for its CL tables (order 0) and task orders 0, 1, 2 for the task-order study.
Crossing all of them, as issue 6 asks, gives (7·2 + 7·2 + 5·1) · 5 seeds · 3 orders = 495 runs
(:data:`FULL_GRID_RUNS`). Every dimension can be narrowed; a name that is not part of the
paper's grid (or not registered at all) raises :class:`GridError` listing the valid ones.

:func:`grid_cost` counts the runs and their training iterations (from the profile's
configs), with two time references: the paper's own wall-clock tables (GPU machine, ``paper``
profile) and, when ``clfd-bench bench train`` speeds are given, this CPU.
"""

from __future__ import annotations

import json
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from clfd_bench.leaderboard.grid import DEFAULT_OPTIONS, GridOptions, RunSpec

__all__ = [
    "FULL_GRID_RUNS",
    "PAPER_GRID",
    "PAPER_ORDERS",
    "PAPER_PROFILE",
    "PAPER_SEEDS",
    "CostRow",
    "GridError",
    "grid_cost",
    "load_bench_rates",
    "paper_grid",
    "paper_methods",
]

ALL_METHODS: tuple[str, ...] = ("sg", "ft", "rep", "si", "mas", "hn", "chn")

PAPER_GRID: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "lasa": (ALL_METHODS, ("t", "i")),
    "helloworld": (ALL_METHODS, ("t", "i")),
    "robotasks": (("sg", "ft", "rep", "hn", "chn"), ("t",)),
}
"""dataset -> (methods, NODE variants) the paper ran."""

PAPER_SEEDS: tuple[int, ...] = (0, 1, 2, 3, 4)
PAPER_ORDERS: tuple[int, ...] = (0, 1, 2)
PAPER_PROFILE = "paper"

FULL_GRID_RUNS = (7 * 2 + 7 * 2 + 5 * 1) * len(PAPER_SEEDS) * len(PAPER_ORDERS)
"""495: every dataset × method × NODE variant of the paper, 5 seeds, 3 orders."""

TRAIN_TIME_TABLES: dict[str, dict[str, str]] = {
    "lasa": {"position": "lasa"},
    "helloworld": {"position": "helloworld"},
    "robotasks": {"position": "robotasks_position", "orientation": "robotasks_orientation"},
}
"""dataset -> part -> the paper's wall-clock table (:func:`paper_numbers.train_times`)."""


class GridError(ValueError):
    """A grid selection outside the paper's grid; the message lists the valid choices."""


def paper_methods(dataset: str) -> tuple[str, ...]:
    """The methods the paper ran on ``dataset`` (lower-case)."""
    if dataset not in PAPER_GRID:
        raise GridError(f"unknown dataset {dataset!r}; the paper's: {', '.join(PAPER_GRID)}")
    return PAPER_GRID[dataset][0]


def _check_subset(kind: str, given: Iterable, valid: Sequence) -> None:
    bad = [x for x in given if x not in valid]
    if bad:
        raise GridError(
            f"unknown {kind} {', '.join(map(str, bad))}; valid: {', '.join(map(str, valid))}"
        )


def paper_grid(
    datasets: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    nodes: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
    orders: Sequence[int] | None = None,
    profile: str = PAPER_PROFILE,
    options: GridOptions = DEFAULT_OPTIONS,
) -> list[RunSpec]:
    """The paper's grid, narrowed to the given values (None: the paper's full set), with the
    tasks and simulation of ``options`` (its NODE variants are ``nodes``, not
    ``options.node``).

    A method or NODE variant applies only to the datasets the paper ran it on (``--methods si``
    with ``--datasets lasa,robotasks`` gives LASA's SI runs only); one that applies to none of
    the selected datasets raises. Runs are ordered by dataset, NODE variant, method, order,
    seed.

    Raises:
        GridError: an unknown or inapplicable dataset, method, node, order, or an empty list.
    """
    from clfd_bench.data import DATASETS
    from clfd_bench.harness.run_config import PROFILES

    datasets = list(PAPER_GRID) if datasets is None else list(datasets)
    seeds = list(PAPER_SEEDS) if seeds is None else list(seeds)
    orders = list(PAPER_ORDERS) if orders is None else list(orders)
    for kind, values in (("datasets", datasets), ("seeds", seeds), ("orders", orders),
                         ("methods", methods), ("nodes", nodes)):  # fmt: skip
        if values is not None and len(values) == 0:
            raise GridError(f"--{kind} is empty; give at least one value or leave it out")
    _check_subset("dataset", datasets, list(PAPER_GRID))
    _check_subset("profile", [profile], PROFILES)
    if methods is not None:
        _check_subset("method", methods, ALL_METHODS)
        for m in methods:
            if not any(m in PAPER_GRID[d][0] for d in datasets):
                raise GridError(
                    f"the paper did not run {m.upper()} on {', '.join(datasets)}; "
                    "its methods there: "
                    + "; ".join(f"{d}: {','.join(PAPER_GRID[d][0])}" for d in datasets)
                )
    if nodes is not None:
        _check_subset("node", nodes, ("t", "i"))
        for n in nodes:
            if not any(n in PAPER_GRID[d][1] for d in datasets):
                raise GridError(
                    f"the paper did not use NODE^{n.upper()} on {', '.join(datasets)} "
                    "(RoboTasks: NODE^T only)"
                )
    if any(s < 0 for s in seeds):
        raise GridError(f"seeds must be >= 0, got {seeds}")
    tasks, sim = options.tasks, options.sim
    if tasks is not None and tasks < 1:
        raise GridError(f"--tasks must be >= 1, got {tasks}")
    for d in datasets:
        _check_subset(f"order for {d}", orders, list(range(len(DATASETS[d].task_names()))))
    specs = []
    for d in datasets:
        d_methods, d_nodes = PAPER_GRID[d]
        for node in d_nodes:
            if nodes is not None and node not in nodes:
                continue
            for m in d_methods:
                if methods is not None and m not in methods:
                    continue
                for o in orders:
                    specs += [RunSpec(d, m, profile, s, o, node, tasks, sim) for s in seeds]
    return specs


# ------------------------------------------------------------------------------------------
# Cost


@dataclass(frozen=True)
class CostRow:
    """The runs of one (dataset, method, NODE variant) and what they cost.

    Attributes:
        runs: number of runs. tasks: tasks per run.
        iterations: training iterations of one run (all tasks, all parts: RoboTasks trains a
            position and an orientation model).
        gpu_s: one run's time on the paper's GPU machine (its wall-clock tables, median
            over seeds; only for the ``paper`` profile) or None.
        cpu_s: one run's time on this CPU from ``bench train`` speeds, or None if not measured.
    """

    dataset: str
    method: str
    node: str
    runs: int
    tasks: int
    iterations: int
    gpu_s: float | None
    cpu_s: float | None

    @property
    def total_iterations(self) -> int:
        return self.runs * self.iterations


def load_bench_rates(paths: Iterable[Path]) -> dict[tuple[str, str, str], float]:
    """Training speeds from ``clfd-bench bench train --json`` files.

    Returns:
        ``{(method, dataset, part): it/s}``, the slowest of the timed tasks (task 1 has the
        regularisers of SI, MAS, HN, CHN active, task 0 not; later tasks are slower still
        for HN/CHN, whose ``paper`` regulariser loops over every earlier task, so times
        from these speeds are lower bounds for them).
    """
    rates: dict[tuple[str, str, str], list[float]] = {}
    for path in paths:
        try:
            rows = json.loads(Path(path).read_text())["rows"]
        except (OSError, ValueError, KeyError) as exc:
            raise GridError(
                f"{path}: not a `clfd-bench bench train --json` file ({exc}); create one with "
                "`clfd-bench bench train --json FILE`"
            ) from None
        for r in rows:
            if r.get("it_per_s"):
                rates.setdefault((r["method"], r["dataset"], r["part"]), []).append(r["it_per_s"])
    return {k: min(v) for k, v in rates.items()}


def _gpu_seconds(dataset: str, method: str, tasks: int) -> float | None:
    """The paper's time for one run: mean per-task time over its table's tasks × tasks."""
    from clfd_bench.metrics.paper_numbers import train_times

    total = 0.0
    for table in TRAIN_TIME_TABLES.get(dataset, {}).values():
        t = train_times(table)
        values = t.get(method.upper())
        if not values:
            return None
        listed = [v for k, v in zip(t["tasks"], values, strict=True) if k < tasks]
        listed = listed or values[:1]
        total += statistics.mean(listed) * tasks
    return total or None


def grid_cost(
    specs: Sequence[RunSpec],
    cpu_rates: Mapping[tuple[str, str, str], float] | None = None,
) -> list[CostRow]:
    """One :class:`CostRow` per (dataset, method, NODE variant) of ``specs``, in grid order.

    Iterations come from the resolved configs of each run's profile
    (:func:`~clfd_bench.harness.config.resolve_config`). ``cpu_rates`` as from
    :func:`load_bench_rates`; a run's CPU time is the sum over its parts of
    ``iterations / it_per_s`` (None when a part was not measured).

    Raises:
        ConfigError: a profile has no settings for a run (e.g. ``paper`` SI on RoboTasks).
    """
    from clfd_bench.harness.config import resolve_config

    groups: dict[tuple[str, str, str], list[RunSpec]] = {}
    for s in specs:
        groups.setdefault((s.dataset, s.method, s.node), []).append(s)
    rows = []
    for (dataset, method, node), group in groups.items():
        first = group[0]
        tasks = first.num_tasks()
        config = resolve_config(method, dataset, first.profile, node=node, tasks=first.tasks)
        iterations = sum(cfg.iterations for _, cfg in config.parts) * tasks
        cpu: float | None = 0.0
        for part, cfg in config.parts:
            rate = (cpu_rates or {}).get((method, dataset, part))
            cpu = None if (rate is None or cpu is None) else cpu + cfg.iterations * tasks / rate
        gpu = _gpu_seconds(dataset, method, tasks) if first.profile == PAPER_PROFILE else None
        rows.append(CostRow(dataset, method, node, len(group), tasks, iterations, gpu, cpu))
    return rows
