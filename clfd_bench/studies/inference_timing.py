"""Inference timing of the hypernetwork methods (HN, CHN): the paper's appendix table.

For each dataset part (LASA, HelloWorld, RoboTasks positions, RoboTasks orientations) and
each hypernetwork method, three quantities are timed, each the median of ``repeats`` timed
calls after ``warmup`` untimed ones (milliseconds, and Hz = 1000 / median ms):

* ``generate`` -- ``f_h -> f_theta``: one hypernetwork forward pass for one task embedding,
  producing the NODE's weights (the method's own :meth:`~clfd_bench.methods.base.Method.field`,
  i.e. exactly what prediction uses);
* ``step`` -- ``f_theta(x)``: one evaluation of the generated NODE on one state ``[1, D]``;
* ``integrate`` -- a whole trajectory: the generated NODE integrated from one demonstration's
  start over the task's 1000 output times with the profile's own prediction solver
  (``paper``: dopri5, rtol 1e-6, atol 1e-7; ``fast``: RK4, one step per sample), through
  :func:`clfd_bench.learning.odeint.integrate` as :meth:`PartLearner.predict` does.

Timing does not depend on the trained values for ``generate`` and ``step``, so by default the
models are built at a profile's sizes (:func:`build_learner`: the ``paper`` profile's widths,
embedding sizes and number of task embeddings, random initial weights). An adaptive solver's
cost does depend on the dynamics (how many evaluations it needs), so every integration also
records ``nfe``, the number of vector-field evaluations; :func:`load_run` times a trained run
instead. On a GPU (``torch.cuda``) the device is synchronised before and after each call.

The comparison table puts our medians next to the paper's
(:func:`clfd_bench.metrics.paper_numbers.inference`) with the ratio ours / paper per cell
(> 1: slower than the paper).
"""

from __future__ import annotations

import csv
import io
import os
import platform
import statistics
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import Tensor

from clfd_bench.data import load_dataset
from clfd_bench.data.types import Task
from clfd_bench.harness.config import resolve_config
from clfd_bench.harness.learner import Learner, PartLearner
from clfd_bench.harness.loop import solver_spec
from clfd_bench.harness.protocol import load_learner
from clfd_bench.harness.run_config import RunConfig
from clfd_bench.io import atomic_write_json, atomic_write_text
from clfd_bench.learning.mlp import num_weights
from clfd_bench.learning.node import VectorField
from clfd_bench.learning.odeint import SolverSpec, integrate
from clfd_bench.runs import RunDir

__all__ = [
    "EVAL_KEYS",
    "apply_eval_overrides",
    "DATASETS",
    "METHODS",
    "PART_LABELS",
    "QUANTITIES",
    "StudyResult",
    "TimedPart",
    "build_learner",
    "cell_path",
    "comparison_rows",
    "count_evaluations",
    "default_devices",
    "generate_node",
    "initial_state",
    "load_run",
    "machine_info",
    "measure_part",
    "paper_device",
    "plot_comparison",
    "ratio",
    "run_study",
    "summary",
    "time_call",
    "timed_parts",
    "to_csv",
    "to_markdown",
    "write_outputs",
]

METHODS = ("hn", "chn")
"""The methods in the paper's table (the ones that generate a NODE with a hypernetwork)."""

DATASETS = ("lasa", "helloworld", "robotasks")
"""Datasets in the paper's table (RoboTasks contributes a position and an orientation row)."""

PART_LABELS: dict[tuple[str, str], str] = {
    ("lasa", "position"): "LASA",
    ("helloworld", "position"): "HelloWorld",
    ("robotasks", "position"): "RoboTasks (pos)",
    ("robotasks", "orientation"): "RoboTasks (ori)",
}
"""``(dataset, part) -> dataset label`` of the paper's table, in the paper's row order."""

QUANTITIES = ("generate", "step", "integrate")
"""Timed quantities: NODE generation, one NODE evaluation, one 1000-step trajectory."""

QUANTITY_TITLES = {
    "generate": r"$f_h \rightarrow f_\theta$ (generate the NODE)",
    "step": r"$f_\theta(x)$ (one NODE step)",
    "integrate": r"$\int f_\theta\,d\tau$ (1000-step trajectory)",
}


# -- the models ---------------------------------------------------------------------------
@dataclass
class TimedPart:
    """One model to time: a part of a learner, the task whose embedding is used, the input.

    Attributes:
        method: ``hn`` or ``chn``. dataset: dataset name. label: the paper's row label.
        part: the :class:`PartLearner` (its method owns the hypernetwork and embeddings).
        index: the task whose NODE is generated.
        y0: ``[1, D]`` normalised start state (one demonstration's first sample).
        times: ``[T]`` output times in seconds (the task's recorded times, T = 1000).
        solver: the part's prediction solver.
        source: ``built`` (profile sizes, untrained weights) or the trained run's directory.
        profile: the configuration profile the sizes and solver come from.
        num_tasks: task embeddings the hypernetwork holds.
    """

    method: str
    dataset: str
    label: str
    part: PartLearner
    index: int
    y0: Tensor
    times: Tensor
    solver: SolverSpec
    source: str
    profile: str
    num_tasks: int

    @property
    def kind(self) -> str:
        return self.part.kind


def _check_method(method: str) -> None:
    if method not in METHODS:
        raise ValueError(
            f"the timing study times hypernetwork methods (NODE generation f_h -> f_theta); "
            f"got {method!r}, valid: {', '.join(METHODS)}"
        )


def _check_dataset(dataset: str) -> None:
    if dataset not in DATASETS:
        raise ValueError(f"unknown dataset {dataset!r} for the timing study; valid: "
                         f"{', '.join(DATASETS)}")


def initial_state(part: PartLearner, index: int, task: Task, demo: int = 0) -> Tensor:
    """The normalised start state ``[1, D]`` of ``task``'s demo ``demo``, as prediction sees it.

    Positions: the demo's first position; orientations: its tangent vector relative to the
    goal the protocol uses (the demo's final quaternion for ``tangent_goal = "demo"``) times
    ``tangent_scale``; both through the task's normaliser (:meth:`PartLearner.node_states`).
    """
    if part.kind == "position":
        return torch.as_tensor(part.node_states(index, task.positions[demo, :1]),
                               dtype=torch.float32)  # [1, D]
    quats = task.quaternions
    if quats is None:
        raise ValueError(f"task {task.name!r} has no orientations")
    goal = (np.asarray(task.demo_goals[demo : demo + 1, 3:]) if part.cfg.tangent_goal == "demo"
            else None)  # None: the task's goal
    y0 = part.node_states(index, quats[demo, :1], goal)  # [1, 3], tangent_scale applied
    return torch.as_tensor(y0, dtype=torch.float32)


def build_learner(
    method: str,
    dataset: str,
    profile: str = "paper",
    *,
    overrides: Sequence[str] = (),
    seed: int = 0,
    node: str = "t",
) -> tuple[Learner, list[Task]]:
    """A learner at ``profile``'s sizes holding one task embedding per task of ``dataset``.

    The weights are the random initial ones (seeded by ``seed``); each task gets its
    normaliser fitted on its demos, as training would. Returns the learner and the tasks
    (order 0).
    """
    _check_method(method)
    _check_dataset(dataset)
    config = resolve_config(method, dataset, profile, seed=seed, node=node, overrides=overrides)
    ds = load_dataset(dataset, order=0)
    torch.manual_seed(seed)
    learner = Learner.from_config(config, ds[0].dim)
    for part in learner.parts.values():
        for task in ds.tasks:
            part.add_task(task)
    return learner, list(ds.tasks)


def load_run(run_dir: str | os.PathLike[str],
             threads: int | None = None) -> tuple[Learner, list[Task]]:
    """The trained learner of a run and its tasks (in the run's order); torch's CPU threads
    set to ``threads`` (default :func:`clfd_bench.harness.protocol.default_threads`).

    Raises:
        FileNotFoundError: no checkpoint (says what to run).
        ValueError: the run is not an HN/CHN run or its dataset is not in the paper's table.
    """
    run = RunDir(run_dir)
    if not run.has_checkpoint():
        raise FileNotFoundError(
            f"{run.checkpoint_path} does not exist: train the run first, e.g. "
            f"`clfd-bench train --method hn --dataset helloworld --profile paper --out "
            f"{run.path}`"
        )
    learner, _header = load_learner(run.path, threads=threads)
    config: RunConfig = learner.config
    _check_method(config.method)
    _check_dataset(config.dataset)
    ds = load_dataset(config.dataset, order=config.order)
    return learner, list(ds.tasks[: learner.num_tasks])


EVAL_KEYS = ("eval_solver", "eval_rtol", "eval_atol", "eval_substeps", "solver_backend")
"""Config keys that may be overridden on a trained run (they change how it is integrated,
not the model)."""


def apply_eval_overrides(learner: Learner, overrides: Sequence[str]) -> None:
    """Change the prediction solver of a loaded run's parts (``[part.]key=value``, keys in
    :data:`EVAL_KEYS`), e.g. ``eval_solver=dopri5`` to integrate a ``fast`` run adaptively."""
    import dataclasses

    from clfd_bench.harness.config import ConfigError, parse_override

    for text in overrides:
        part_name, key, value = parse_override(text)
        if key not in EVAL_KEYS:
            raise ConfigError(f"override {text!r}: a trained run can only change "
                              f"{', '.join(EVAL_KEYS)}")
        for kind, part in learner.parts.items():
            if part_name is None or part_name == kind:
                part.cfg = dataclasses.replace(part.cfg, **{key: value})


def timed_parts(
    learner: Learner,
    tasks: Sequence[Task],
    *,
    source: str,
    index: int = 0,
    demo: int = 0,
) -> list[TimedPart]:
    """One :class:`TimedPart` per part of ``learner`` (positions first), for task ``index``."""
    config = learner.config
    if not 0 <= index < learner.num_tasks:
        raise ValueError(f"task {index} is not learned; the model holds {learner.num_tasks} tasks")
    task = tasks[index]
    out = []
    for kind in ("position", "orientation"):
        part = learner.parts.get(kind)
        if part is None:
            continue
        out.append(TimedPart(
            method=config.method, dataset=config.dataset,
            label=PART_LABELS[(config.dataset, kind)], part=part, index=index,
            y0=initial_state(part, index, task, demo),
            times=torch.tensor(part.node_times(index, task.times), dtype=torch.float32),
            solver=solver_spec(part.cfg, evaluation=True), source=source,
            profile=config.profile, num_tasks=part.method.num_tasks,
        ))
    return out


# -- what is timed ------------------------------------------------------------------------
def generate_node(part: PartLearner, index: int) -> VectorField:
    """``f_h -> f_theta``: the NODE of task ``index``, generated from its embedding.

    This is the method's own :meth:`~clfd_bench.methods.base.Method.field` (the hypernetwork
    forward pass for one embedding, cut into the NODE's weight tensors), i.e. exactly the
    field :meth:`PartLearner.predict` integrates.
    """
    with torch.no_grad():
        return part.method.field(index)


def _sync(device: torch.device) -> Callable[[], None]:
    if device.type == "cuda":
        return lambda: torch.cuda.synchronize(device)
    return lambda: None


def time_call(
    fn: Callable[[], object],
    repeats: int,
    warmup: int,
    device: torch.device | str = "cpu",
) -> list[float]:
    """Run ``fn`` ``warmup`` times untimed, then ``repeats`` times timed -> milliseconds each.

    On a CUDA device the device is synchronised before starting and after each call's end,
    so a time covers the whole computation, not just the kernel launches.
    """
    if repeats < 1 or warmup < 0:
        raise ValueError(f"repeats must be >= 1 and warmup >= 0, got {repeats}, {warmup}")
    sync = _sync(torch.device(device))
    with torch.no_grad():
        for _ in range(warmup):
            fn()
        sync()
        out = []
        for _ in range(repeats):
            start = time.perf_counter()
            fn()
            sync()
            out.append((time.perf_counter() - start) * 1e3)
    return out


def count_evaluations(field: VectorField, y0: Tensor, times: Tensor, solver: SolverSpec) -> int:
    """Vector-field evaluations one integration needs (the same algorithm, counted by
    running it once through the reference ``autograd`` path with a counting field)."""
    count = 0

    def counted(t, y):
        nonlocal count
        count += 1
        return field(t, y)

    with torch.no_grad():
        integrate(counted, y0, times, solver, fused=False)
    return count


def _stats(samples: Sequence[float]) -> dict[str, float]:
    q1, med, q3 = np.percentile(np.asarray(samples), [25, 50, 75])
    return {"ms": float(med), "hz": 1e3 / float(med) if med > 0 else float("inf"),
            "iqr_ms": float(q3 - q1)}


def measure_part(
    tp: TimedPart,
    *,
    repeats: int = 100,
    warmup: int = 5,
    device: torch.device | str = "cpu",
) -> dict[str, Any]:
    """Time ``generate``, ``step`` and ``integrate`` of one part -> a cell (plain data).

    The cell holds, per quantity ``q``: ``q_ms`` (median), ``q_hz`` (1000 / median),
    ``q_iqr_ms`` and the raw ``samples[q]``; plus ``nfe`` (evaluations per integration),
    ``integrate_ms_per_eval``, the model sizes and the solver.
    """
    device = torch.device(device)
    method = tp.part.method
    method.to(device)
    method.eval()
    y0, times = tp.y0.to(device), tp.times.to(device)
    t0 = times[0]
    field = generate_node(tp.part, tp.index)
    samples = {
        "generate": time_call(lambda: generate_node(tp.part, tp.index), repeats, warmup, device),
        "step": time_call(lambda: field(t0, y0), repeats, warmup, device),
        "integrate": time_call(lambda: integrate(field, y0, times, tp.solver),
                               repeats, max(1, min(warmup, 2)), device),
    }
    nfe = count_evaluations(field, y0, times, tp.solver)
    hnet = method.hnet
    cell: dict[str, Any] = {
        "device": device.type,
        "dataset": tp.dataset,
        "part": tp.kind,
        "label": tp.label,
        "method": tp.method.upper(),
        "source": tp.source,
        "profile": tp.profile,
        "task": tp.index,
        "num_tasks": tp.num_tasks,
        "node_hidden": list(tp.part.cfg.node_hidden),
        "hnet_hidden": list(tp.part.cfg.hnet_hidden),
        "node_params": num_weights(method.node_spec.param_shapes()),
        "hnet_params": sum(int(p.numel()) for p in hnet.parameters()),
        "solver": {"method": tp.solver.method, "rtol": tp.solver.rtol, "atol": tp.solver.atol,
                   "substeps": tp.solver.substeps, "backend": tp.solver.backend},
        "output_times": int(times.shape[0]),
        "repeats": repeats,
        "warmup": warmup,
        "nfe": nfe,
    }
    for q in QUANTITIES:
        s = _stats(samples[q])
        cell[f"{q}_ms"], cell[f"{q}_hz"], cell[f"{q}_iqr_ms"] = s["ms"], s["hz"], s["iqr_ms"]
    cell["integrate_ms_per_eval"] = cell["integrate_ms"] / nfe if nfe else None
    cell["samples"] = samples
    method.to("cpu")
    return cell


def cell_path(out: str | os.PathLike[str], device: str, dataset: str, part: str,
              method: str) -> Path:
    """Where a measured cell is cached: ``out/cells/{device}_{dataset}_{part}_{method}.json``."""
    return Path(out) / "cells" / f"{device}_{dataset}_{part}_{method.lower()}.json"


# -- machine ------------------------------------------------------------------------------
def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def machine_info() -> dict[str, Any]:
    """CPU model, core counts, torch version and threads, GPU name, load average now."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else None
    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except OSError:  # pragma: no cover
        load = None
    return {
        "cpu": _cpu_model(),
        "logical_cpus": os.cpu_count(),
        "available_cores": cores,
        "torch": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "gpu": gpu,
        "load_average_1_5_15min": load,
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


# -- the study ----------------------------------------------------------------------------
@dataclass
class StudyResult:
    """What :func:`run_study` measured and wrote."""

    cells: list[dict[str, Any]]
    rows: dict[str, list[dict[str, Any]]]
    files: list[Path]
    machine: dict[str, Any]
    measured: int
    cached: int

    def summary(self) -> str:
        return " ".join(summary(rows, d, self.machine) for d, rows in self.rows.items())


def default_devices() -> tuple[str, ...]:
    """``cpu``, plus ``cuda`` when a GPU is available."""
    return ("cpu", "cuda") if torch.cuda.is_available() else ("cpu",)


def _parts_of(dataset: str) -> tuple[str, ...]:
    return ("position", "orientation") if dataset == "robotasks" else ("position",)


def run_study(
    out: str | os.PathLike[str],
    *,
    methods: Sequence[str] = METHODS,
    datasets: Sequence[str] = DATASETS,
    runs: Sequence[str | os.PathLike[str]] = (),
    profile: str = "paper",
    overrides: Sequence[str] = (),
    repeats: int = 100,
    warmup: int = 5,
    threads: int = 1,
    devices: Sequence[str] | None = None,
    seed: int = 0,
    task: int = 0,
    force: bool = False,
    log: Callable[[str], None] | None = print,
) -> StudyResult:
    """Measure every cell (cached in ``out/cells/``; a cell measured with the same settings is
    reused unless ``force``) and write the tables and figures into ``out``.

    Args:
        methods, datasets: what to build at ``profile``'s sizes (ignored when ``runs`` given).
        runs: trained HN/CHN run directories to time instead of built models.
        overrides: ``[part.]key=value`` config overrides for built models (e.g.
            ``eval_solver=rk4``); for runs only the solver keys :data:`EVAL_KEYS`.
        threads: torch CPU threads while timing (restored afterwards).
        devices: ``cpu`` and/or ``cuda`` (default: :func:`default_devices`).
        task: the task whose embedding generates the NODE (and whose demo 0 starts it).
    """
    from clfd_bench.progress import progress

    for m in methods:
        _check_method(m)
    for d in datasets:
        _check_dataset(d)
    devices = tuple(devices or default_devices())
    for d in devices:
        if d not in ("cpu", "cuda"):
            raise ValueError(f"unknown device {d!r}; valid: cpu, cuda")
        if d == "cuda" and not torch.cuda.is_available():
            raise ValueError("device cuda requested but torch.cuda.is_available() is False")
    out = Path(out)
    previous_threads = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        machine = machine_info()
        base = {"repeats": repeats, "warmup": warmup, "threads": threads, "task": task,
                "torch": torch.__version__}
        if runs:
            jobs = [("run", str(Path(r)), "") for r in runs]
        else:
            jobs = [("built", m, d) for m in methods for d in datasets]
        cells: list[dict[str, Any]] = []
        measured = cached = 0
        bar = progress(total=len(jobs) * len(devices), desc="timing")
        for kind, a, b in jobs:
            if kind == "run":
                learner, tasks = load_run(a, threads)
                apply_eval_overrides(learner, overrides)
                method, dataset, source = learner.config.method, learner.config.dataset, a
                settings = {**base, "source": source, "overrides": list(overrides),
                            "checkpoint_sha256": RunDir(a).checkpoint_sha256()}
                loaded: tuple[Learner, list[Task]] | None = (learner, tasks)
            else:
                method, dataset, source = a, b, "built"
                settings = {**base, "source": source, "profile": profile,
                            "overrides": list(overrides), "seed": seed}
                loaded = None
            for device in devices:
                keys = [(p, cell_path(out, device, dataset, p, method)) for p in _parts_of(dataset)]
                todo = []
                for part, path in keys:
                    cell = _read_cell(path, settings) if not force else None
                    if cell is None:
                        todo.append(part)
                    else:
                        cells.append(cell)
                        cached += 1
                if todo:
                    if loaded is None:
                        loaded = build_learner(method, dataset, profile, overrides=overrides,
                                               seed=seed)
                    learner, tasks = loaded
                    for tp in timed_parts(learner, tasks, source=source, index=task):
                        if tp.kind not in todo:
                            continue
                        bar.set_postfix_str(f"{device} {tp.label} {method.upper()}")
                        cell = measure_part(tp, repeats=repeats, warmup=warmup, device=device)
                        cell["settings"] = settings
                        cell["load_average_after"] = machine_info()["load_average_1_5_15min"]
                        atomic_write_json(cell_path(out, device, dataset, tp.kind, method), cell)
                        cells.append(cell)
                        measured += 1
                        if log:
                            log(f"[timing] {device} {tp.label:16s} {method.upper():3s}: "
                                f"generate {cell['generate_ms']:.3f} ms, step "
                                f"{cell['step_ms']:.3f} ms, integrate "
                                f"{cell['integrate_ms']:.1f} ms ({cell['nfe']} evaluations)")
                bar.update(1)
        bar.close()
        study_settings = {"profile": profile if not runs else "from runs",
                          "repeats": repeats, "warmup": warmup, "threads": threads,
                          "task": task, "seed": seed, "overrides": list(overrides),
                          "source": "runs: " + ", ".join(map(str, runs)) if runs
                          else "built (untrained weights)"}
        rows, files = write_outputs(out, cells, machine, study_settings)
    finally:
        torch.set_num_threads(previous_threads)
    return StudyResult(cells, rows, files, machine, measured, cached)


def _read_cell(path: Path, settings: Mapping[str, Any]) -> dict[str, Any] | None:
    import json

    if not path.is_file():
        return None
    try:
        cell = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return cell if cell.get("settings") == dict(settings) else None
