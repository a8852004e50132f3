"""The paper's CL tables and training-time tables, built from our runs, next to the paper's.

A CL table is built like the paper's: the runs of task order 0, one row per method, each
criterion the median over seeds; FS across the methods of the table (so it needs a finished
run of every method of the table, else FS, CL_score and CL_stability stay empty), CL_score /
CL_stability recomputed from the six criteria (:func:`clfd_bench.leaderboard.aggregate.aggregate`
does all of this). Tables:

* LASA and HelloWorld: one per NODE variant (``t``, ``i``), from the DTW criteria;
* RoboTasks: a position and an orientation table (NODE^T), from ``cl_metrics_by_metric``
  ``"dtw"`` (positions, threshold 7131 cm-DTW) and ``"quaternion"`` (orientation error, 10°),
  with MS, FS and TE from the matching model (``num_params_by_part`` /
  ``train_time_s_by_part`` ``"position"`` or ``"orientation"``), as the paper trained
  separate models.

Each cell holds ours, the paper's (:func:`clfd_bench.metrics.paper_numbers.cl_table`) and
ours − paper. Our execution success in simulation (exec ACC / REM, from ``sim_cl_metrics``,
and exec CL_score, CL_score with them in place of ACC and REM) is added as columns the paper
does not have (RoboTasks: the whole pose is executed, so both
tables show the same values). A method without finished runs shows "—" and its count of
finished runs; nothing is filled in.

A run is looked up with simulation first and, if that one is not done, as the same run
without simulation (``..._nosim``), so tables mix both kinds (exec columns stay empty for the
latter).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.io import atomic_write_json, atomic_write_text
from clfd_bench.leaderboard.aggregate import RunRecord, aggregate
from clfd_bench.leaderboard.grid import RunSpec
from clfd_bench.leaderboard.runner import collect
from clfd_bench.metrics.paper_numbers import CL_COLUMNS, DATASET_LABELS
from clfd_bench.studies.paper_grid import PAPER_GRID, TRAIN_TIME_TABLES

__all__ = [
    "CL_COLUMNS",
    "EXEC_COLUMNS",
    "CLTable",
    "TableRow",
    "TableSpec",
    "TimeTable",
    "build_cl_table",
    "build_tables",
    "build_time_table",
    "find_records",
    "plot_diff_heatmap",
    "table_specs",
    "write_outputs",
]

EXEC_COLUMNS: tuple[str, ...] = ("exec_ACC", "exec_REM", "exec_CL_score")
"""Our extra columns: ACC and REM of execution success in simulation, and CL_score with them
in place of the trajectory ACC and REM."""

DASH = "—"


@dataclass(frozen=True)
class TableSpec:
    """One CL table: a dataset, a NODE variant and which criteria (metric / model part).

    Attributes:
        variant: the paper's table variant (``t``, ``i``, ``position``, ``orientation``).
        metric: key of ``cl_metrics_by_metric`` (``dtw`` or ``quaternion``).
        part: the model whose sizes and times feed MS, FS, TE (``position``/``orientation``).
    """

    dataset: str
    node: str
    variant: str
    metric: str
    part: str

    @property
    def key(self) -> str:
        return f"{self.dataset}_{self.variant}"

    @property
    def title(self) -> str:
        if self.dataset == "robotasks":
            return f"RoboTasks, {self.variant} (NODE^{self.node.upper()})"
        return f"{DATASET_LABELS.get(self.dataset, self.dataset)}, NODE^{self.node.upper()}"


def table_specs(specs: Sequence[RunSpec]) -> list[TableSpec]:
    """The CL tables the runs of ``specs`` can fill, in grid order."""
    out: list[TableSpec] = []
    for s in specs:
        if s.dataset == "robotasks":
            new = [TableSpec(s.dataset, s.node, "position", "dtw", "position"),
                   TableSpec(s.dataset, s.node, "orientation", "quaternion", "orientation")]
        else:
            new = [TableSpec(s.dataset, s.node, s.node, "dtw", "position")]
        out += [t for t in new if t not in out]
    return out


def find_records(specs: Sequence[RunSpec], out: Path) -> list[RunRecord]:
    """The state of each run on disk; a run not done with simulation is looked up without.

    Returns one :class:`RunRecord` per spec (its ``spec`` is the one found on disk when the
    fallback was used).
    """
    out = Path(out)
    first = collect(list(specs), out)
    alt_specs = [dataclasses.replace(r.spec, sim=not r.spec.sim) for r in first]
    alts = collect(alt_specs, out)
    records = []
    for rec, alt in zip(first, alts, strict=True):
        if rec.status != "done" and alt.status == "done":
            records.append(alt)
        else:
            records.append(rec)
    return records


def _view(results: dict[str, Any], metric: str, part: str) -> dict[str, Any]:
    """``results`` with ``cl_metrics``, ``num_params``, ``train_time_s`` of one metric / part."""
    view = dict(results)
    view["cl_metrics"] = (results.get("cl_metrics_by_metric") or {}).get(metric, {})
    view["cl_metrics_primary"] = metric  # FS then takes this metric's model (aggregate)
    view["num_params"] = (results.get("num_params_by_part") or {}).get(
        part, results.get("num_params", []))
    view["train_time_s"] = (results.get("train_time_s_by_part") or {}).get(
        part, results.get("train_time_s", []))
    return view


@dataclass
class TableRow:
    """One method of a CL table: our medians, the paper's values, and run counts."""

    method: str
    runs_done: int
    runs_expected: int
    runs_failed: int
    ours: dict[str, float] = field(default_factory=dict)
    paper: dict[str, float] = field(default_factory=dict)

    def diff(self, col: str) -> float:
        """ours − paper (NaN when either is missing)."""
        a, b = self.ours.get(col, math.nan), self.paper.get(col, math.nan)
        return a - b if math.isfinite(a) and math.isfinite(b) else math.nan


@dataclass
class CLTable:
    """A built CL table."""

    spec: TableSpec
    rows: list[TableRow]
    notes: list[str]

    def to_dict(self) -> dict[str, Any]:
        def num(x: float) -> float | None:
            return None if not math.isfinite(x) else float(x)

        return {
            "dataset": self.spec.dataset,
            "node": self.spec.node,
            "variant": self.spec.variant,
            "metric": self.spec.metric,
            "title": self.spec.title,
            "notes": self.notes,
            "rows": [
                {
                    "method": r.method,
                    "runs_done": r.runs_done,
                    "runs_expected": r.runs_expected,
                    "runs_failed": r.runs_failed,
                    "ours": {c: num(r.ours.get(c, math.nan)) for c in CL_COLUMNS + EXEC_COLUMNS},
                    "paper": {c: num(r.paper.get(c, math.nan)) for c in CL_COLUMNS},
                    "diff": {c: num(r.diff(c)) for c in CL_COLUMNS},
                }
                for r in self.rows
            ],
        }


def _paper_cl(spec: TableSpec) -> dict[str, dict[str, float]]:
    from clfd_bench.metrics.paper_numbers import cl_table

    try:
        return cl_table(spec.dataset, spec.variant)
    except KeyError:
        return {}


def build_cl_table(spec: TableSpec, records: Sequence[RunRecord]) -> CLTable:
    """One CL table from the records of the grid (those of other tables are ignored).

    Uses the runs of task order 0 of ``spec.dataset`` / ``spec.node``; methods in the paper's
    order for the dataset, those with records only.
    """
    mine = [r for r in records if r.spec.dataset == spec.dataset and r.spec.node == spec.node
            and r.spec.order == 0]
    present = {r.spec.method for r in mine}
    methods = [m for m in PAPER_GRID.get(spec.dataset, ((), ()))[0] if m in present]
    methods += sorted(present - set(methods))
    viewed = [
        dataclasses.replace(r, results=_view(r.results, spec.metric, spec.part))
        if r.results is not None else r
        for r in mine
    ]
    rows = aggregate(viewed, methods) if methods else []
    paper = _paper_cl(spec)
    notes = []
    if not mine:
        notes.append("no runs of task order 0 selected: the paper's tables use order 0")
    out_rows = []
    for row in rows:
        ours = {c: row.median(c) for c in CL_COLUMNS}
        ours.update({c: row.median(c) for c in EXEC_COLUMNS})
        expected = sum(1 for r in mine if r.spec.method == row.method)
        out_rows.append(TableRow(row.method, row.runs_ok, expected, row.runs_failed, ours,
                                 dict(paper.get(row.method.upper(), {}))))
    missing = [r.method.upper() for r in out_rows if r.runs_done == 0]
    if missing and len(missing) < len(out_rows):
        notes.append(
            f"FS, CL_score and CL_stability need a finished run of every method of the table "
            f"(FS compares final model sizes); missing: {', '.join(missing)}"
        )
    if not paper:
        notes.append("the paper has no table for this dataset / NODE variant")
    return CLTable(spec, out_rows, notes)


@dataclass
class TimeTable:
    """Training time per task: ours (median over seeds, this CPU) and the paper's (GPU).

    Attributes:
        tasks: the task indices the paper's table lists (those our runs reach).
        ours, paper: ``{method: [seconds per listed task]}`` (NaN: no finished run).
    """

    dataset: str
    part: str
    paper_table: str
    tasks: list[int]
    ours: dict[str, list[float]]
    paper: dict[str, list[float]]
    runs: dict[str, int]

    def to_dict(self) -> dict[str, Any]:
        return {
            "dataset": self.dataset,
            "part": self.part,
            "paper_table": self.paper_table,
            "tasks": self.tasks,
            "runs": self.runs,
            "ours_s": {m: [None if not math.isfinite(v) else v for v in vals]
                       for m, vals in self.ours.items()},
            "paper_s": self.paper,
        }


def build_time_table(dataset: str, part: str, records: Sequence[RunRecord]) -> TimeTable | None:
    """The paper's wall-clock table for ``dataset`` / ``part`` next to ours (NODE^T, order 0).

    Returns None when the paper has no such table.
    """
    from clfd_bench.metrics.paper_numbers import train_times

    name = TRAIN_TIME_TABLES.get(dataset, {}).get(part)
    if name is None:
        return None
    paper = train_times(name)
    mine = [r for r in records if r.spec.dataset == dataset and r.spec.node == "t"
            and r.spec.order == 0]
    if not mine:
        return None
    max_tasks = max(r.spec.num_tasks() for r in mine)
    tasks = [k for k in paper["tasks"] if k < max_tasks]
    keep = [i for i, k in enumerate(paper["tasks"]) if k < max_tasks]
    methods = [m for m in PAPER_GRID[dataset][0] if any(r.spec.method == m for r in mine)]
    ours, paper_vals, runs = {}, {}, {}
    for m in methods:
        done = [r.results for r in mine
                if r.spec.method == m and r.status == "done" and r.results is not None]
        runs[m] = len(done)
        seconds = [(res.get("train_time_s_by_part") or {}).get(part) or [] for res in done]
        per_task = []
        for k in tasks:
            vals = [float(s[k]) for s in seconds if k < len(s)]
            per_task.append(float(np.median(vals)) if vals else math.nan)
        ours[m] = per_task
        paper_vals[m] = [float(paper[m.upper()][i]) for i in keep] if m.upper() in paper else []
    return TimeTable(dataset, part, name, tasks, ours, paper_vals, runs)


def build_tables(
    specs: Sequence[RunSpec], out: Path
) -> tuple[list[CLTable], list[TimeTable], list[RunRecord]]:
    """Every CL table and training-time table the grid ``specs`` can fill from ``out/runs``."""
    records = find_records(specs, out)
    tables = [build_cl_table(t, records) for t in table_specs(specs)]
    times = []
    for dataset in dict.fromkeys(s.dataset for s in specs):
        for part in TRAIN_TIME_TABLES.get(dataset, {}):
            table = build_time_table(dataset, part, records)
            if table is not None:
                times.append(table)
    return tables, times, records


# ------------------------------------------------------------------------------------------
# Output


def _f(x: float, signed: bool = False) -> str:
    if not math.isfinite(x):
        return DASH
    return f"{x:+.2f}" if signed else f"{x:.2f}"


def _cell(row: TableRow, col: str) -> str:
    ours = row.ours.get(col, math.nan)
    paper = row.paper.get(col, math.nan)
    if not math.isfinite(paper):
        return _f(ours)
    return f"{_f(ours)} / {_f(paper)} ({_f(row.diff(col), signed=True)})"


def _markdown(tables: list[CLTable], times: list[TimeTable], meta: dict[str, Any]) -> str:
    lines = [
        "# The paper's tables, reproduced",
        "",
        f"Profile `{meta['profile']}`; seeds {meta['seeds']}; CL tables from task order 0 "
        "(as the paper's). Cells: **ours / paper (ours − paper)**; ours is the median over "
        "seeds. FS across the methods of each table, CL_score / CL_stability recomputed from "
        "the six criteria. exec ACC / exec REM: execution success in simulation (this "
        "project's addition; the paper has none); exec CL_score: CL_score with them in place "
        f"of ACC and REM. {DASH}: no finished run.",
    ]
    if meta["profile"] != "paper":
        lines += ["", f"Note: profile `{meta['profile']}` is not the paper's training budget "
                      "(`paper`), so differences to the paper are expected."]
    for t in tables:
        head = ["method", "runs", *CL_COLUMNS, *(c.replace("exec_", "exec ") for c in EXEC_COLUMNS)]
        lines += ["", f"## {t.spec.title}", "",
                  "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in t.rows:
            runs = f"{r.runs_done}/{r.runs_expected}" + (
                f" ({r.runs_failed} failed)" if r.runs_failed else "")
            cells = [r.method.upper(), runs, *[_cell(r, c) for c in CL_COLUMNS],
                     *[_f(r.ours.get(c, math.nan)) for c in EXEC_COLUMNS]]
            lines.append("| " + " | ".join(cells) + " |")
        if not t.rows:
            lines.append("| (no runs selected) |" + " |" * (len(head) - 1))
        lines += [f"\n- {n}" for n in t.notes]
    if times:
        lines += ["", "## Training time per task (seconds)", "",
                  "Ours: median over seeds of finished order-0 NODE^T runs, on this machine's "
                  "CPU (1 torch thread, machine shared with other work); paper: its appendix "
                  "tables (median over 5 seeds, one GPU, RTX 2070). Different hardware and, "
                  "unless the profile is `paper`, a different training budget: compare the "
                  "growth over tasks, not the values."]
        for tt in times:
            head = ["method", "runs", *[f"task {k}" for k in tt.tasks]]
            lines += ["", f"### {tt.dataset} ({tt.part}; paper table `{tt.paper_table}`)", "",
                      "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
            for m, vals in tt.ours.items():
                pv = tt.paper.get(m) or [math.nan] * len(vals)
                cells = [m.upper(), str(tt.runs[m])] + [
                    f"{DASH if not math.isfinite(o) else f'{o:.0f}'} / "
                    f"{DASH if not math.isfinite(p) else f'{p:.0f}'}"
                    for o, p in zip(vals, pv, strict=True)
                ]
                lines.append("| " + " | ".join(cells) + " |")
    figs = meta.get("figures") or []
    if figs:
        lines += ["", "## Figures", ""] + [f"![{Path(f).stem}]({Path(f).name})" for f in figs]
    return "\n".join(lines) + "\n"


def _csv(tables: list[CLTable], times: list[TimeTable]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["table", "dataset", "node", "variant", "method", "column", "ours", "paper",
                "diff", "runs_done", "runs_expected"])

    def num(x: float) -> str | float:
        return "" if not math.isfinite(x) else round(float(x), 6)

    for t in tables:
        for r in t.rows:
            for c in CL_COLUMNS + EXEC_COLUMNS:
                w.writerow([t.spec.key, t.spec.dataset, t.spec.node, t.spec.variant, r.method,
                            c, num(r.ours.get(c, math.nan)), num(r.paper.get(c, math.nan)),
                            num(r.diff(c)), r.runs_done, r.runs_expected])
    for tt in times:
        for m, vals in tt.ours.items():
            pv = tt.paper.get(m) or [math.nan] * len(vals)
            for k, o, p in zip(tt.tasks, vals, pv, strict=True):
                w.writerow([f"train_time_{tt.paper_table}", tt.dataset, "t", tt.part, m,
                            f"train_s_task{k}", num(o), num(p),
                            num(o - p) if math.isfinite(o) and math.isfinite(p) else "",
                            tt.runs[m], ""])
    return buf.getvalue()


def plot_diff_heatmap(tables: list[CLTable], path: Path, title: str) -> Path | None:
    """Heatmap of ours − paper per method × criterion, one panel per table with paper numbers.

    Diverging colour map centred at 0 (blue: ours higher, red: lower), ±1 full scale, the
    value printed in each cell; grey "—" where either value is missing. None if no table has
    both.
    """
    from clfd_bench.leaderboard.plots import _plt, _save

    panels = [t for t in tables if t.rows and any(r.paper for r in t.rows)]
    if not panels:
        return None
    plt = _plt()
    n = len(panels)
    cols = min(n, 2)
    nrows = math.ceil(n / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(6.4 * cols, 4.7 * nrows), squeeze=False,
                             layout="constrained")
    image = None
    for ax, t in zip(axes.flat, panels, strict=False):
        data = np.array([[r.diff(c) for c in CL_COLUMNS] for r in t.rows], dtype=float)
        masked = np.ma.masked_invalid(data)
        cmap = plt.get_cmap("RdBu").with_extremes(bad="#dddddd")
        image = ax.imshow(masked, cmap=cmap, vmin=-1.0, vmax=1.0, aspect="auto")
        for i in range(len(t.rows)):
            for j in range(len(CL_COLUMNS)):
                v = data[i, j]
                text = DASH if not math.isfinite(v) else f"{v:+.2f}"
                dark = math.isfinite(v) and abs(v) > 0.6
                ax.text(j, i, text, ha="center", va="center", fontsize=8,
                        color="white" if dark else "black")
        ax.set_xticks(range(len(CL_COLUMNS)))
        ax.set_xticklabels([c.replace("CL_stability", "CL_stab") for c in CL_COLUMNS],
                           rotation=30, ha="right", fontsize=8)
        ax.set_yticks(range(len(t.rows)))
        ax.set_yticklabels([f"{r.method.upper()} (n={r.runs_done})" for r in t.rows], fontsize=8)
        ax.set_title(t.spec.title.replace("NODE^T", r"NODE$^\mathrm{T}$")
                     .replace("NODE^I", r"NODE$^\mathrm{I}$"), fontsize=10)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    if image is not None:
        fig.colorbar(image, ax=axes.ravel().tolist(), shrink=0.8, label="ours − paper")
    fig.suptitle(title, fontsize=11)
    saved = _save(fig, Path(path))
    plt.close(fig)
    return saved


def write_outputs(
    tables: list[CLTable], times: list[TimeTable], out: Path, meta: dict[str, Any]
) -> list[Path]:
    """Write ``paper_tables.md``/``.csv``/``.json`` and ``paper_diff.png`` into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    title = f"ours − paper (profile {meta['profile']}, median over seeds {meta['seeds']})"
    fig = plot_diff_heatmap(tables, out / "paper_diff.png", title)
    meta = {**meta, "figures": [str(fig)] if fig else []}
    md, cs, js = out / "paper_tables.md", out / "paper_tables.csv", out / "paper_tables.json"
    atomic_write_text(md, _markdown(tables, times, meta))
    atomic_write_text(cs, _csv(tables, times))
    atomic_write_json(js, {
        "schema_version": 1,
        "meta": meta,
        "cl_tables": [t.to_dict() for t in tables],
        "train_time_tables": [t.to_dict() for t in times],
    })
    return [md, cs, js] + ([fig] if fig else [])
