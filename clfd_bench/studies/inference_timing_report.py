"""Inference timing of the hypernetwork methods (HN, CHN): the report. The measured cells
(:func:`~clfd_bench.studies.inference_timing_measure.measure_part`) next to the paper's
(:func:`clfd_bench.metrics.paper_numbers.inference`) with the ratio ours / paper per cell
(> 1: slower than the paper), as a markdown table, CSV, JSON, a one-paragraph summary and a
bar plot per device (:func:`write_outputs`).
"""

from __future__ import annotations

import csv
import io
import statistics
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.io import atomic_write_json, atomic_write_text
from clfd_bench.studies.inference_timing_measure import METHODS, PART_LABELS, QUANTITIES

__all__ = [
    "comparison_rows",
    "paper_device",
    "plot_comparison",
    "ratio",
    "summary",
    "to_csv",
    "to_markdown",
    "write_outputs",
]

QUANTITY_TITLES = {
    "generate": r"$f_h \rightarrow f_\theta$ (generate the NODE)",
    "step": r"$f_\theta(x)$ (one NODE step)",
    "integrate": r"$\int f_\theta\,d\tau$ (1000-step trajectory)",
}


# -- the comparison table -----------------------------------------------------------------
def paper_device(device: str) -> str:
    """The paper's table for a torch device type: ``cpu`` -> ``cpu``, ``cuda`` -> ``gpu``."""
    return "gpu" if device == "cuda" else "cpu"


def ratio(ours: float | None, paper: float | None) -> float | None:
    """``ours / paper`` (None when either is missing or the paper's value is 0)."""
    if ours is None or paper is None or paper == 0:
        return None
    return float(ours) / float(paper)


def comparison_rows(
    cells: Iterable[Mapping[str, Any]],
    device: str,
    paper: Mapping[tuple[str, str], Mapping[str, float]] | None = None,
) -> list[dict[str, Any]]:
    """Our cells for ``device`` next to the paper's numbers, in the paper's row order.

    Args:
        cells: measured cells (:func:`measure_part`); those of other devices are ignored.
        device: ``cpu`` or ``cuda``.
        paper: ``{(label, METHOD): {generate_ms, ...}}``; default: the paper's table for
            the device (:func:`clfd_bench.metrics.paper_numbers.inference`).

    Returns:
        One row per measured (label, method): ``dataset``, ``method``, per quantity ``q``:
        ``q_ms``, ``q_hz``, ``q_iqr_ms``, ``paper_q_ms``, ``paper_q_hz``, ``ratio_q``
        (ours / paper ms), and ``nfe``.
    """
    if paper is None:
        from clfd_bench.metrics.paper_numbers import inference

        paper = inference(paper_device(device))
    by_key = {(c["label"], c["method"]): c for c in cells if c["device"] == device}
    order = [(label, m.upper()) for label in PART_LABELS.values() for m in METHODS]
    extra = sorted(k for k in by_key if k not in order)
    rows = []
    for key in order + extra:
        cell = by_key.get(key)
        if cell is None:
            continue
        ref = paper.get(key, {})
        row: dict[str, Any] = {"dataset": key[0], "method": key[1]}
        for q in QUANTITIES:
            row[f"{q}_ms"] = cell[f"{q}_ms"]
            row[f"{q}_hz"] = cell[f"{q}_hz"]
            row[f"{q}_iqr_ms"] = cell.get(f"{q}_iqr_ms")
            row[f"paper_{q}_ms"] = ref.get(f"{q}_ms")
            row[f"paper_{q}_hz"] = ref.get(f"{q}_hz")
            row[f"ratio_{q}"] = ratio(cell[f"{q}_ms"], ref.get(f"{q}_ms"))
        row["nfe"] = cell.get("nfe")
        rows.append(row)
    return rows


def _fmt(value: float | None) -> str:
    """Two decimals like the paper; three significant digits below 1."""
    if value is None:
        return "—"
    return f"{value:.3g}" if abs(value) < 1 else f"{value:.2f}"


def to_markdown(rows: Sequence[Mapping[str, Any]], device: str) -> str:
    """A markdown table like the paper's, ours | paper | ratio per quantity."""
    head = ["Dataset", "Method"]
    for sym in ("f_h→f_θ", "f_θ(x)", "∫f_θ"):
        head += [f"{sym} ms", f"{sym} Hz", "paper ms", "paper Hz", "ours/paper"]
    head.append("NFE")
    lines = [
        f"Inference timing on {device.upper()} (median ms and Hz; paper: "
        f"{'GPU' if device == 'cuda' else 'CPU'} table; ratio = our ms / paper ms)",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "|".join(["---"] * 2 + ["---:"] * (len(head) - 2)) + "|",
    ]
    for r in rows:
        cells = [r["dataset"], r["method"]]
        for q in QUANTITIES:
            cells += [_fmt(r[f"{q}_ms"]), _fmt(r[f"{q}_hz"]), _fmt(r[f"paper_{q}_ms"]),
                      _fmt(r[f"paper_{q}_hz"]), _fmt(r[f"ratio_{q}"])]
        cells.append(str(r.get("nfe", "")))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


CSV_COLUMNS = ("device", "dataset", "method") + tuple(
    f"{p}{q}_{u}" for q in QUANTITIES for p in ("", "paper_") for u in ("ms", "hz")
) + tuple(f"ratio_{q}" for q in QUANTITIES) + tuple(f"{q}_iqr_ms" for q in QUANTITIES) + (
    "nfe",)


def to_csv(rows_by_device: Mapping[str, Sequence[Mapping[str, Any]]]) -> str:
    """All devices' comparison rows as CSV (columns :data:`CSV_COLUMNS`)."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(CSV_COLUMNS), lineterminator="\n")
    writer.writeheader()
    for device, rows in rows_by_device.items():
        for r in rows:
            writer.writerow({"device": device, **{k: r.get(k) for k in CSV_COLUMNS[1:]}})
    return buf.getvalue()


def plot_comparison(rows: Sequence[Mapping[str, Any]], device: str, path: Path) -> Path | None:
    """Grouped bars (ours vs the paper, log scale), one panel per quantity -> ``path``."""
    from clfd_bench.leaderboard.plots import _plt, _save

    if not rows:
        return None
    plt = _plt()
    fig, axes = plt.subplots(1, len(QUANTITIES), figsize=(5.2 * len(QUANTITIES), 4.6))
    labels = [f"{r['dataset']}\n{r['method']}" for r in rows]
    x = np.arange(len(rows))
    width = 0.4
    paper_name = "paper (GPU)" if device == "cuda" else "paper (CPU)"
    for ax, q in zip(axes, QUANTITIES, strict=True):
        ours = [r[f"{q}_ms"] for r in rows]
        ref = [r[f"paper_{q}_ms"] if r[f"paper_{q}_ms"] is not None else np.nan for r in rows]
        ax.bar(x - width / 2, ours, width, label=f"ours ({device.upper()})", color="tab:blue")
        ax.bar(x + width / 2, ref, width, label=paper_name, color="tab:gray")
        ax.set_yscale("log")
        for xi, a, b in zip(x, ours, ref, strict=True):
            if np.isfinite(b) and b > 0:
                ax.annotate(f"×{a / b:.2g}", (xi, max(a, b)), textcoords="offset points",
                            xytext=(0, 2), ha="center", fontsize=7)
        ax.set_xticks(x, labels, rotation=60, ha="right", fontsize=7)
        ax.set_ylabel("median time [ms] (log)")
        ax.set_title(QUANTITY_TITLES[q], fontsize=10)
        ax.grid(axis="y", which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Inference speed of the hypernetwork methods: ours vs the paper")
    fig.tight_layout()
    path = _save(fig, Path(path))
    plt.close(fig)
    return path


def summary(rows: Sequence[Mapping[str, Any]], device: str, machine: Mapping[str, Any]) -> str:
    """One paragraph: ranges of our medians, the paper's, and the median ratio per quantity."""
    if not rows:
        return f"no {device} cells were measured"

    def span(values: Sequence[float]) -> str:
        lo, hi = min(values), max(values)
        return f"{lo:.3g}" if lo == hi else f"{lo:.3g}–{hi:.3g}"

    parts = []
    for q, name in (("generate", "generating a NODE"), ("step", "one NODE step"),
                    ("integrate", "a 1000-step trajectory")):
        ours = [r[f"{q}_ms"] for r in rows]
        ref = [r[f"paper_{q}_ms"] for r in rows if r[f"paper_{q}_ms"] is not None]
        ratios = [r[f"ratio_{q}"] for r in rows if r[f"ratio_{q}"] is not None]
        text = f"{name} took {span(ours)} ms"
        if ref:
            text += (f" (paper {span(ref)} ms; median ratio ours/paper "
                     f"{statistics.median(ratios):.2f})")
        parts.append(text)
    nfe = [r["nfe"] for r in rows if r.get("nfe")]
    where = (f"{machine.get('gpu')}" if device == "cuda" else
             f"{machine.get('cpu')}, torch threads: {machine.get('torch_threads')}")
    return (
        f"On {device.upper()} ({where}; torch {machine.get('torch')}; a shared machine), "
        + "; ".join(parts)
        + (f". The integrations needed {span(nfe)} vector-field evaluations each."
           if nfe else ".")
    )


def write_outputs(
    out: Path, cells: Sequence[Mapping[str, Any]], machine: Mapping[str, Any],
    settings: Mapping[str, Any],
) -> tuple[dict[str, list[dict[str, Any]]], list[Path]]:
    """Write ``timing.md``, ``timing.csv``, ``timing.json`` and ``timing_{device}.png``."""
    devices = [d for d in ("cpu", "cuda") if any(c["device"] == d for c in cells)]
    rows = {d: comparison_rows(cells, d) for d in devices}
    files: list[Path] = []
    md = ["# Inference timing (HN, CHN)", ""]
    md.append("Machine: " + ", ".join(f"{k} = {v}" for k, v in machine.items()
                                      if k != "load_average_1_5_15min")
              + ". The load average (1, 5, 15 min) after each cell's measurement is in "
              "timing.json (`cells[].load_average_after`); timings on a shared machine vary.")
    md.append("")
    md.append("Settings: " + ", ".join(f"{k} = {v}" for k, v in settings.items()) + ".")
    md.append("")
    for d in devices:
        md += [to_markdown(rows[d], d), summary(rows[d], d, machine), ""]
    atomic_write_text(out / "timing.md", "\n".join(md))
    atomic_write_text(out / "timing.csv", to_csv(rows))
    atomic_write_json(out / "timing.json", {
        "machine": dict(machine), "settings": dict(settings), "rows": rows,
        "cells": [{k: v for k, v in c.items() if k != "samples"} for c in cells],
    })
    files += [out / "timing.md", out / "timing.csv", out / "timing.json"]
    for d in devices:
        png = plot_comparison(rows[d], d, out / f"timing_{d}.png")
        if png is not None:
            files.append(png)
    return rows, files
