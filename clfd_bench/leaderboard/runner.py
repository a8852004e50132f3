"""``run_leaderboard``: run the grid runs still missing, then aggregate, plot and tabulate."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from clfd_bench.leaderboard.aggregate import MethodRow, RunRecord, aggregate
from clfd_bench.leaderboard.executors import RunOutcome, execute_grid
from clfd_bench.leaderboard.grid import (
    DEFAULT_OPTIONS,
    GridOptions,
    RunSpec,
    make_grid,
    reread_simulator,
    run_state,
)
from clfd_bench.leaderboard.plots import plot_all
from clfd_bench.leaderboard.report import write_tables
from clfd_bench.progress import progress
from clfd_bench.runs import RunDir, RunFileError, exclusive

__all__ = [
    "GRID_ARG_NAMES",
    "GridRun",
    "check_methods",
    "LeaderboardResult",
    "collect",
    "included_records",
    "run_leaderboard",
    "run_specs",
    "validate_plan",
]

GRID_ARG_NAMES = {"seed": "--seeds", "order": "--orders"}
"""The grid options run-level values come from, named in plan errors."""


def check_methods(methods: list[str]) -> None:
    """Every name of ``--methods`` is a method, a plugin or a named entry
    (:data:`~clfd_bench.leaderboard.entries.ENTRIES`).

    Raises:
        UnknownMethodError: the first unknown name, with the valid methods and entries.
        MethodClassError: a plugin class that is not a method.
    """
    from clfd_bench.harness.run_config import suggest
    from clfd_bench.leaderboard.entries import ENTRIES, entry_help
    from clfd_bench.methods import UnknownMethodError, get_method_class, list_methods

    for name in methods:
        try:
            get_method_class(ENTRIES[name].method if name in ENTRIES else name)
        except UnknownMethodError as exc:
            hint = suggest(name, [*list_methods(), *ENTRIES])
            raise UnknownMethodError(f"{exc}; or {entry_help()}{hint}") from None


def validate_plan(specs: list[RunSpec], out: Path) -> None:
    """Check a whole grid before anything is launched or any folder created: ``out`` is
    usable, every run's names are registry names (so its directory stays below ``out``),
    every run's configuration resolves and passes every range check, and every dataset (in
    every order) loads with good files.

    Raises:
        ConfigError, UnknownMethodError, InputError, DatasetError: one line naming the bad
            value and where it came from (``clfd-bench`` prints it and exits with code 2).
    """
    from clfd_bench.harness.config import ConfigError
    from clfd_bench.harness.validate import check_dataset, check_out_dir, check_thread_invariance

    out = Path(out)
    check_out_dir(out)
    check_thread_invariance()
    runs_root = (out / "runs").resolve()
    for spec in specs:
        spec.config(GRID_ARG_NAMES)
        if not spec.run_dir(out).resolve().is_relative_to(runs_root):  # pragma: no cover
            raise ConfigError(f"run {spec.name!r} would be written outside {out}/runs")
    for dataset, order in sorted({(s.dataset, s.order) for s in specs}):
        check_dataset(dataset, order)


class RunCounts:
    """`counts` for a result that has ``specs``, ``trained``, ``executed_again``, ``skipped``
    and ``failed`` (`GridRun`, `LeaderboardResult`)."""

    specs: list[RunSpec]
    trained: list[RunSpec]
    skipped: list[RunSpec]
    failed: list[RunOutcome]
    executed_again: list[RunSpec]

    def counts(self) -> str:
        """What the grid did, in words: "7 runs: 2 trained now, 5 executed again (trained
        before), 0 already done, 0 failed"."""
        run_now, again = len(self.trained), len(self.executed_again)
        said = f", {again} executed again (trained before)" if again else ""
        plural = "" if len(self.specs) == 1 else "s"
        return (f"{len(self.specs)} run{plural}: {run_now - again} trained now{said}, "
                f"{len(self.skipped)} already done, {len(self.failed)} failed")


@dataclass
class LeaderboardResult(RunCounts):
    """What a leaderboard call did: runs trained now, skipped as done, failed; files written."""

    specs: list[RunSpec]
    trained: list[RunSpec]
    skipped: list[RunSpec]
    failed: list[RunOutcome]
    rows: list[MethodRow]
    files: list[Path]
    seconds: float
    executed_again: list[RunSpec] = field(default_factory=list)


def collect(specs: list[RunSpec], out: Path) -> list[RunRecord]:
    """The current state of every run of the grid, read from disk (the simulator's files
    included: executions by a simulator edited since do not count)."""
    reread_simulator()
    records = []
    for spec in specs:
        run = RunDir(spec.run_dir(out))
        state = run_state(spec, out)
        status, error = state.state, state.reason or None
        if status == "failed":
            error = str((run.failure() or {}).get("error", "failed (no readable failed.json)"))
        results = None
        if status == "done":
            try:
                results = run.read_results()
            except RunFileError as exc:  # changed on disk since the status was read
                status, error = "failed", str(exc)
        records.append(RunRecord(spec, status, results, error))
    return records


def included_records(paths: list[Path], specs: list[RunSpec],
                     methods: list[str]) -> list[RunRecord]:
    """Finished run directories from elsewhere (``--include``): a run scored from external
    predictions (``clfd-bench score``) or any finished run, as records of the leaderboard,
    under their run's method label.

    Each must be finished, on the grid's dataset, with as many tasks as the grid's runs, and
    its label must not be one of the grid's ``methods`` (scored predictions are labelled with
    ``--method-name``); two included runs with one label are one row (e.g. its seeds).

    Raises:
        InputError: one line naming the directory and what is wrong.
    """
    from clfd_bench.harness.validate import InputError

    records = []
    wanted = {s.dataset for s in specs}, {s.num_tasks() for s in specs}
    for path in paths:
        run = RunDir(path)
        try:
            results = run.load_results()
        except (FileNotFoundError, RunFileError) as exc:
            raise InputError(f"--include {path}: {exc}") from None
        config = results.get("config") or {}
        label = str(config.get("method") or "")
        dataset, done = config.get("dataset"), int(results.get("tasks_done") or 0)
        state = run.status(done, sim=False)
        if state.state != "done" or done == 0:
            raise InputError(f"--include {path}: the run is not finished ({state.reason}); "
                             "finish it first")
        if dataset not in wanted[0]:
            raise InputError(f"--include {path}: a run on {dataset}, not on this leaderboard's "
                             f"{', '.join(sorted(wanted[0]))}")
        if done not in wanted[1]:
            raise InputError(f"--include {path}: it learned {done} tasks, this leaderboard's "
                             f"runs {', '.join(map(str, sorted(wanted[1])))}; score or train it "
                             "with as many (--tasks)")
        if not label or label in methods:
            raise InputError(f"--include {path}: its method {label!r} is also in --methods; "
                             "leave it out of --methods, or score the predictions again with "
                             "another --method-name")
        spec = RunSpec(str(dataset), label, str(config.get("profile") or "external"),
                       int(config.get("seed") or 0), int(config.get("order") or 0),
                       str(config.get("node") or "t"), done, bool(results.get("success")))
        records.append(RunRecord(spec, "done", results))
    return records


@dataclass
class GridRun(RunCounts):
    """What :func:`run_specs` did: runs run now (``trained``: trained, resumed or executed
    again), skipped as done, failed; final records. ``executed_again``: those of ``trained``
    whose training was finished before, which only executed their predictions again (e.g.
    under a changed simulator)."""

    specs: list[RunSpec]
    trained: list[RunSpec]
    skipped: list[RunSpec]
    failed: list[RunOutcome]
    records: list[RunRecord]
    executed_again: list[RunSpec] = field(default_factory=list)


def run_specs(
    specs: list[RunSpec],
    out: Path,
    options: GridOptions = DEFAULT_OPTIONS,
    desc: str = "grid",
) -> GridRun:
    """Run (or resume) the specs that are not done yet, then read every run's state.

    The building block of the leaderboard and of the studies (:mod:`clfd_bench.studies`):
    finished runs are skipped, half-finished ones resume, a crash is recorded in the run's
    ``failed.json`` and the grid goes on. Runs go to ``out/runs/<spec.name>``, on the
    executor of ``options``.
    """
    out = Path(out)
    validate_plan(specs, out)  # before anything is launched or created
    with exclusive(out, f"clfd-bench {desc}"):  # one grid at a time on an output folder
        return _run_specs(specs, out, options, desc)


def _run_specs(specs: list[RunSpec], out: Path, options: GridOptions, desc: str) -> GridRun:
    states = {s.name: run_state(s, out) for s in specs}
    todo = [s for s in specs if states[s.name].state != "done"]
    skipped = [s for s in specs if s not in todo]
    executed_again = [s for s in todo if states[s.name].state == "partial"
                      and states[s.name].trained >= states[s.name].wanted]
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
            execute_grid(todo, out, options, on_done)
        finally:
            bar.close()
    # A run can end without a crash and still not count: e.g. its predictions were executed
    # by a simulator whose files have changed since. Such a run must not vanish from the
    # table in silence: it is a failure of the grid, with the reason.
    crashed = {o.spec.name for o in failed}
    records = []
    for record in collect(specs, out):
        if record.status not in ("done", "failed"):
            record = RunRecord(record.spec, "failed", None,
                               f"ended but does not count: {record.error}")
        if record.status == "failed" and record.spec.name not in crashed:
            failed.append(RunOutcome(record.spec, False, record.error, 0.0))
        records.append(record)
    return GridRun(specs, todo, skipped, failed, records, executed_again)


def run_leaderboard(
    dataset: str,
    methods: list[str],
    profile: str,
    seeds: list[int],
    orders: list[int],
    out: Path,
    options: GridOptions = DEFAULT_OPTIONS,
    include: list[Path] | tuple[Path, ...] = (),
    configs: dict[str, str] | None = None,
) -> LeaderboardResult:
    """Run the grid's missing runs (finished ones are skipped), then write the leaderboard.

    Writes into ``out``: ``runs/...`` (one directory per run), ``leaderboard.md``, ``.csv``,
    ``.json`` and the figures (PNG). ``options``: the runs' node, tasks and simulation, and
    where they run (:class:`~clfd_bench.leaderboard.grid.GridOptions`). ``include``: finished
    run directories from elsewhere put in beside the grid's runs (:func:`included_records`),
    e.g. predictions scored with ``clfd-bench score``; they are read, never written.
    ``configs``: method -> its hyperparameter file (``--config METHOD=PATH``; a method of
    ``methods`` each).
    """
    from clfd_bench.harness.validate import InputError

    check_methods(methods)  # an unknown name fails here, listing the valid ones
    for flag, values in (("--methods", methods), ("--seeds", seeds), ("--orders", orders)):
        if not values:
            raise InputError(f"{flag} is empty; a grid needs at least one value")
    stray = sorted(set(configs or {}) - set(methods))
    if stray:
        raise InputError(f"--config {stray[0]}=...: {stray[0]!r} is not in --methods "
                         f"({', '.join(methods)}); name the method as in --methods")
    start = time.perf_counter()
    out = Path(out)
    specs = make_grid(dataset, methods, profile, seeds, orders, options, configs)
    # Checked before any work; read, never written.
    extra = included_records([Path(p) for p in include], specs, methods) if include else []
    grid = run_specs(specs, out, options, desc=f"grid {dataset}")
    records = grid.records + extra
    labels = methods + list(dict.fromkeys(r.spec.method for r in extra))
    rows = aggregate(records, labels)
    title = f"{dataset} ({profile})"
    figures = plot_all(records, rows, labels, out, title)
    meta = {
        "dataset": dataset,
        "methods": methods,
        "profile": profile,
        "seeds": seeds,
        "orders": orders,
        "node": options.node,
        "tasks": options.tasks,
        "sim": options.sim,
        "executor": options.executor,
        "figures": [p.name for p in figures],  # beside the tables: the folder can move
        "runs": {s.name: r.status for s, r in zip(specs, grid.records, strict=True)},
        "included": [{"path": str(p), "method": r.spec.method,
                      "external": bool((r.results.get("provenance") or {}).get("external"))}
                     for p, r in zip(include, extra, strict=True)],
    }
    files = write_tables(rows, out, meta) + figures
    return LeaderboardResult(
        specs, grid.trained, grid.skipped, grid.failed, rows, files, time.perf_counter() - start,
        grid.executed_again,
    )
