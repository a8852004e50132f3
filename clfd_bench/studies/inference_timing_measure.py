"""Inference timing of the hypernetwork methods (HN, CHN): the measurement -- the models timed
and the timed calls. The study that runs it over every dataset part and caches the cells is
:mod:`clfd_bench.studies.inference_timing`; its tables are
:mod:`~clfd_bench.studies.inference_timing_report`.

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
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
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
from clfd_bench.learning.mlp import num_weights
from clfd_bench.learning.node import VectorField
from clfd_bench.learning.odeint import SolverSpec, integrate
from clfd_bench.runs import RunDir

__all__ = [
    "EVAL_KEYS",
    "check_timing_dataset",
    "check_timing_method",
    "apply_eval_overrides",
    "DATASETS",
    "METHODS",
    "PART_LABELS",
    "QUANTITIES",
    "TimedPart",
    "build_learner",
    "count_evaluations",
    "generate_node",
    "initial_state",
    "load_run",
    "measure_part",
    "time_call",
    "timed_parts",
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


def check_timing_method(method: str) -> None:
    if method not in METHODS:
        raise ValueError(
            f"the timing study times hypernetwork methods (NODE generation f_h -> f_theta); "
            f"got {method!r}, valid: {', '.join(METHODS)}"
        )


def check_timing_dataset(dataset: str) -> None:
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
    check_timing_method(method)
    check_timing_dataset(dataset)
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
    check_timing_method(config.method)
    check_timing_dataset(config.dataset)
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
