"""Leaderboard figures (PNG, matplotlib's Agg backend, no display needed).

* error vs current task: after learning task i, the errors of every task seen so far, over
  all runs of a method: median line and IQR band, as in the paper's figures;
* box plots of every error after the last task, per method;
* radar charts of the six CL criteria, one polygon per method (medians over runs);
* execution success vs current task: mean simulated success over the tasks seen so far.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from clfd_bench.leaderboard.aggregate import CRITERIA, MethodRow, RunRecord, error_metric_for

__all__ = ["plot_all"]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _done(records: list[RunRecord], method: str) -> list[dict]:
    return [
        r.results
        for r in records
        if r.spec.label == method and r.status == "done" and r.results is not None
    ]


def _errors_after(results: dict, metric: str, i: int) -> list[float]:
    rows = results["errors"][metric][i]
    return [float(e) for j, demos in enumerate(rows[: i + 1]) for e in demos if e is not None]


def _num_tasks(records: list[RunRecord]) -> int:
    counts = [len(r.results["tasks"]) for r in records if r.results and r.status == "done"]
    return max(counts) if counts else 0


def _first_results(records: list[RunRecord]) -> dict | None:
    return next((r.results for r in records if r.results and r.status == "done"), None)


def _unit(records: list[RunRecord], metric: str | None) -> str:
    res = _first_results(records)
    unit = (res or {}).get("units", {}).get(metric or "dtw")
    return f" [{unit}]" if unit else ""


def _threshold_line(ax, records: list[RunRecord], metric: str | None) -> None:
    res = _first_results(records)
    thr = (res or {}).get("thresholds", {}).get(metric or "dtw")
    if thr:
        ax.axhline(thr, color="k", ls="--", lw=1, label=f"accuracy threshold ({thr:g})")


def _median_band(ax, label: str, samples: dict[int, list[float]]) -> None:
    """Plot the median of each x's samples as a line and their IQR as a band."""
    xs = [x for x, vals in samples.items() if vals]
    if not xs:
        return
    q1, q2, q3 = np.array([np.percentile(samples[x], [25, 50, 75]) for x in xs]).T
    line = ax.plot(xs, q2, marker="o", ms=3, label=label)[0]
    ax.fill_between(xs, q1, q3, color=line.get_color(), alpha=0.2)


def _save(fig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=120, bbox_inches="tight")
    tmp.replace(path)
    return path


def plot_error_vs_task(records, methods, out: Path, title: str) -> Path | None:
    plt = _plt()
    m_tasks = _num_tasks(records)
    if m_tasks == 0:
        return None
    fig, ax = plt.subplots(figsize=(7, 4))
    metric = None
    for method in methods:
        runs = _done(records, method)
        if not runs:
            continue
        metric = metric or error_metric_for(runs[0])
        samples = {
            i: [e for res in runs if i < len(res["tasks"]) for e in _errors_after(res, metric, i)]
            for i in range(m_tasks)
        }
        _median_band(ax, method.upper(), samples)
    _threshold_line(ax, records, metric)
    ax.set_yscale("log")
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.set_xlabel("current task (index of the task just learned)")
    ax.set_ylabel(f"{(metric or 'dtw').upper()} of all seen tasks{_unit(records, metric)}")
    ax.set_title(f"{title}: error vs current task (median, IQR)")
    ax.legend(ncol=4, fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, out / "error_vs_task.png")


def plot_error_boxes(records, methods, out: Path, title: str) -> Path | None:
    plt = _plt()
    data, labels, metric = [], [], None
    for method in methods:
        runs = _done(records, method)
        if not runs:
            continue
        metric = metric or error_metric_for(runs[0])
        errs = [e for res in runs for e in _errors_after(res, metric, len(res["tasks"]) - 1)]
        data.append(errs)
        labels.append(method.upper())
    if not data:
        return None
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.boxplot(data, tick_labels=labels, showfliers=True)
    _threshold_line(ax, records, metric)
    ax.set_yscale("log")
    ax.set_ylabel(f"{(metric or 'dtw').upper()} after the last task{_unit(records, metric)}")
    ax.set_title(f"{title}: all errors after the last task")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    return _save(fig, out / "error_boxes.png")


def plot_radar(rows: list[MethodRow], out: Path, title: str) -> Path | None:
    plt = _plt()
    # A row with criteria its runs did not provide (predictions scored elsewhere) is left
    # out rather than drawn with made-up zeros.
    rows = [r for r in rows if r.runs_ok and not r.not_provided & set(CRITERIA)]
    if not rows:
        return None
    angles = np.linspace(0, 2 * np.pi, len(CRITERIA), endpoint=False)
    fig, ax = plt.subplots(figsize=(5.5, 5.5), subplot_kw={"projection": "polar"})
    for row in rows:
        vals = np.array([row.median(k) for k in CRITERIA])
        vals = np.nan_to_num(vals, nan=0.0)
        ax.plot(np.append(angles, angles[0]), np.append(vals, vals[0]), label=row.method.upper())
        ax.fill(np.append(angles, angles[0]), np.append(vals, vals[0]), alpha=0.08)
    ax.set_xticks(angles)
    ax.set_xticklabels(CRITERIA)
    ax.set_ylim(0, 1)
    ax.set_title(f"{title}: CL criteria (median over runs; 1 best)", pad=18)
    ax.legend(loc="upper right", bbox_to_anchor=(1.3, 1.1), fontsize=8)
    return _save(fig, out / "cl_radar.png")


def plot_success_vs_task(records, methods, out: Path, title: str) -> Path | None:
    plt = _plt()
    m_tasks = _num_tasks(records)
    fig, ax = plt.subplots(figsize=(7, 4))
    drawn = False
    for method in methods:
        runs = [res for res in _done(records, method) if res.get("success")]
        if not runs:
            continue
        samples = {}
        for i in range(m_tasks):
            samples[i] = []
            for res in runs:
                if i >= len(res["success"]):
                    continue
                # tasks without an env (RoboTasks9's scoop, ...) are None: not executed
                flags = [bool(s) for row in res["success"][i][: i + 1] if row is not None
                         for s in row]
                if flags:
                    samples[i].append(float(np.mean(flags)))
        _median_band(ax, method.upper(), samples)
        drawn = True
    if not drawn:
        plt.close(fig)
        return None
    ax.set_ylim(-0.03, 1.03)
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.set_xlabel("current task (index of the task just learned)")
    ax.set_ylabel("execution success of seen tasks")
    ax.set_title(f"{title}: simulated execution success vs current task")
    ax.legend(ncol=4, fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, out / "success_vs_task.png")


def plot_all(records, rows, methods, out: Path, title: str) -> list[Path]:
    """Write every figure that has data; return their paths."""
    paths = [
        plot_error_vs_task(records, methods, out, title),
        plot_error_boxes(records, methods, out, title),
        plot_radar(rows, out, title),
        plot_success_vs_task(records, methods, out, title),
    ]
    _plt().close("all")
    return [p for p in paths if p is not None]
