"""``run_leaderboard``: run the grid runs still missing, then aggregate, plot and tabulate."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from clfd_bench.leaderboard.aggregate import MethodRow, RunRecord, aggregate
from clfd_bench.leaderboard.executors import RunOutcome, execute_grid
from clfd_bench.leaderboard.grid import FAILED_FILE, RunSpec, make_grid, read_results, run_status
from clfd_bench.leaderboard.plots import plot_all
from clfd_bench.leaderboard.report import write_tables
from clfd_bench.progress import progress

__all__ = ["GridRun", "LeaderboardResult", "collect", "run_leaderboard", "run_specs"]


@dataclass
class LeaderboardResult:
    """What a leaderboard call did: runs trained now, skipped as done, failed; files written."""

    specs: list[RunSpec]
    trained: list[RunSpec]
    skipped: list[RunSpec]
    failed: list[RunOutcome]
    rows: list[MethodRow]
    files: list[Path]
    seconds: float


def collect(specs: list[RunSpec], out: Path) -> list[RunRecord]:
    """The current state of every run of the grid, read from disk."""
    import json

    records = []
    for spec in specs:
        status = run_status(spec, out)
        error = None
        if status == "failed":
            try:
                error = json.loads((spec.run_dir(out) / FAILED_FILE).read_text())["error"]
            except (OSError, ValueError, KeyError):
                error = "failed (no readable failed.json)"
        results = read_results(spec.run_dir(out)) if status == "done" else None
        records.append(RunRecord(spec, status, results, error))
    return records


@dataclass
class GridRun:
    """What :func:`run_specs` did: runs trained now, skipped as done, failed; final records."""

    specs: list[RunSpec]
    trained: list[RunSpec]
    skipped: list[RunSpec]
    failed: list[RunOutcome]
    records: list[RunRecord]


def run_specs(
    specs: list[RunSpec],
    out: Path,
    executor: str = "local",
    workers: int = 1,
    address: str | None = None,
    desc: str = "grid",
) -> GridRun:
    """Run (or resume) the specs that are not done yet, then read every run's state.

    The building block of the leaderboard and of the studies (:mod:`clfd_bench.studies`):
    finished runs are skipped, half-finished ones resume, a crash is recorded in the run's
    ``failed.json`` and the grid goes on. Runs go to ``out/runs/<spec.name>``.
    """
    out = Path(out)
    todo = [s for s in specs if run_status(s, out) != "done"]
    skipped = [s for s in specs if s not in todo]
    failed: list[RunOutcome] = []
    if todo:
        bar = progress(total=len(todo), desc=f"{desc} ({len(skipped)} done before)")

        def on_done(outcome: RunOutcome) -> None:
            bar.update(1)
            state = "ok" if outcome.ok else f"FAILED: {outcome.error}"
            bar.write(f"[grid] {outcome.spec.name}: {state} ({outcome.seconds:.0f} s)")
            if not outcome.ok:
                failed.append(outcome)

        try:
            execute_grid(todo, out, executor, workers, address, on_done)
        finally:
            bar.close()
    return GridRun(specs, todo, skipped, failed, collect(specs, out))


def run_leaderboard(
    dataset: str,
    methods: list[str],
    profile: str,
    seeds: list[int],
    orders: list[int],
    out: Path,
    node: str = "t",
    tasks: int | None = None,
    sim: bool = True,
    executor: str = "local",
    workers: int = 1,
    address: str | None = None,
) -> LeaderboardResult:
    """Run the grid's missing runs (finished ones are skipped), then write the leaderboard.

    Writes into ``out``: ``runs/...`` (one directory per run), ``leaderboard.md``, ``.csv``,
    ``.json`` and the figures (PNG).
    """
    from clfd_bench.methods import get_method_class

    for method in methods:
        get_method_class(method)  # an unknown name fails here, listing the valid ones
    start = time.perf_counter()
    out = Path(out)
    specs = make_grid(dataset, methods, profile, seeds, orders, node, tasks, sim)
    grid = run_specs(specs, out, executor, workers, address, desc=f"grid {dataset}")
    records = grid.records
    rows = aggregate(records, methods)
    title = f"{dataset} ({profile})"
    figures = plot_all(records, rows, methods, out, title)
    meta = {
        "dataset": dataset,
        "methods": methods,
        "profile": profile,
        "seeds": seeds,
        "orders": orders,
        "node": node,
        "tasks": tasks,
        "sim": sim,
        "executor": executor,
        "figures": [str(p) for p in figures],
        "runs": {s.name: r.status for s, r in zip(specs, records, strict=True)},
    }
    files = write_tables(rows, out, meta) + figures
    return LeaderboardResult(
        specs, grid.trained, grid.skipped, grid.failed, rows, files, time.perf_counter() - start
    )
