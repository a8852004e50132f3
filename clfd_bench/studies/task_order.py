"""Robustness to task order (paper appendix "Robustness to Task Order").

The same methods are trained on orders 0, 1, 2 of each dataset (several seeds each) through
the leaderboard grid (:func:`clfd_bench.leaderboard.runner.run_specs`; finished runs are
skipped, half-finished ones resume). Then, per dataset:

* one figure with one column per order: the error of every seen task vs the current task
  (median line, IQR band over seeds and over the tasks learned so far; DTW, plus a row for the
  quaternion error on pose data) and, when the runs executed in simulation, a row with the
  execution success of the seen tasks vs the current task;
* a table per dataset x order x method (ACC, REM, CL_score, CL_stability, exec ACC; medians
  over seeds, FS across the methods of that order) and, per method, the spread of its CL_score
  and ACC across orders and its rank in each order, so one sees whether the order changes the
  ranking.
"""

from __future__ import annotations

import csv
import io
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.io import atomic_write_json, atomic_write_text, json_safe
from clfd_bench.leaderboard.aggregate import RunRecord, aggregate
from clfd_bench.leaderboard.grid import DEFAULT_OPTIONS, GridOptions, RunSpec, make_grid
from clfd_bench.leaderboard.plots import _errors_after, _median_band, _plt, _save
from clfd_bench.leaderboard.runner import run_specs
from clfd_bench.node_variants import node_label

__all__ = [
    "OrderCell",
    "OrderStudyResult",
    "TABLE_KEYS",
    "method_spread",
    "order_figure",
    "order_specs",
    "order_table",
    "run_order_study",
    "task_names",
    "write_order_tables",
]

TABLE_KEYS: tuple[str, ...] = ("ACC", "REM", "CL_score", "CL_stability", "exec_ACC", "exec_REM")
"""Columns of the order table (medians over seeds of :func:`aggregate`'s per-run values)."""

_METRIC_LABEL = {"dtw": "position DTW", "quaternion": "quaternion error"}


def task_names(dataset: str, order: int) -> tuple[str, ...]:
    """The dataset's task names in the given order (paper table "Task orders")."""
    from clfd_bench.data import DATASETS

    orders = DATASETS[dataset].task_names()
    if not 0 <= order < len(orders):
        raise ValueError(f"dataset {dataset!r} has task orders 0..{len(orders) - 1}, not {order}")
    return tuple(orders[order])


def order_specs(
    datasets: list[str],
    methods: list[str],
    orders: list[int],
    seeds: list[int],
    profile: str,
    options: GridOptions = DEFAULT_OPTIONS,
) -> list[RunSpec]:
    """Every (dataset, method, order, seed) run of the study, in a stable order."""
    if not datasets:
        raise ValueError("the order study needs at least one dataset")
    specs: list[RunSpec] = []
    for dataset in datasets:
        specs += make_grid(dataset, methods, profile, seeds, orders, options)
    return specs


# ------------------------------------------------------------------------------ table
@dataclass
class OrderCell:
    """One row of the order table: a method on one order of one dataset (medians over seeds).

    ``values`` maps each of :data:`TABLE_KEYS` to its median (NaN when no run has it);
    ``rank`` is the method's place by median CL_score among the methods of that order
    (1 best; None when it has no CL_score).
    """

    dataset: str
    order: int
    method: str
    runs_ok: int
    runs_failed: int
    values: dict[str, float] = field(default_factory=dict)
    rank: int | None = None


def order_table(records: list[RunRecord], methods: list[str]) -> list[OrderCell]:
    """Aggregate the runs per dataset and order (FS across the methods of that order).

    Args:
        records: the runs' states (:func:`clfd_bench.leaderboard.runner.collect`).
        methods: the compared methods, in table order.

    Returns:
        One :class:`OrderCell` per (dataset, order, method), datasets and orders in the order
        they first appear in ``records``.
    """
    groups: dict[tuple[str, int], list[RunRecord]] = {}
    for record in records:
        groups.setdefault((record.spec.dataset, record.spec.order), []).append(record)
    cells: list[OrderCell] = []
    for (dataset, order), group in groups.items():
        rows = aggregate(group, methods)
        these = [
            OrderCell(dataset, order, row.method, row.runs_ok, row.runs_failed,
                      {key: row.median(key) for key in TABLE_KEYS})
            for row in rows
        ]  # fmt: skip
        scored = sorted(
            (c for c in these if not math.isnan(c.values["CL_score"])),
            key=lambda c: -c.values["CL_score"],
        )
        for place, cell in enumerate(scored, 1):
            cell.rank = place
        cells += these
    return cells


def method_spread(cells: list[OrderCell]) -> list[dict[str, Any]]:
    """Per dataset and method: how much CL_score and ACC move across orders, and the ranks.

    Returns:
        ``[{"dataset", "method", "orders": [...], "CL_score": [...], "ACC": [...],
        "CL_score_spread", "ACC_spread" (max - min over orders, NaN with < 1 value),
        "ranks": [...], "rank_changes": bool}]``.
    """
    out: list[dict[str, Any]] = []
    keys = list(dict.fromkeys((c.dataset, c.method) for c in cells))
    for dataset, method in keys:
        mine = [c for c in cells if c.dataset == dataset and c.method == method]
        entry: dict[str, Any] = {
            "dataset": dataset,
            "method": method,
            "orders": [c.order for c in mine],
            "ranks": [c.rank for c in mine],
        }
        for key in ("CL_score", "ACC"):
            vals = [c.values[key] for c in mine]
            entry[key] = vals
            finite = [v for v in vals if not math.isnan(v)]
            entry[f"{key}_spread"] = max(finite) - min(finite) if finite else math.nan
        entry["rank_changes"] = len({r for r in entry["ranks"] if r is not None}) > 1
        out.append(entry)
    return out


def _fmt(value: float | None) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{value:.2f}"


def _markdown(cells: list[OrderCell], spread: list[dict[str, Any]], meta: dict[str, Any]) -> str:
    lines = [
        "# Robustness to task order",
        "",
        f"Methods {', '.join(m.upper() for m in meta['methods'])}; orders {meta['orders']}; "
        f"seeds {meta['seeds']}; profile {meta['profile']}; {node_label(meta['node'])}"
        + (f"; first {meta['tasks']} tasks" if meta.get("tasks") else "")
        + ("; with simulated execution" if meta.get("sim") else "; no simulation")
        + ".",
        "Cells: median over seeds. ACC/REM: trajectory accuracy (DTW under the paper's "
        "threshold); CL_score/CL_stability over ACC, REM, MS, TE, FS, SSS with FS across the "
        "methods of that order; exec ACC/REM: from executing the predictions in simulation. "
        "Rank: place by CL_score within the order.",
    ]
    for dataset in dict.fromkeys(c.dataset for c in cells):
        lines += ["", f"## {dataset}", ""]
        head = ["order", "tasks", "method", "runs", "ACC", "REM", "CL_score", "CL_stab",
                "exec ACC", "exec REM", "rank"]  # fmt: skip
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for cell in (c for c in cells if c.dataset == dataset):
            names = task_names(dataset, cell.order)[: meta.get("tasks") or None]
            runs = f"{cell.runs_ok}" + (f" (+{cell.runs_failed} failed)" if cell.runs_failed
                                        else "")
            row = [str(cell.order), ", ".join(names), cell.method.upper(), runs,
                   *(_fmt(cell.values[k]) for k in TABLE_KEYS),
                   "-" if cell.rank is None else str(cell.rank)]  # fmt: skip
            lines.append("| " + " | ".join(row) + " |")
        lines += ["", "Spread across orders (max - min of the per-order medians):", ""]
        lines += ["| method | CL_score per order | spread | ACC per order | spread | ranks |",
                  "|---|---|---|---|---|---|"]  # fmt: skip
        for entry in (e for e in spread if e["dataset"] == dataset):
            ranks = ", ".join("-" if r is None else str(r) for r in entry["ranks"])
            lines.append(
                f"| {entry['method'].upper()} | {', '.join(_fmt(v) for v in entry['CL_score'])} "
                f"| {_fmt(entry['CL_score_spread'])} | {', '.join(_fmt(v) for v in entry['ACC'])}"
                f" | {_fmt(entry['ACC_spread'])} | {ranks} |"
            )
        changes = [e["method"].upper() for e in spread if e["dataset"] == dataset
                   and e["rank_changes"]]  # fmt: skip
        lines += ["", "Ranking by CL_score: " + (
            "the same in every order." if not changes
            else f"changes with the order (methods whose rank moves: {', '.join(changes)})."
        )]
        fig = (meta.get("figures") or {}).get(dataset)
        if fig:
            lines += ["", f"![order_{dataset}]({Path(fig).name})"]
    return "\n".join(lines) + "\n"


def write_order_tables(
    cells: list[OrderCell], spread: list[dict[str, Any]], out: Path, meta: dict[str, Any]
) -> list[Path]:
    """Write ``order_table.md``, ``.csv`` and ``.json`` into ``out``; return their paths."""
    out.mkdir(parents=True, exist_ok=True)
    md, cs, js = out / "order_table.md", out / "order_table.csv", out / "order_table.json"
    atomic_write_text(md, _markdown(cells, spread, meta))
    buffer = io.StringIO()
    writer = csv.writer(buffer)
    writer.writerow(["dataset", "order", "method", "runs_ok", "runs_failed", *TABLE_KEYS, "rank"])
    for c in cells:
        vals = ["" if math.isnan(c.values[k]) else c.values[k] for k in TABLE_KEYS]
        writer.writerow([c.dataset, c.order, c.method, c.runs_ok, c.runs_failed, *vals,
                         "" if c.rank is None else c.rank])  # fmt: skip
    atomic_write_text(cs, buffer.getvalue())
    payload = {
        "schema_version": 1,
        "meta": meta,
        "cells": [
            {"dataset": c.dataset, "order": c.order, "method": c.method,
             "tasks": list(task_names(c.dataset, c.order)[: meta.get("tasks") or None]),
             "runs_ok": c.runs_ok, "runs_failed": c.runs_failed, "rank": c.rank,
             "metrics": {k: json_safe(v) for k, v in c.values.items()}}
            for c in cells
        ],  # fmt: skip
        "spread": [{k: json_safe(v) for k, v in e.items()} for e in spread],
    }
    atomic_write_json(js, payload)
    return [md, cs, js]


# ------------------------------------------------------------------------------ figure
def _runs(records: list[RunRecord], dataset: str, order: int, method: str) -> list[dict]:
    return [
        r.results
        for r in records
        if r.spec.dataset == dataset and r.spec.order == order and r.spec.method == method
        and r.status == "done" and r.results is not None
    ]  # fmt: skip


def _success_after(results: dict, i: int) -> float | None:
    """Mean execution success over the seen tasks' demos after learning task ``i``."""
    rows = results.get("success") or []
    if i >= len(rows):
        return None
    flags = [bool(s) for cell in rows[i][: i + 1] if cell is not None for s in cell]
    return float(np.mean(flags)) if flags else None


def order_figure(
    records: list[RunRecord], dataset: str, methods: list[str], orders: list[int], title: str = ""
):
    """The order figure of one dataset: one column per order (matplotlib Figure).

    Rows: the error of all seen tasks vs the current task for each error metric the runs have
    (``dtw``; pose data add ``quaternion``), log scale, the paper's threshold dashed; then, if
    any run executed in simulation, the execution success of the seen tasks. Lines: median over
    seeds and seen tasks, bands: IQR. The x axis names the task learned at each step.
    """
    plt = _plt()
    done = [r.results for r in records if r.spec.dataset == dataset and r.results is not None
            and r.status == "done"]  # fmt: skip
    first = done[0] if done else {}
    metrics = [m for m in ("dtw", "quaternion") if m in first.get("errors", {})]
    if not metrics and first:
        metrics = [next(iter(first["errors"]))]
    has_sim = any(res.get("success") for res in done)
    nrows = max(1, len(metrics) + int(has_sim))
    ncols = len(orders)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.6 * ncols + 0.6, 3.0 * nrows + 1.2),
                             squeeze=False, sharey="row", layout="constrained")  # fmt: skip
    units = first.get("units", {})
    thresholds = first.get("thresholds", {})
    for col, order in enumerate(orders):
        names = task_names(dataset, order)
        learned = max(
            (len(res["tasks"]) for m in methods for res in _runs(records, dataset, order, m)),
            default=0,
        )
        for row, metric in enumerate(metrics):
            ax = axes[row][col]
            for method in methods:
                runs = _runs(records, dataset, order, method)
                samples = {
                    i: [e for res in runs if i < len(res["tasks"])
                        for e in _errors_after(res, metric, i)]
                    for i in range(learned)
                }  # fmt: skip
                _median_band(ax, method.upper(), samples)
            if thresholds.get(metric):
                ax.axhline(thresholds[metric], color="k", ls="--", lw=1, label="threshold")
            ax.set_yscale("log")
            if col == 0:
                unit = f" [{units[metric]}]" if units.get(metric) else ""
                ax.set_ylabel(f"{_METRIC_LABEL.get(metric, metric)} of seen tasks{unit}")
        if has_sim:
            ax = axes[len(metrics)][col]
            for method in methods:
                runs = _runs(records, dataset, order, method)
                samples: dict[int, list[float]] = {}
                for i in range(learned):
                    vals = [_success_after(res, i) for res in runs]
                    samples[i] = [v for v in vals if v is not None]
                _median_band(ax, method.upper(), samples)
            ax.set_ylim(-0.03, 1.03)
            if col == 0:
                ax.set_ylabel("execution success of seen tasks")
        axes[0][col].set_title(f"order {order}")
        for row in range(nrows):
            ax = axes[row][col]
            ax.grid(alpha=0.3)
            ax.set_xticks(range(learned))
            if row == nrows - 1:
                ax.set_xlabel("current task (the task just learned)")
                shown = names[:learned]
                if max((len(n) for n in shown), default=0) <= 2:
                    ax.set_xticklabels([f"{i}\n{n}" for i, n in enumerate(shown)], fontsize=8)
                else:
                    ax.set_xticklabels([f"{i}: {n}" for i, n in enumerate(shown)], rotation=60,
                                       ha="right", fontsize=7 if learned <= 8 else 5)
            else:
                ax.tick_params(labelbottom=False)
    handles, labels = axes[0][0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8)
    fig.suptitle(title or f"{dataset}: robustness to task order (median, IQR over seeds "
                 "and seen tasks)")  # fmt: skip
    return fig


# ------------------------------------------------------------------------------ study
@dataclass
class OrderStudyResult:
    """What :func:`run_order_study` did and wrote."""

    specs: list[RunSpec]
    trained: list[RunSpec]
    skipped: list[RunSpec]
    failed: list[Any]
    cells: list[OrderCell]
    spread: list[dict[str, Any]]
    files: list[Path]
    seconds: float

    def summary(self) -> str:
        """One paragraph: what ran, and whether the order changed the ranking."""
        parts = [
            f"Task-order study: {len(self.specs)} runs ({len(self.trained)} trained now, "
            f"{len(self.skipped)} already done, {len(self.failed)} failed) in "
            f"{self.seconds:.0f} s."
        ]
        for dataset in dict.fromkeys(c.dataset for c in self.cells):
            mine = [e for e in self.spread if e["dataset"] == dataset]
            spreads = ", ".join(
                f"{e['method'].upper()} {_fmt(e['CL_score_spread'])}" for e in mine
            )
            moved = [e["method"].upper() for e in mine if e["rank_changes"]]
            parts.append(
                f"{dataset}: CL_score spread across orders {spreads}; ranking "
                + ("unchanged across orders." if not moved else f"changes ({', '.join(moved)}).")
            )
        return " ".join(parts)


def run_order_study(
    datasets: list[str],
    methods: list[str],
    orders: list[int],
    seeds: list[int],
    profile: str,
    out: Path,
    options: GridOptions = DEFAULT_OPTIONS,
) -> OrderStudyResult:
    """Run (or resume) the study's runs, then write the tables and one figure per dataset.

    Writes into ``out``: ``runs/...`` (one directory per run), ``order_table.md``, ``.csv``,
    ``.json`` and ``order_<dataset>.png``. ``options``: the runs' node, tasks and simulation,
    and where they run (:class:`~clfd_bench.leaderboard.grid.GridOptions`).
    """
    from clfd_bench.methods import get_method_class

    for method in methods:
        get_method_class(method)  # an unknown name fails here, listing the valid ones
    for dataset in datasets:
        for order in orders:
            task_names(dataset, order)  # unknown dataset / order fails before training
    start = time.perf_counter()
    out = Path(out)
    specs = order_specs(datasets, methods, orders, seeds, profile, options)
    grid = run_specs(specs, out, options, desc="order study")
    cells = order_table(grid.records, methods)
    spread = method_spread(cells)
    figures: dict[str, str] = {}
    for dataset in datasets:
        fig = order_figure(grid.records, dataset, methods, orders)
        figures[dataset] = str(_save(fig, out / f"order_{dataset}.png"))
        _plt().close(fig)
    meta = {
        "datasets": datasets, "methods": methods, "orders": orders, "seeds": seeds,
        "profile": profile, "node": options.node, "tasks": options.tasks, "sim": options.sim,
        "executor": options.executor,
        "figures": figures,
        "runs": {r.spec.name: r.status for r in grid.records},
    }  # fmt: skip
    files = write_order_tables(cells, spread, out, meta) + [Path(p) for p in figures.values()]
    return OrderStudyResult(specs, grid.trained, grid.skipped, grid.failed, cells, spread, files,
                            time.perf_counter() - start)  # fmt: skip
