"""Tables and the figure of the start-position study (:mod:`clfd_bench.studies.start_robustness`).

Tables report distances in centimetres (as the paper's figure); records stay in metres.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.io import atomic_write_json, atomic_write_text
from clfd_bench.studies.start_robustness import (
    BINS_CM,
    LARGE_M,
    REFERENCE,
    SETTLE_M,
    StartRecord,
)

__all__ = ["bin_labels", "plot_overview", "plot_settling", "plot_study", "summarize",
           "write_records", "write_summary"]

_LARGE_CM = LARGE_M * 100.0
_BAND_TOP_CM = _LARGE_CM * 1.2  # the "Large" band spans 100..120 cm in the plots


def bin_labels() -> list[str]:
    """``["0-5", "5-10", ...]`` (cm)."""
    return [f"{a:g}-{b:g}" for a, b in zip(BINS_CM[:-1], BINS_CM[1:], strict=True)]


def _bin(start_cm: float) -> int:
    """Index of the start-Δ bin (the last bin includes its upper edge)."""
    i = int(np.searchsorted(BINS_CM, start_cm, side="right")) - 1
    return min(max(i, 0), len(BINS_CM) - 2)


def _finite_or_none(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def summarize(records: list[StartRecord], methods: list[str],
              tasks: list[str]) -> list[dict[str, Any]]:
    """One row per (method, task): ``n``, ``median_end_cm``, ``large_frac``,
    ``settled_frac`` (share of starts that settled within :data:`SETTLE_M` of the goal),
    ``median_settle`` and ``max_settle`` (when they settled, multiples of the demo's duration;
    ``inf`` when half / any did not), ``median_end_cm_<bin>``, ``success_rate`` (None when not
    executed), ``success_rate_<bin>``, ``ref_end_cm`` and ``ref_success`` (from the demo's own
    start). Medians may be ``inf`` (more than half diverged)."""
    rows = []
    for m in methods:
        for t in tasks:
            recs = [r for r in records if r.method == m and r.task == t]
            ref = next((r for r in recs if r.start_index == REFERENCE), None)
            sample = [r for r in recs if r.start_index != REFERENCE]
            if not sample:
                continue
            ends = [r.end_delta_m * 100.0 for r in sample]
            executed = [r for r in sample if r.success is not None]
            row: dict[str, Any] = {
                "method": m, "task": t, "demo": sample[0].demo, "n": len(sample),
                "median_end_cm": _median(ends),
                "large_frac": float(np.mean([r.large for r in sample])),
                "settled_frac": float(np.mean([math.isfinite(r.settle_time) for r in sample])),
                "median_settle": _median([r.settle_time for r in sample]),
                "max_settle": float(max(r.settle_time for r in sample)),
                "success_rate": (float(np.mean([r.success for r in executed]))
                                 if executed else None),
            }
            for b, label in enumerate(bin_labels()):
                in_bin = [r for r in sample if _bin(r.start_delta_m * 100.0) == b]
                row[f"median_end_cm_{label}"] = _median([r.end_delta_m * 100 for r in in_bin])
                ex = [r.success for r in in_bin if r.success is not None]
                row[f"success_rate_{label}"] = float(np.mean(ex)) if ex else None
                row[f"n_{label}"] = len(in_bin)
            row["ref_end_cm"] = ref.end_delta_m * 100.0 if ref else None
            row["ref_success"] = ref.success if ref else None
            rows.append(row)
    return rows


_RECORD_COLS = ("method", "task", "demo", "start_index", "start_delta_m", "end_delta_m", "large",
                "settle_time", "success", "failure", "approach_steps", "max_tracking_error_m")


def write_records(records: list[StartRecord], out: Path) -> list[Path]:
    """``records.csv`` and ``records.json`` (end Δ ``inf`` in csv, null in json = diverged;
    the json has the start pose and the env's final task quantities too)."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(_RECORD_COLS)
    for r in records:
        w.writerow([getattr(r, c) for c in _RECORD_COLS])
    atomic_write_text(out / "records.csv", buf.getvalue())
    atomic_write_json(out / "records.json", [r.to_json() for r in records])
    return [out / "records.csv", out / "records.json"]


def _fmt(x: Any, pct: bool = False) -> str:
    if x is None:
        return "–"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, float):
        if not math.isfinite(x):
            return "inf"
        return f"{100 * x:.0f} %" if pct else f"{x:.1f}"
    return str(x)


def _fmt_times(x: float | None) -> str:
    """A settle time in multiples of the demo's duration (``–`` when it did not settle)."""
    return "–" if x is None or not math.isfinite(x) else f"{x:.2g}x"


def summary_markdown(rows: list[dict[str, Any]]) -> str:
    """The summary as a markdown table (end Δ in cm; n = starts in the bin; settled: within
    :data:`SETTLE_M` of the goal from then on, times in multiples of the demo's duration)."""
    labels = bin_labels()
    tol = f"{SETTLE_M * 100:g} cm"
    head = (["method", "task", "demo", "median end Δ", "Large (>100 cm)",
             f"settled within {tol}", "settled after (median / slowest)"]
            + [f"median end Δ, start {lb} cm" for lb in labels]
            + ["sim success"] + [f"success, start {lb} cm" for lb in labels]
            + ["end Δ from demo start", "success from demo start"])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = ([r["method"], r["task"], str(r["demo"]), _fmt(r["median_end_cm"]),
                  _fmt(r["large_frac"], pct=True), _fmt(r["settled_frac"], pct=True),
                  f"{_fmt_times(r['median_settle'])} / {_fmt_times(r['max_settle'])}"]
                 + [f"{_fmt(r[f'median_end_cm_{lb}'])} (n={r[f'n_{lb}']})" for lb in labels]
                 + [_fmt(r["success_rate"], pct=True)]
                 + [_fmt(r[f"success_rate_{lb}"], pct=True) for lb in labels]
                 + [_fmt(r["ref_end_cm"]), _fmt(r["ref_success"])])
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def write_summary(rows: list[dict[str, Any]], out: Path) -> list[Path]:
    """``summary.md``, ``summary.csv``, ``summary.json`` (inf medians: ``inf`` / null)."""
    atomic_write_text(out / "summary.md", summary_markdown(rows))
    cols = list(rows[0]) if rows else []
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(cols)
    for r in rows:
        w.writerow([r[c] for c in cols])
    atomic_write_text(out / "summary.csv", buf.getvalue())
    atomic_write_json(out / "summary.json", [
        {k: (_finite_or_none(v) if isinstance(v, float) else v) for k, v in r.items()}
        for r in rows])
    return [out / "summary.md", out / "summary.csv", out / "summary.json"]


# --------------------------------------------------------------------------- figure
def _clip_cm(end_m: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """End Δ in cm, values above the Large threshold spread inside the band (100..120 cm)."""
    cm = np.asarray(end_m, dtype=float) * 100.0
    large = ~(cm <= _LARGE_CM)
    cm[large] = _LARGE_CM + rng.uniform(0.1, 0.9, large.sum()) * (_BAND_TOP_CM - _LARGE_CM)
    return cm


def _band(ax, horizontal: bool = True) -> None:
    ax.axhspan(_LARGE_CM, _BAND_TOP_CM, color="0.85", zorder=0)
    ax.text(0.99, (_LARGE_CM + _BAND_TOP_CM) / 2, "Large", transform=ax.get_yaxis_transform(),
            ha="right", va="center", fontsize=7, color="0.3")
    ax.set_ylim(0, _BAND_TOP_CM)


def plot_study(records: list[StartRecord], methods: list[str], tasks: list[str],
               path: Path) -> Path | None:
    """The paper-like figure: one row per task, columns (a) end Δ vs start Δ scatter,
    (b) end Δ per start-Δ bin (box; × = end Δ from the demo's own start), (c) every end Δ per
    method (box + violin), (d) simulated success rate per start-Δ bin (× = from the demo's
    start). End Δ above 100 cm are drawn inside the grey "Large" band."""
    from clfd_bench.leaderboard.plots import _plt, _save

    if not records or not tasks:
        return None
    plt = _plt()
    rng = np.random.default_rng(0)
    colors = {m: f"C{i}" for i, m in enumerate(methods)}
    labels = bin_labels()
    nb = len(labels)
    width = 0.8 / max(1, len(methods))
    fig, axes = plt.subplots(len(tasks), 4, figsize=(17, 3.2 * len(tasks)), squeeze=False)
    for row, task in zip(axes, tasks, strict=True):
        ax_a, ax_b, ax_c, ax_d = row
        for k, m in enumerate(methods):
            recs = [r for r in records if r.method == m and r.task == task]
            sample = [r for r in recs if r.start_index != REFERENCE]
            ref = next((r for r in recs if r.start_index == REFERENCE), None)
            if not sample:
                continue
            c = colors[m]
            start_cm = np.array([r.start_delta_m for r in sample]) * 100.0
            end_cm = _clip_cm(np.array([r.end_delta_m for r in sample]), rng)
            ax_a.scatter(start_cm, end_cm, s=10, color=c, alpha=0.7, label=m)
            bins = np.array([_bin(s) for s in start_cm])
            off = (k - (len(methods) - 1) / 2) * width
            data = [end_cm[bins == b] for b in range(nb)]
            pos = [b + off for b in range(nb) if len(data[b])]
            bp = ax_b.boxplot([d for d in data if len(d)], positions=pos, widths=width * 0.9,
                              patch_artist=True, showfliers=True, flierprops={"ms": 2})
            for patch in bp["boxes"]:
                patch.set_facecolor(c)
                patch.set_alpha(0.5)
            if ref is not None:
                ax_b.scatter([-0.6 + off], _clip_cm(np.array([ref.end_delta_m]), rng), marker="x",
                             s=40, color=c, zorder=5)
            vp = ax_c.violinplot([end_cm], positions=[k], showmedians=True, widths=0.8)
            for body in vp["bodies"]:
                body.set_facecolor(c)
            ax_c.text(k, _BAND_TOP_CM * 0.97, f"Large {np.mean([r.large for r in sample]):.0%}",
                      ha="center", va="top", fontsize=7)
            ex = [(b, r.success) for b, r in zip(bins, sample, strict=True)
                  if r.success is not None]
            if ex:
                rates = [np.mean([s for b2, s in ex if b2 == b]) if any(b2 == b for b2, _ in ex)
                         else np.nan for b in range(nb)]
                ax_d.bar(np.arange(nb) + off, rates, width=width * 0.9, color=c, alpha=0.7,
                         label=m)
                if ref is not None and ref.success is not None:
                    ax_d.scatter([-0.6 + off], [float(ref.success)], marker="x", s=40, color=c,
                                 zorder=5)
        for ax in (ax_a, ax_b, ax_c):
            _band(ax)
            ax.set_ylabel("end Δ [cm]")
        ax_a.set_title(f"{task}: (a) end Δ vs start Δ", fontsize=9)
        ax_a.set_xlabel("start Δ [cm]")
        ax_a.set_xlim(0, BINS_CM[-1])
        if ax_a.get_legend_handles_labels()[0]:
            ax_a.legend(fontsize=7, loc="upper left")
        ax_b.set_title("(b) by start Δ (× = demo start)", fontsize=9)
        ax_b.set_xticks([-0.6, *range(nb)], ["0", *labels], fontsize=7)
        ax_b.set_xlabel("start Δ [cm]")
        ax_c.set_title("(c) all starts", fontsize=9)
        ax_c.set_xticks(range(len(methods)), methods)
        ax_d.set_title("(d) sim success (× = demo start)", fontsize=9)
        ax_d.set_xticks([-0.6, *range(nb)], ["0", *labels], fontsize=7)
        ax_d.set_xlabel("start Δ [cm]")
        ax_d.set_ylim(0, 1.05)
        ax_d.set_ylabel("success rate")
    fig.tight_layout()
    out = _save(fig, Path(path))
    plt.close(fig)
    return out


def plot_overview(records: list[StartRecord], methods: list[str], tasks: list[str],
                  path: Path, goal_cm: float = 1.0) -> Path | None:
    """Every task in one panel: per task and method, the end Δ of all starts (box, log
    scale; diverged and Large ones at the top, in the grey band), a dashed line at
    ``goal_cm``, and per method the share of starts that end within it (legend)."""
    from clfd_bench.leaderboard.plots import _plt, _save

    if not records or not tasks:
        return None
    plt = _plt()
    width = 0.8 / max(1, len(methods))
    fig, ax = plt.subplots(figsize=(max(6.0, 0.45 * len(tasks) * max(1, len(methods)) + 2), 4.2))
    top = _BAND_TOP_CM
    for k, m in enumerate(methods):
        sample = [r for r in records if r.method == m and r.start_index != REFERENCE
                  and r.task in tasks]
        if not sample:
            continue
        within = np.mean([r.end_delta_m * 100.0 <= goal_cm for r in sample])
        data, pos = [], []
        for i, task in enumerate(tasks):
            cm = np.array([r.end_delta_m for r in sample if r.task == task]) * 100.0
            if len(cm):
                data.append(np.clip(np.where(np.isfinite(cm), cm, top), 1e-3, top))
                pos.append(i + (k - (len(methods) - 1) / 2) * width)
        bp = ax.boxplot(data, positions=pos, widths=width * 0.85, patch_artist=True,
                        showfliers=True, flierprops={"ms": 2})
        for patch in bp["boxes"]:
            patch.set_facecolor(f"C{k}")
            patch.set_alpha(0.6)
        bp["boxes"][0].set_label(f"{m}: {within:.0%} of starts end within {goal_cm:g} cm")
    ax.set_yscale("log")
    ax.axhline(goal_cm, color="k", ls="--", lw=0.8)
    ax.axhspan(_LARGE_CM, top, color="0.85", zorder=0)
    ax.set_ylim(1e-3, top)
    ax.set_xticks(range(len(tasks)), tasks, rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("end Δ to the goal [cm]")
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    out = _save(fig, Path(path))
    plt.close(fig)
    return out


def _settled_share(settle: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """``[G]``: the share of the settle times ``settle: [N]`` at or before each ``grid`` time."""
    return (settle[None, :] <= grid[:, None]).mean(axis=1)


def plot_settling(records: list[StartRecord], methods: list[str], tasks: list[str],
                  path: Path, horizon: float | None = None) -> Path | None:
    """How fast predictions converge: per method (one panel), the share of starts settled
    within :data:`SETTLE_M` of the goal against time (multiples of the demo's duration, up to
    ``horizon``, default the slowest settle time), one thin line per task and a thick one over
    all tasks."""
    from clfd_bench.leaderboard.plots import _plt, _save

    recs = [r for r in records if r.start_index != REFERENCE and r.task in tasks]
    if not recs:
        return None
    plt = _plt()
    finite = [r.settle_time for r in recs if math.isfinite(r.settle_time)]
    horizon = horizon or max([1.0, *finite])
    grid = np.linspace(0.0, horizon, 400)
    fig, axes = plt.subplots(1, len(methods), figsize=(4.2 * len(methods), 3.4),
                             squeeze=False, sharey=True)
    for ax, m in zip(axes[0], methods, strict=True):
        mine = [r for r in recs if r.method == m]
        for task in tasks:
            t = np.array([r.settle_time for r in mine if r.task == task])
            if len(t):
                ax.plot(grid, _settled_share(t, grid), lw=0.6, alpha=0.5)
        t = np.array([r.settle_time for r in mine])
        if len(t):
            ax.plot(grid, _settled_share(t, grid), color="k", lw=2.0,
                    label=f"all tasks: {np.isfinite(t).mean():.0%} settled")
            ax.legend(fontsize=7, loc="lower right")
        ax.set_title(m, fontsize=9)
        ax.set_xlabel("time [x the demo's duration]")
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(f"starts within {SETTLE_M * 100:g} cm of the goal for good")
    fig.tight_layout()
    out = _save(fig, Path(path))
    plt.close(fig)
    return out
