"""Training time per task as tasks accrue: does a method's cost stay flat?

A hypernetwork's output regulariser (HN, CHN) looks at earlier tasks at every step. The
paper's loop (``hnet_reg = "all"``) makes one hypernetwork pass per earlier task, so a task's
training time grows with the number learned before it; ``batched`` computes the same value in
one pass (slower growth); the follow-up's stochastic regulariser (``sampled``) looks at a fixed
number of earlier tasks, so the time per task should stay flat. This study trains a grid of
methods x regulariser modes on one dataset (the leaderboard's runs: resumable, a crash is
reported) and plots each run's ``train_time_s`` per task.

Reported per configuration (median over seeds per task): the first task's seconds (no
earlier task to regularise), the second's (the first with the regulariser), the last's, and
the ratios last / first and last / second. Task times are wall-clock seconds of this machine:
anything else running beside the study shows up in them.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.io import atomic_write_json, atomic_write_text
from clfd_bench.leaderboard.aggregate import RunRecord
from clfd_bench.leaderboard.grid import GridOptions, RunSpec

__all__ = ["TimeRow", "plot_task_time", "study_specs", "summarize", "write_outputs"]

_WITHOUT_SIM = GridOptions(sim=False)


def study_specs(dataset: str, methods: list[str], regs: list[str], profile: str,
                seeds: list[int], options: GridOptions = _WITHOUT_SIM
                ) -> list[RunSpec]:
    """One run per method x regulariser mode x seed, with the node, tasks and simulation of
    ``options`` (the study's command runs them without simulation: training times are what
    it measures), labelled ``"<method> <mode>"`` (with the NODE variant unless NODE^T)."""
    from clfd_bench.node_variants import node_label

    node = options.node
    suffix = "" if node == "t" else f" ({node_label(node)})"
    return [RunSpec(dataset, m, profile, s, node=node, tasks=options.tasks, sim=options.sim,
                    overrides=(("hnet_reg", r),), entry=f"{m} {r}{suffix}")
            for m in methods for r in regs for s in seeds]


@dataclass
class TimeRow:
    """One configuration's times (seconds, medians over its finished runs)."""

    label: str
    runs: int
    per_task: list[float]
    first: float
    second: float
    last: float
    last_over_first: float
    last_over_second: float

    def to_dict(self) -> dict[str, Any]:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in asdict(self).items()}


def _times(record: RunRecord) -> list[float]:
    return [float(x) for x in (record.results or {}).get("train_time_s") or []]


def summarize(records: list[RunRecord], labels: list[str]) -> list[TimeRow]:
    """One :class:`TimeRow` per label (the records' ``spec.label``), in ``labels`` order;
    runs of one label are cut to the shortest run's number of tasks."""
    rows = []
    for label in labels:
        series = [_times(r) for r in records
                  if r.spec.label == label and r.status == "done" and _times(r)]
        if not series:
            rows.append(TimeRow(label, 0, [], math.nan, math.nan, math.nan, math.nan, math.nan))
            continue
        n = min(len(s) for s in series)
        med = np.median(np.array([s[:n] for s in series]), axis=0)
        first, last = float(med[0]), float(med[-1])
        second = float(med[1]) if n > 1 else math.nan
        rows.append(TimeRow(label, len(series), [float(x) for x in med], first, second, last,
                            last / first if first > 0 else math.nan,
                            last / second if second > 0 else math.nan))
    return rows


def _fmt(x: float, digits: int = 1) -> str:
    return "–" if not math.isfinite(x) else f"{x:.{digits}f}"


def markdown(rows: list[TimeRow], meta: dict[str, Any]) -> str:
    """The summary table."""
    lines = [
        f"# Training time per task: {meta['dataset']} ({meta['profile']} profile)",
        "",
        f"Runs: {', '.join(r.label for r in rows)}; seeds {meta['seeds']}; seconds are medians "
        "over seeds, wall clock on this machine.",
        "",
        "| configuration | runs | tasks | first task s | second s | last s | last / first "
        "| last / second |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r.label} | {r.runs} | {len(r.per_task)} | {_fmt(r.first)} | "
                     f"{_fmt(r.second)} | {_fmt(r.last)} | {_fmt(r.last_over_first, 2)} | "
                     f"{_fmt(r.last_over_second, 2)} |")
    return "\n".join(lines) + "\n"


def plot_task_time(rows: list[TimeRow], path: Path, title: str) -> Path | None:
    """Seconds per task against the task's index, one line per configuration; the legend
    gives last / first."""
    from clfd_bench.leaderboard.plots import _plt, _save

    rows = [r for r in rows if r.per_task]
    if not rows:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for k, r in enumerate(rows):
        x = np.arange(1, len(r.per_task) + 1)
        ax.plot(x, r.per_task, marker="o", ms=3, color=f"C{k}",
                label=f"{r.label}: last / first {_fmt(r.last_over_first, 2)}")
    ax.set_xlabel("task (order of learning)")
    ax.set_ylabel("training time of the task [s]")
    ax.set_ylim(bottom=0)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    out = _save(fig, Path(path))
    plt.close(fig)
    return out


def write_outputs(rows: list[TimeRow], out: Path, meta: dict[str, Any]) -> list[Path]:
    """``task_time.md/.csv/.json`` and ``task_time.png`` into ``out``."""
    out = Path(out)
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["configuration", "task", "seconds"])
    for r in rows:
        for i, sec in enumerate(r.per_task):
            w.writerow([r.label, i, f"{sec:.3f}"])
    atomic_write_text(out / "task_time.md", markdown(rows, meta))
    atomic_write_text(out / "task_time.csv", buf.getvalue())
    atomic_write_json(out / "task_time.json", {"meta": meta, "rows": [r.to_dict() for r in rows]})
    fig = plot_task_time(rows, out / "task_time.png",
                         f"{meta['dataset']} ({meta['profile']}): training time per task")
    files = [out / f"task_time.{ext}" for ext in ("md", "csv", "json")]
    return files + ([fig] if fig else [])
