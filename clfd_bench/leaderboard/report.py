"""Leaderboard tables: Markdown, CSV and JSON, written atomically.

The paper's ranking beside ours
-------------------------------
When the grid is one the paper has a CL table for (:func:`paper_ranking`), the Markdown
table gets two more columns, ``paper #`` (the method's rank in that table by CL_score) and
``paper CL_score``, and a line under the table names the table (its LaTeX label), says
whether our ranking by median CL_score equals the paper's and, if not, which pairs are
swapped and by how much. A grid matches a paper table when it has the same dataset, the same
NODE variant and exactly the table's methods; the profile, seeds, orders, simulation and a
``--tasks`` limit do not matter (the last is said in the line). Otherwise the table is
unchanged and the line says why no paper table matches.

* Ranks: the paper prints CL_scores rounded to two decimals; methods with the same printed
  CL_score **share a rank** (competition ranking: 1, 2, 2, 4), as nothing in the paper orders
  them (only LASA NODE^I has such ties: FT/SI 0.69, REP/CHN 0.82).
* Swaps: a pair is swapped when ours and the paper order it strictly the other way round
  (a pair tied in either is not). A swap whose CL_scores differ by at most :data:`TIE` in
  ours or in the paper's counts as a tie, and the line says so; the ranking "equals the
  paper's up to ties" when every swap is one. Methods without a CL_score of ours (no finished
  run) are left out of the comparison, and named.
* By execution: when the runs executed their predictions, the line also compares our ranking
  by **exec CL_score** (ACC and REM from execution, the other criteria the same:
  :mod:`clfd_bench.leaderboard.aggregate`) with the paper's ranking by its CL_score, by the
  same rules. The paper scored trajectories only; this says whether what the robot achieves
  orders the methods as the paper's trajectory scores did.
* RoboTasks: the paper has a position table (``tab:rt_pos_cl``, DTW of positions) and an
  orientation table (``tab:rt_ori_cl``, quaternion error). The leaderboard has one CL_score,
  computed (:func:`clfd_bench.leaderboard.aggregate.aggregate`) from a run's
  ``cl_metrics``, which is its primary metric, ``cl_metrics_primary`` = ``"dtw"``: position
  DTW, with MS and TE from the position model. So a RoboTasks leaderboard is compared with
  the position table only; the orientation one has no counterpart here (the paper-table
  study, :mod:`clfd_bench.studies.paper_tables`, builds both). The paper's RoboTasks tables
  are NODE^T only and ``robotasks9`` has none.

The ``.csv`` and ``.json`` rows carry ``paper_rank`` and ``paper_cl_score`` (empty / null
when no paper table matches); the ``.json`` also has the comparison under ``"paper"``.

Reading a leaderboard back (the static site, :mod:`clfd_bench.site`) goes through this module
too: :func:`read_leaderboard` (``leaderboard.json``), :func:`leaderboard_runs` (the run
directories behind its rows), :func:`leaderboard_figures` and :func:`paper_values` (the
matching paper table's numbers, every column, per method).

Runs put in with ``--include`` (e.g. predictions scored elsewhere, ``clfd-bench score``) get a
row under their method label; a cell their run could not fill (no model size, training time
or stored samples given) shows "—" (``null`` and ``not_provided`` in the ``.json``), never a
made-up number, and a row without a CL_score ranks after those with one.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

from clfd_bench.execution.execute import FAILURE_KINDS
from clfd_bench.io import atomic_write_json, atomic_write_text
from clfd_bench.leaderboard.aggregate import MethodRow
from clfd_bench.leaderboard.entries import ENTRIES
from clfd_bench.metrics.cl import CRITERIA
from clfd_bench.metrics.paper_numbers import DATASET_LABELS
from clfd_bench.node_variants import node_label

__all__ = ["COLUMNS", "LEADERBOARD_JSON", "Column", "NOT_PROVIDED", "TIE", "LeaderboardRun",
           "PaperRanking", "format_cell", "leaderboard_figures", "leaderboard_runs",
           "paper_ranking", "paper_values", "rank", "read_leaderboard", "write_tables"]

class Column(NamedTuple):
    """One column of the leaderboard: ``key`` in :attr:`MethodRow.values` and in
    ``leaderboard.json``'s rows' ``metrics`` (and the CSV's ``<key>_median`` ...), ``head``
    its header (its name in :mod:`clfd_bench.metrics.glossary`), ``group`` what it measures:
    ``trajectory`` (DTW under the paper's threshold), ``execution`` (on the simulated robot)
    or ``cost``."""

    key: str
    head: str
    group: str


COLUMNS: tuple[Column, ...] = (
    Column("CL_score", "CL_score", "trajectory"),
    Column("CL_stability", "CL_stab", "trajectory"),
    *(Column(k, k, "trajectory") for k in CRITERIA),
    Column("BWT", "BWT", "trajectory"),
    Column("exec_ACC", "exec ACC", "execution"),
    Column("exec_REM", "exec REM", "execution"),
    Column("exec_BWT", "exec BWT", "execution"),
    Column("exec_CL_score", "exec CL_score", "execution"),
    Column("train_time_s", "train s", "cost"),
    Column("train_cpu_s", "train CPU s", "cost"),
    Column("final_params", "params", "cost"),
)
"""The leaderboard's columns, in table order: the one list the Markdown, CSV and JSON tables
and the site's table (:mod:`clfd_bench.site.build`) are written from."""


LEADERBOARD_JSON = "leaderboard.json"
"""The leaderboard's machine-readable file in its output folder."""
_SCHEMA = 1

TIE = 0.02
"""A swap of two methods whose CL_scores differ by at most this (ours or the paper's) is a tie."""



@dataclass
class PaperRanking:
    """The paper's CL table matching a leaderboard's grid, and how our ranking compares.

    Attributes:
        label: the paper table's LaTeX label, or None when no table matches the grid.
        note: the one line printed under the Markdown table.
        table: ``(dataset, variant)`` of :func:`clfd_bench.metrics.paper_numbers.cl_table`.
        reason: why no table matches (None when one does).
        ranks, scores: method (lower case, as in the grid) -> the paper's rank / CL_score.
        matches: our ranking equals the paper's (None: no table, or nothing to compare).
        matches_up_to_ties: the same, counting swaps within :data:`TIE` as ties.
        swaps: ``{"paper_ahead", "ours_ahead", "paper_diff", "ours_diff", "tie"}`` per
            swapped pair, in the paper's order.
        not_compared: methods without a CL_score of ours.
        key: which score of ours was compared (``CL_score`` or ``exec_CL_score``).
        executed: the comparison by ``exec_CL_score`` (set by :func:`write_tables` when the
            runs executed), None otherwise.
    """

    label: str | None
    note: str
    table: tuple[str, str] | None = None
    reason: str | None = None
    ranks: dict[str, int] = field(default_factory=dict)
    scores: dict[str, float] = field(default_factory=dict)
    matches: bool | None = None
    matches_up_to_ties: bool | None = None
    swaps: list[dict[str, Any]] = field(default_factory=list)
    not_compared: list[str] = field(default_factory=list)
    key: str = "CL_score"
    executed: PaperRanking | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "table": self.label,
            "dataset": self.table[0] if self.table else None,
            "variant": self.table[1] if self.table else None,
            "reason": self.reason,
            "ranking_matches": self.matches,
            "ranking_matches_up_to_ties": self.matches_up_to_ties,
            "tie_threshold": TIE,
            "swaps": self.swaps,
            "not_compared": self.not_compared,
            "note": self.note,
            "executed": self.executed.to_dict() if self.executed is not None else None,
        }


def _paper_table(meta: dict[str, Any]) -> tuple[tuple[str, str] | None, str]:
    """``((dataset, variant), label)`` of the paper table matching the grid, or
    ``(None, reason)``."""
    from clfd_bench.metrics.paper_numbers import cl_table, cl_table_label, cl_tables

    dataset, node = meta["dataset"], meta.get("node", "t")
    if dataset not in DATASET_LABELS:
        return None, f"the paper has no CL table for {dataset}"
    if node == "s":
        return None, "the paper has no sNODE tables (the stable NODE is its follow-up's)"
    if dataset == "robotasks":
        if node != "t":
            return None, (f"the paper's RoboTasks tables are NODE^T only (this grid: "
                          f"NODE^{node.upper()})")
        variant = "position"  # CL_score here is from the runs' primary metric, position DTW
    else:
        variant = node
    if (dataset, variant) not in cl_tables():
        return None, f"the paper has no CL table for {dataset} NODE^{node.upper()}"
    label = cl_table_label(dataset, variant)
    paper = list(cl_table(dataset, variant))
    ours = [m.upper() for m in meta["methods"]]
    missing = [m for m in paper if m not in ours]
    extra = [m for m in ours if m not in paper]
    if missing or extra:
        parts = ([f"missing {', '.join(missing)}"] if missing else []) + (
            [f"not in it {', '.join(extra)}"] if extra else [])
        return None, f"methods differ from {label}: {'; '.join(parts)}"
    return (dataset, variant), label


def paper_ranking(rows: list[MethodRow], meta: dict[str, Any],
                  key: str = "CL_score") -> PaperRanking:
    """Compare the leaderboard's rows (any order) with the paper's matching CL table.

    ``meta`` needs ``dataset``, ``methods`` and ``node`` (default ``"t"``); ``tasks`` is
    mentioned when set. ``key``: our score to rank by, ``CL_score`` or ``exec_CL_score``
    (then the note is only the comparison's sentence, to follow the CL_score one). See the
    module docstring for the rules.
    """
    if key not in ("CL_score", "exec_CL_score"):
        raise ValueError(f"key must be 'CL_score' or 'exec_CL_score', got {key!r}")
    score_name = {"CL_score": "CL_score", "exec_CL_score": "exec CL_score"}[key]
    by = score_name if key == "CL_score" else f"{score_name} (ACC and REM from execution)"
    from clfd_bench.metrics.paper_numbers import cl_table

    table, label = _paper_table(meta)
    if table is None:
        return PaperRanking(None, f"Paper: no paper CL table matches this grid ({label}).",
                            reason=label, key=key)
    dataset, variant = table
    paper = {m.lower(): row["CL_score"] for m, row in cl_table(dataset, variant).items()}
    ranks = {m: 1 + sum(other > score for other in paper.values()) for m, score in paper.items()}
    order = sorted(paper, key=lambda m: (ranks[m], list(paper).index(m)))
    ours = {r.method.lower(): r.median(key) for r in rows}
    not_compared = [m for m in order if math.isnan(ours.get(m, math.nan))]
    swaps = []
    for i, ahead in enumerate(order):
        for behind in order[i + 1:]:
            if ahead in not_compared or behind in not_compared:
                continue
            paper_diff = paper[ahead] - paper[behind]
            ours_diff = ours[behind] - ours[ahead]
            if paper_diff > 0 and ours_diff > 0:
                tie = min(paper_diff, ours_diff) <= TIE + 1e-9
                swaps.append({"paper_ahead": ahead, "ours_ahead": behind,
                              "paper_diff": round(paper_diff, 6), "ours_diff": round(ours_diff, 6),
                              "tie": tie})
    name = DATASET_LABELS[dataset]
    what = (f"{name} NODE^T, positions: CL_score here is from position DTW"
            if dataset == "robotasks" else f"{name} NODE^{variant.upper()}")
    parts = [f"Paper: {label} ({what}); \"paper #\" ranks by its CL_score"]
    shared = [r for r in sorted(set(ranks.values())) if list(ranks.values()).count(r) > 1]
    if shared:
        tied = ", ".join("/".join(m.upper() for m in order if ranks[m] == r)
                         + f" {next(paper[m] for m in order if ranks[m] == r):.2f}"
                         for r in shared)
        parts[0] += f", ties sharing a rank ({tied})"
    parts[0] += "."
    if key != "CL_score":
        parts = []
    if len(order) - len(not_compared) < 2:
        matches = up_to_ties = None
        parts.append(f"Not enough {score_name}s of ours to compare rankings.")
    else:
        matches = not swaps
        up_to_ties = all(s["tie"] for s in swaps)

        def say(s: dict[str, Any]) -> str:
            text = (f"{s['paper_ahead'].upper()}/{s['ours_ahead'].upper()} (ours: "
                    f"{s['ours_ahead'].upper()} ahead by {s['ours_diff']:.2f}; paper: "
                    f"{s['paper_ahead'].upper()} ahead by {s['paper_diff']:.2f})")
            return text + (f", a tie (within {TIE})" if s["tie"] else "")

        if matches:
            parts.append(f"Our ranking by {by} equals the paper's.")
        elif up_to_ties:
            parts.append(f"Our ranking by {by} equals the paper's up to ties (scores "
                         f"within {TIE} in ours or the paper's); swapped: "
                         + "; ".join(say(s) for s in swaps) + ".")
        else:
            parts.append(f"Our ranking by {by} differs from the paper's; swapped: "
                         + "; ".join(say(s) for s in swaps) + ".")
    if not_compared:
        parts.append(f"Not compared (no {score_name} of ours): "
                     f"{', '.join(m.upper() for m in not_compared)}.")
    if meta.get("tasks") and key == "CL_score":
        parts.append(f"This grid learns only the first {meta['tasks']} tasks; the paper's "
                     "table, all of them.")
    return PaperRanking(label, " ".join(parts), table, None, ranks, paper, matches,
                        up_to_ties, swaps, not_compared, key)


NOT_PROVIDED = "—"
"""The cell of a value the run did not provide (predictions scored from elsewhere)."""


def format_cell(value: float | None, key: str) -> str:
    """A table cell: "-" for a missing value, parameter counts with thousands separators,
    training seconds (wall-clock and CPU) whole, everything else to two decimals."""
    if value is None or math.isnan(value):
        return "-"
    if key == "final_params":
        return f"{value:,.0f}"
    if key in ("train_time_s", "train_cpu_s"):
        return f"{value:.0f}"
    return f"{value:.2f}"


def rank(rows: list[MethodRow]) -> list[MethodRow]:
    """Rows by median CL_score (trajectory-based), best first; rows without runs last."""

    have_score = any(not math.isnan(r.median("CL_score")) for r in rows)

    def key(row: MethodRow) -> tuple[int, int, float]:
        score = row.median("CL_score")
        # Without any CL_score, every row ranks by ACC; else rows without one come after.
        later = int(have_score and math.isnan(score))
        if math.isnan(score):
            score = row.median("ACC")
        return (0 if row.runs_ok else 1, later, -(score if not math.isnan(score) else -1.0))

    return sorted(rows, key=key)


def _cell(row: MethodRow, key: str) -> str:
    med = row.median(key)
    if math.isnan(med):
        return NOT_PROVIDED if key in row.not_provided else "-"
    q1, q3 = row.iqr(key)
    if len(row.values.get(key, [])) > 1 and (q3 - q1) > 0:
        return f"{format_cell(med, key)} [{format_cell(q1, key)}, {format_cell(q3, key)}]"
    return format_cell(med, key)


def _markdown(rows: list[MethodRow], meta: dict[str, Any], paper: PaperRanking) -> str:
    heads = [c.head for c in COLUMNS]
    if paper.label:  # the paper's rank after ours, its CL_score after ours
        head = ["#", "paper #", "method", "runs", heads[0], "paper CL_score", *heads[1:]]
    else:
        head = ["#", "method", "runs", *heads]
    lines = [
        f"# Leaderboard: {meta['dataset']} ({meta['profile']} profile)",
        "",
        f"Grid: methods {', '.join(meta['methods'])}; seeds {meta['seeds']}; orders "
        f"{meta['orders']}; {node_label(meta['node'])}"
        + (f"; first {meta['tasks']} tasks" if meta.get("tasks") else "")
        + ("; with simulated execution" if meta.get("sim") else "; no simulation")
        + ".",
        "Cells: median [IQR] over runs. ACC, REM, BWT: trajectory accuracy (DTW under the "
        "paper's threshold); exec ACC/REM/BWT: the same from executing predictions in "
        f"simulation. CL_score/CL_stability over {', '.join(CRITERIA)} (FS across the "
        "methods compared here); exec CL_score: CL_score with exec ACC and exec REM. train s / "
        "train CPU s: wall-clock and CPU seconds of training (one process per run).",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for idx, row in enumerate(rows, 1):
        runs = f"{row.runs_ok}" + (f" (+{row.runs_failed} failed)" if row.runs_failed else "")
        cells = [_cell(row, c.key) for c in COLUMNS]
        if paper.label:
            m = row.method.lower()
            p_rank = str(paper.ranks[m]) if m in paper.ranks else "-"
            p_score = f"{paper.scores[m]:.2f}" if m in paper.scores else "-"
            cells = [str(idx), p_rank, row.method.upper(), runs, cells[0], p_score, *cells[1:]]
        else:
            cells = [str(idx), row.method.upper(), runs, *cells]
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", paper.note + (f" {paper.executed.note}" if paper.executed else "")]
    named = [ENTRIES[m].describe() for m in meta["methods"] if m in ENTRIES]
    if named:  # their own NODE variant and settings, whatever the grid's
        lines += ["", "Named entries: " + "; ".join(named) + "."]
    included = meta.get("included") or []
    if included:
        lines += ["", "Included runs (`--include`): " + "; ".join(
            f"{r['method'].upper()} `{r['path']}`"
            + (" (scored from external predictions)" if r.get("external") else "")
            for r in included) + "."]
    if any(row.not_provided for row in rows):
        lines += [f"{NOT_PROVIDED}: not provided by the run (predictions scored elsewhere "
                  "without model size, training time or stored samples); never estimated."]
    lines += _failure_table(rows)
    failures = [(row.method, e) for row in rows for e in row.errors]
    if failures:
        lines += ["", "## Failed runs", ""]
        lines += [f"- {m.upper()}: `{e}`" for m, e in failures]
    figs = meta.get("figures") or []
    if figs:
        lines += ["", "## Figures", ""] + [f"![{Path(f).stem}]({Path(f).name})" for f in figs]
    return "\n".join(lines) + "\n"


def _failure_table(rows: list[MethodRow]) -> list[str]:
    """Markdown lines: executions that failed, by kind, per method (nothing without sim)."""
    kinds = [k for k in FAILURE_KINDS if any((r.failures or {}).get(k) for r in rows)]
    if not any(r.failures is not None for r in rows):
        return []
    lines = ["", "## Executions that failed, by kind", "",
             "Counts over every executed prediction of the method's runs: reflex, tracking, "
             "unreachable and collision are commands the real Panda would refuse or could not "
             "follow; task: the task was not achieved (writing: the rollout stops once that is "
             "decided, so a later refusal is not counted). Each execution counts its first "
             "failure.", ""]
    if not kinds:
        return lines + ["No execution failed."]
    lines += ["| method | " + " | ".join(kinds) + " |", "|" + "---|" * (len(kinds) + 1)]
    for row in rows:
        f = row.failures
        cells = ["-" if f is None else str(f.get(k, 0)) for k in kinds]
        lines.append(f"| {row.method.upper()} | " + " | ".join(cells) + " |")
    return lines + _failed_check_table(rows)


def _failed_check_table(rows: list[MethodRow]) -> list[str]:
    """Markdown lines: the success checks behind the task failures, per method."""
    totals: dict[str, int] = {}
    for row in rows:
        for name, n in (row.failed_checks or {}).items():
            totals[name] = totals.get(name, 0) + n
    if not totals:
        return []
    names = sorted(totals, key=lambda k: (-totals[k], k))
    lines = ["", "### Task failures, by the check that failed", "",
             "How often each success check failed in the task failures above (an execution "
             "that fails two checks counts for both; the checks, their bounds and why: "
             "tasks/README.md). A run's page on the results site gives each failure in words.",
             "", "| method | " + " | ".join(names) + " |", "|" + "---|" * (len(names) + 1)]
    for row in rows:
        f = row.failed_checks
        cells = ["-" if f is None else str(f.get(k, 0)) for k in names]
        lines.append(f"| {row.method.upper()} | " + " | ".join(cells) + " |")
    return lines


def _csv(rows: list[MethodRow], paper: PaperRanking) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer)
    header = ["rank", "method", "runs_ok", "runs_failed"]
    for key, *_ in COLUMNS:
        header += [f"{key}_median", f"{key}_q1", f"{key}_q3"]
    header += ["paper_rank", "paper_cl_score"]  # empty when no paper table matches
    writer.writerow(header)
    for idx, row in enumerate(rows, 1):
        out: list[Any] = [idx, row.method, row.runs_ok, row.runs_failed]
        for key, *_ in COLUMNS:
            q1, q3 = row.iqr(key)
            out += [row.median(key), q1, q3]
        out += [paper.ranks.get(row.method.lower(), ""), paper.scores.get(row.method.lower(), "")]
        writer.writerow(["" if isinstance(v, float) and math.isnan(v) else v for v in out])
    return buffer.getvalue()


def _json_value(value: float) -> float | None:
    return None if math.isnan(value) else value


def write_tables(rows: list[MethodRow], out: Path, meta: dict[str, Any]) -> list[Path]:
    """Write ``leaderboard.md``, ``.csv`` and ``.json`` into ``out``; return their paths."""
    ranked = rank(rows)
    paper = paper_ranking(ranked, meta)
    if paper.label and any(row.values.get("exec_CL_score") for row in ranked):
        paper.executed = paper_ranking(ranked, meta, key="exec_CL_score")
    out.mkdir(parents=True, exist_ok=True)
    md, cs, js = out / "leaderboard.md", out / "leaderboard.csv", out / LEADERBOARD_JSON
    atomic_write_text(md, _markdown(ranked, meta, paper))
    atomic_write_text(cs, _csv(ranked, paper))
    payload = {
        "schema_version": _SCHEMA,
        "meta": meta,
        "paper": paper.to_dict(),
        "rows": [
            {
                "rank": idx,
                "method": row.method,
                "runs_ok": row.runs_ok,
                "runs_failed": row.runs_failed,
                "paper_rank": paper.ranks.get(row.method.lower()),
                "paper_cl_score": paper.scores.get(row.method.lower()),
                "errors": row.errors,
                "exec_failures": row.failures,
                "exec_failed_checks": row.failed_checks,
                "not_provided": sorted(row.not_provided),
                "metrics": {
                    key: {
                        "median": _json_value(row.median(key)),
                        "q1": _json_value(row.iqr(key)[0]),
                        "q3": _json_value(row.iqr(key)[1]),
                        "values": [v for v in row.values.get(key, []) if not math.isnan(v)],
                    }
                    for key, *_ in COLUMNS
                },
            }
            for idx, row in enumerate(ranked, 1)
        ],
    }
    atomic_write_json(js, payload)
    return [md, cs, js]


# ----------------------------------------------------------------------------- reading back
_RUN_IT = ("`clfd-bench leaderboard --dataset ... --out DIR` or `bash run.sh main` (which "
           "writes results/)")


def read_leaderboard(out: str | Path) -> dict[str, Any]:
    """The ``leaderboard.json`` a leaderboard wrote into ``out`` (see :func:`write_tables`).

    Raises:
        InputError: ``out`` is not a folder, has no ``leaderboard.json``, or holds one this
            version cannot read (the message says what to run).
    """
    import json

    from clfd_bench.harness.validate import InputError

    out = Path(out)
    path = out / LEADERBOARD_JSON
    if not out.is_dir():
        raise InputError(f"{out} is not a folder; give the output folder of {_RUN_IT}")
    if not path.is_file():
        raise InputError(f"{out} is not a results folder: it has no {LEADERBOARD_JSON}; "
                         f"make one with {_RUN_IT}")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise InputError(f"{path} is not valid JSON ({exc}); run the leaderboard again to "
                         "rewrite it") from None
    if (not isinstance(doc, dict) or doc.get("schema_version") != _SCHEMA
            or not isinstance(doc.get("rows"), list) or not isinstance(doc.get("meta"), dict)):
        raise InputError(f"{path} is not a leaderboard of schema {_SCHEMA} (rows, meta); run "
                         "the leaderboard again with this version to rewrite it")
    return doc


@dataclass(frozen=True)
class LeaderboardRun:
    """A run directory behind a leaderboard row.

    Attributes:
        label: the row (method or entry name, lower case as in ``--methods``).
        name: the run's name (its path below ``runs/``, or the included folder).
        path: the run directory.
        status: ``done``, ``failed``, ``partial`` or ``missing`` when the leaderboard was
            written; ``included`` for a run put in with ``--include``.
        seed, order: the grid point (None for an included run).
    """

    label: str
    name: str
    path: Path
    status: str
    seed: int | None = None
    order: int | None = None


def leaderboard_runs(out: str | Path, doc: dict[str, Any]) -> list[LeaderboardRun]:
    """The runs of a leaderboard read with :func:`read_leaderboard`, in its grid's order
    (method, order, seed), then the included ones. Run directories are found from the grid
    (:func:`clfd_bench.leaderboard.grid.make_grid`), as the leaderboard placed them."""
    from clfd_bench.leaderboard.grid import GridOptions, make_grid

    out = Path(out)
    meta = doc["meta"]
    statuses = meta.get("runs") or {}
    specs = make_grid(meta["dataset"], list(meta["methods"]), meta["profile"],
                      list(meta["seeds"]), list(meta["orders"]), GridOptions.from_meta(meta))
    runs = [LeaderboardRun(s.label, s.name, s.run_dir(out), str(statuses.get(s.name, "missing")),
                           s.seed, s.order) for s in specs]
    for inc in meta.get("included") or []:
        path = Path(inc["path"])
        runs.append(LeaderboardRun(str(inc["method"]), str(path), path, "included"))
    return runs


def leaderboard_figures(out: str | Path, doc: dict[str, Any]) -> list[Path]:
    """The leaderboard's figures that exist in ``out`` (found by file name: the paths in
    ``meta.figures`` are as the leaderboard was called, possibly relative to another folder)."""
    out = Path(out)
    found = [out / Path(f).name for f in doc["meta"].get("figures") or []]
    return [p for p in found if p.is_file()]


def paper_values(doc: dict[str, Any]) -> dict[str, dict[str, float]]:
    """The numbers of the paper's CL table matching the leaderboard (every column of
    :data:`clfd_bench.metrics.paper_numbers.CL_COLUMNS`), per method in lower case; empty
    when no paper table matches (``doc["paper"]["reason"]`` says why)."""
    from clfd_bench.metrics.paper_numbers import cl_table

    paper = doc.get("paper") or {}
    if not paper.get("table") or not paper.get("dataset") or not paper.get("variant"):
        return {}
    table = cl_table(paper["dataset"], paper["variant"])
    return {m.lower(): dict(values) for m, values in table.items()}
