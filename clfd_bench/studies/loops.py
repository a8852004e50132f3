"""Loops without a time input: which learned tasks keep the loops their demos draw.

The paper adds a time input to the NODE (NODE^T) because without one (NODE^I) "even SG is
unable to learn trajectories with loops" (its HelloWorld 'e', 'r' and 'd'). On a planar
dataset that is geometry: the solutions of a time-invariant planar vector field never cross,
so a NODE^I prediction cannot close a loop, whatever its training. How much that costs
depends on the criterion that judges the prediction. This study shows it per task, right
after the task is learned (the diagonal of the run's matrices), for NODE^T and NODE^I:

* how often the demos cross themselves, and the predictions (:func:`self_crossings`, points
  closer than 0.5 % of the demo's extent to the last kept one dropped first);
* the prediction's median DTW against the paper's threshold, and the fraction of demos whose
  prediction passes it (the paper's accuracy);
* the fraction whose prediction succeeds when executed in simulation (runs with simulation).

A loop task whose NODE^I prediction passes the DTW threshold but fails in execution is a loop
the threshold forgives and the task's success criterion does not. The runs are the
leaderboard's (``out/runs``, the paper grid's names, task order 0): finished ones are reused,
missing ones trained (resumable).
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
from clfd_bench.leaderboard.grid import DEFAULT_OPTIONS, GridOptions, RunSpec
from clfd_bench.metrics.trajectory import self_crossings
from clfd_bench.runs import RunDir

__all__ = ["LoopRow", "LoopStudy", "study_specs", "summarize", "write_outputs"]

#: Points closer than this fraction of the demo's extent are dropped before counting
#: crossings (a trajectory resting at its end jitters in place).
MIN_STEP_FRACTION = 0.005


def study_specs(dataset: str, methods: list[str], profile: str, seeds: list[int],
                options: GridOptions = DEFAULT_OPTIONS) -> list[RunSpec]:
    """One run per method x NODE variant (``t``, ``i``; ``options.node`` is not used) x
    seed, task order 0, with the tasks and simulation of ``options``: the paper grid's runs,
    so a grid trained before is reused."""
    tasks, sim = options.tasks, options.sim
    return [RunSpec(dataset, m, profile, s, 0, node, tasks, sim)
            for m in methods for node in ("t", "i") for s in seeds]


@dataclass
class LoopRow:
    """One task x method x NODE variant, right after the task was learned.

    Attributes:
        demo_crossings: median over the demos of how often each crosses itself.
        pred_crossings: median over demos and seeds of the predictions' crossings.
        dtw: median DTW of the predictions (data units); ``threshold`` the paper's.
        dtw_pass: fraction of demos (mean over seeds) whose prediction is under the threshold.
        exec_pass: the same for success in simulation (NaN: no run executed).
    """

    task: str
    method: str
    node: str
    runs: int
    demo_crossings: float
    pred_crossings: float
    dtw: float
    threshold: float
    dtw_pass: float
    exec_pass: float

    @property
    def has_loop(self) -> bool:
        return self.demo_crossings >= 1

    def to_dict(self) -> dict[str, Any]:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in asdict(self).items()}


@dataclass
class LoopStudy:
    """The rows, and one method's predictions for the figure.

    Attributes:
        examples: ``{(node, task): [N, T, 2]}`` predictions of ``example_method`` right after
            each task (first seed); ``demos``: ``{task: [N, T, 2]}``.
    """

    rows: list[LoopRow]
    example_method: str | None
    examples: dict[tuple[str, str], np.ndarray]
    demos: dict[str, np.ndarray]


def _crossings(trajs: np.ndarray, extent: float) -> list[int]:
    return [self_crossings(t, MIN_STEP_FRACTION * extent) for t in trajs]


def summarize(records: list[RunRecord], out: Path, dataset: str,
              methods: list[str]) -> LoopStudy:
    """Rows for every finished run's tasks (methods in ``methods`` order, NODE^T first).

    Raises:
        ValueError: the dataset is not planar (crossings are a planar notion).
    """
    from clfd_bench.data import load_dataset

    ds = load_dataset(dataset, order=0)
    demos = {t.name: np.asarray(t.positions) for t in ds.tasks}
    dims = {d.shape[-1] for d in demos.values()}
    if dims != {2}:
        raise ValueError(f"the loop study needs a planar dataset (positions [N, T, 2]); "
                         f"{dataset} has {sorted(dims)}-D positions: use lasa or helloworld")
    extent = {n: float(np.linalg.norm(np.ptp(d.reshape(-1, 2), axis=0))) for n, d in demos.items()}
    demo_x = {n: float(np.median(_crossings(d, extent[n]))) for n, d in demos.items()}
    rows: list[LoopRow] = []
    examples: dict[tuple[str, str], np.ndarray] = {}
    example_method = None
    for method in methods:
        for node in ("t", "i"):
            done = [r for r in records if r.spec.method == method and r.spec.node == node
                    and r.status == "done" and r.results is not None]
            if not done:
                continue
            done.sort(key=lambda r: r.spec.seed)
            if example_method is None and node == "t":
                example_method = method
            names = done[0].results["tasks"]
            for i, name in enumerate(names):
                crossings, dtws, passes, executed = [], [], [], []
                for rec in done:
                    res = rec.results
                    pred = RunDir(rec.spec.run_dir(out)).load_predictions(i)[i]
                    crossings += _crossings(pred, extent[name])
                    dtws += [float(e) for e in res["errors"]["dtw"][i][i]]
                    passes.append(float(res["accuracy"]["dtw"][i][i]))
                    sim = res.get("sim_accuracy")
                    if sim and sim[i][i] is not None:
                        executed.append(float(sim[i][i]))
                    if method == example_method and rec is done[0]:
                        examples[(node, name)] = pred
                rows.append(LoopRow(
                    name, method, node, len(done), demo_x[name],
                    float(np.median(crossings)), float(np.median(dtws)),
                    float(done[0].results["thresholds"]["dtw"]), float(np.mean(passes)),
                    float(np.mean(executed)) if executed else math.nan))
    return LoopStudy(rows, example_method, examples, demos)


def _f(x: float, digits: int = 2) -> str:
    return "—" if not math.isfinite(x) else f"{x:.{digits}f}"


def markdown(study: LoopStudy, meta: dict[str, Any]) -> str:
    """Per method: the loop tasks' rows (NODE^T beside NODE^I), then a summary line."""
    loops = sorted({r.task for r in study.rows if r.has_loop},
                   key=[r.task for r in study.rows].index)
    lines = [
        f"# Loops without a time input: {meta['dataset']} ({meta['profile']} profile)",
        "",
        f"Seeds {meta['seeds']}, task order 0; each task right after it was learned. Tasks "
        f"whose demos cross themselves (median over demos): {', '.join(loops) or 'none'}. "
        "crossings: median over demos (and seeds) of how often a trajectory crosses itself; "
        "DTW: median, against the paper's threshold; DTW pass / exec pass: fraction of demos "
        "whose prediction is under the threshold / succeeds in simulation (mean over seeds; "
        "— without simulation).",
        "",
        "| method | task | demo crossings | NODE^T crossings | NODE^T DTW / thr | NODE^T DTW "
        "pass | NODE^T exec pass | NODE^I crossings | NODE^I DTW / thr | NODE^I DTW pass | "
        "NODE^I exec pass |",
        "|" + "---|" * 11,
    ]
    by = {(r.method, r.node, r.task): r for r in study.rows}
    methods = list(dict.fromkeys(r.method for r in study.rows))
    for m in methods:
        for task in loops:
            cells = [m.upper(), task]
            first = by.get((m, "t", task)) or by.get((m, "i", task))
            cells.append(_f(first.demo_crossings, 0) if first else "—")
            for node in ("t", "i"):
                r = by.get((m, node, task))
                cells += ([_f(r.pred_crossings, 1), f"{_f(r.dtw, 1)} / {_f(r.threshold, 1)}",
                           _f(r.dtw_pass), _f(r.exec_pass)] if r else ["—"] * 4)
            lines.append("| " + " | ".join(cells) + " |")
    lines += ["", "Over the loop tasks (mean of the rows above):", ""]
    for m in methods:
        parts = []
        for node in ("t", "i"):
            rs = [by[(m, node, t)] for t in loops if (m, node, t) in by]
            if rs:
                parts.append(f"NODE^{node.upper()} DTW pass {_f(np.mean([r.dtw_pass for r in rs]))}"
                             f", exec pass {_f(np.mean([r.exec_pass for r in rs]))}")
        lines.append(f"- {m.upper()}: " + "; ".join(parts))
    return "\n".join(lines) + "\n"


def plot_examples(study: LoopStudy, path: Path, title: str) -> Path | None:
    """One panel per loop task: the demos (grey) and one method's NODE^T / NODE^I predictions
    right after the task (blue / red), as drawn in the plane."""
    from clfd_bench.leaderboard.plots import _plt, _save

    loops = list(dict.fromkeys(r.task for r in study.rows if r.has_loop))
    if not loops or study.example_method is None:
        return None
    plt = _plt()
    fig, axes = plt.subplots(1, len(loops), figsize=(3.2 * len(loops), 3.4), squeeze=False)
    for ax, task in zip(axes[0], loops, strict=True):
        for k, demo in enumerate(study.demos[task]):
            ax.plot(demo[:, 0], demo[:, 1], color="0.7", lw=1,
                    label="demos" if k == 0 else None)
        for node, color in (("t", "C0"), ("i", "C3")):
            pred = study.examples.get((node, task))
            if pred is not None:
                ax.plot(pred[0, :, 0], pred[0, :, 1], color=color, lw=1.4,
                        label=f"NODE^{node.upper()}")
        ax.set_title(task)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
    axes[0][0].legend(fontsize=7, loc="best")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = _save(fig, Path(path))
    plt.close(fig)
    return out


def write_outputs(study: LoopStudy, out: Path, meta: dict[str, Any]) -> list[Path]:
    """``loops.md/.csv/.json`` and ``loops.png`` into ``out``."""
    out = Path(out)
    buf = io.StringIO()
    w = csv.writer(buf)
    fields = list(LoopRow.__dataclass_fields__)
    w.writerow(fields)
    for r in study.rows:
        w.writerow(["" if v is None else v for v in r.to_dict().values()])
    atomic_write_text(out / "loops.md", markdown(study, meta))
    atomic_write_text(out / "loops.csv", buf.getvalue())
    atomic_write_json(out / "loops.json", {"meta": meta, "rows": [r.to_dict() for r in study.rows]})
    method = (study.example_method or "").upper()
    fig = plot_examples(study, out / "loops.png",
                        f"{meta['dataset']}: {method}'s first prediction right after each loop "
                        "task, with and without a time input")
    return [out / f"loops.{ext}" for ext in ("md", "csv", "json")] + ([fig] if fig else [])
