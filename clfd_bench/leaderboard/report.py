"""Leaderboard tables: Markdown, CSV and JSON, written atomically."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

from clfd_bench.execution.execute import FAILURE_KINDS
from clfd_bench.io import atomic_write_json, atomic_write_text
from clfd_bench.leaderboard.aggregate import CRITERIA, MethodRow

__all__ = ["COLUMNS", "rank", "write_tables"]

COLUMNS: tuple[tuple[str, str], ...] = (
    ("CL_score", "CL_score"),
    ("CL_stability", "CL_stab"),
    *((k, k) for k in CRITERIA),
    ("BWT", "BWT"),
    ("exec_ACC", "exec ACC"),
    ("exec_REM", "exec REM"),
    ("exec_BWT", "exec BWT"),
    ("train_time_s", "train s"),
    ("final_params", "params"),
)
"""(key in MethodRow.values, column header), in table order."""


def _fmt(value: float, key: str) -> str:
    if math.isnan(value):
        return "-"
    if key == "final_params":
        return f"{value:,.0f}"
    if key == "train_time_s":
        return f"{value:.0f}"
    return f"{value:.2f}"


def rank(rows: list[MethodRow]) -> list[MethodRow]:
    """Rows by median CL_score (trajectory-based), best first; rows without runs last."""

    def key(row: MethodRow) -> tuple[int, float]:
        score = row.median("CL_score")
        if math.isnan(score):
            score = row.median("ACC")
        return (0 if row.runs_ok else 1, -(score if not math.isnan(score) else -1.0))

    return sorted(rows, key=key)


def _cell(row: MethodRow, key: str) -> str:
    med = row.median(key)
    if math.isnan(med):
        return "-"
    q1, q3 = row.iqr(key)
    if len(row.values.get(key, [])) > 1 and (q3 - q1) > 0:
        return f"{_fmt(med, key)} [{_fmt(q1, key)}, {_fmt(q3, key)}]"
    return _fmt(med, key)


def _markdown(rows: list[MethodRow], meta: dict[str, Any]) -> str:
    head = ["#", "method", "runs", *[h for _, h in COLUMNS]]
    lines = [
        f"# Leaderboard: {meta['dataset']} ({meta['profile']} profile)",
        "",
        f"Grid: methods {', '.join(meta['methods'])}; seeds {meta['seeds']}; orders "
        f"{meta['orders']}; NODE^{meta['node'].upper()}"
        + (f"; first {meta['tasks']} tasks" if meta.get("tasks") else "")
        + ("; with simulated execution" if meta.get("sim") else "; no simulation")
        + ".",
        "Cells: median [IQR] over runs. ACC, REM, BWT: trajectory accuracy (DTW under the "
        "paper's threshold); exec ACC/REM/BWT: the same from executing predictions in "
        "simulation. CL_score/CL_stability over ACC, REM, MS, TE, FS, SSS (FS across the "
        "methods compared here).",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for idx, row in enumerate(rows, 1):
        runs = f"{row.runs_ok}" + (f" (+{row.runs_failed} failed)" if row.runs_failed else "")
        cells = [str(idx), row.method.upper(), runs, *[_cell(row, k) for k, _ in COLUMNS]]
        lines.append("| " + " | ".join(cells) + " |")
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
             "follow; task: executed to the end, but the task was not achieved.", ""]
    if not kinds:
        return lines + ["No execution failed."]
    lines += ["| method | " + " | ".join(kinds) + " |", "|" + "---|" * (len(kinds) + 1)]
    for row in rows:
        f = row.failures
        cells = ["-" if f is None else str(f.get(k, 0)) for k in kinds]
        lines.append(f"| {row.method.upper()} | " + " | ".join(cells) + " |")
    return lines


def _csv(rows: list[MethodRow]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer)
    header = ["rank", "method", "runs_ok", "runs_failed"]
    for key, _ in COLUMNS:
        header += [f"{key}_median", f"{key}_q1", f"{key}_q3"]
    writer.writerow(header)
    for idx, row in enumerate(rows, 1):
        out: list[Any] = [idx, row.method, row.runs_ok, row.runs_failed]
        for key, _ in COLUMNS:
            q1, q3 = row.iqr(key)
            out += [row.median(key), q1, q3]
        writer.writerow(["" if isinstance(v, float) and math.isnan(v) else v for v in out])
    return buffer.getvalue()


def _json_value(value: float) -> float | None:
    return None if math.isnan(value) else value


def write_tables(rows: list[MethodRow], out: Path, meta: dict[str, Any]) -> list[Path]:
    """Write ``leaderboard.md``, ``.csv`` and ``.json`` into ``out``; return their paths."""
    ranked = rank(rows)
    out.mkdir(parents=True, exist_ok=True)
    md, cs, js = out / "leaderboard.md", out / "leaderboard.csv", out / "leaderboard.json"
    atomic_write_text(md, _markdown(ranked, meta))
    atomic_write_text(cs, _csv(ranked))
    payload = {
        "schema_version": 1,
        "meta": meta,
        "rows": [
            {
                "rank": idx,
                "method": row.method,
                "runs_ok": row.runs_ok,
                "runs_failed": row.runs_failed,
                "errors": row.errors,
                "exec_failures": row.failures,
                "metrics": {
                    key: {
                        "median": _json_value(row.median(key)),
                        "q1": _json_value(row.iqr(key)[0]),
                        "q3": _json_value(row.iqr(key)[1]),
                        "values": [v for v in row.values.get(key, []) if not math.isnan(v)],
                    }
                    for key, _ in COLUMNS
                },
            }
            for idx, row in enumerate(ranked, 1)
        ],
    }
    atomic_write_json(js, payload)
    return [md, cs, js]
