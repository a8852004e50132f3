"""Scoring predictions: trajectory errors per demo, accuracy matrices and CL metrics, and the
``results.json`` document they go into (:func:`results_document`, shared by the training
protocol and by the scoring of external predictions, :mod:`clfd_bench.harness.external`).

Errors are computed in the data's units (``m`` for HelloWorld/RoboTasks positions, LASA's
own units, degrees for orientation) and compared with the paper's thresholds converted to
those units (:func:`clfd_bench.metrics.thresholds.threshold`).
"""

from __future__ import annotations

import platform
import sys
from collections.abc import Mapping, Sequence
from importlib import metadata
from typing import Any

import numpy as np

from clfd_bench.data.types import Dataset, Task
from clfd_bench.io import json_safe
from clfd_bench.metrics import trajectory_errors
from clfd_bench.metrics.cl import accuracy_matrix, cl_metrics
from clfd_bench.metrics.thresholds import threshold
from clfd_bench.runs import RunDir

__all__ = [
    "POSITION_METRICS",
    "SCHEMA_VERSION",
    "dataset_provenance",
    "metric_part",
    "metric_units",
    "metrics_for",
    "package_versions",
    "results_document",
    "summarize",
    "task_errors",
    "thresholds_for",
]

SCHEMA_VERSION = 1
"""Version of the ``results.json`` layout (:func:`results_document`)."""

POSITION_METRICS = ("dtw", "frechet", "swept_area")
"""Metrics computed on positions (all datasets); pose data add ``quaternion`` (degrees)."""


def metrics_for(is_pose: bool) -> tuple[str, ...]:
    """The metrics reported for planar or pose data."""
    return POSITION_METRICS + (("quaternion",) if is_pose else ())


def metric_units(task: Task) -> dict[str, str]:
    """Units of each metric's values for a task's data (``swept_area`` is a length unit^2)."""
    length = task.units
    out = {"dtw": length, "frechet": length, "swept_area": f"{length}^2"}
    if task.is_pose:
        out["quaternion"] = "deg"
    return out


def thresholds_for(dataset: str, task: Task) -> dict[str, float]:
    """The paper's thresholds (in the data's units) for every metric that has one."""
    out: dict[str, float] = {}
    for metric in metrics_for(task.is_pose):
        units = "deg" if metric == "quaternion" else task.units
        try:
            out[metric] = threshold(dataset, metric, units)
        except ValueError:
            continue  # no threshold for this dataset/metric in the paper
    return out


def task_errors(task: Task, pred: np.ndarray) -> dict[str, list[float]]:
    """Errors of the predictions of one task's demos.

    Args:
        task: the task (its demos are the references).
        pred: ``[N, T, D]`` predictions from each demo's start, in data units.

    Returns:
        ``{metric: [N] errors}`` for :func:`metrics_for` the task's data.
    """
    ref = np.asarray(task.demos, dtype=np.float64)
    if pred.shape != ref.shape:
        raise ValueError(f"predictions {pred.shape} do not match demos {ref.shape} of {task.name}")
    if not np.all(np.isfinite(pred)):
        bad = ~np.all(np.isfinite(pred.reshape(pred.shape[0], -1)), axis=1)
        pred = np.where(np.isfinite(pred), pred, 0.0)
    else:
        bad = np.zeros(pred.shape[0], dtype=bool)
    if task.is_pose:
        out = trajectory_errors(pred[..., :3], ref[..., :3], POSITION_METRICS)
        out.update(trajectory_errors(pred[..., 3:], ref[..., 3:], ("quaternion",)))
    else:
        out = trajectory_errors(pred, ref, POSITION_METRICS)
    # a diverged prediction (NaN/inf) scores NaN, which accuracy counts as a failure
    return {
        k: [None if b else float(x) for x, b in zip(v, bad, strict=True)] for k, v in out.items()
    }


def metric_part(metric: str, by_part: dict[str, Any]) -> str:
    """The model (``position`` or ``orientation``) whose size and training time a metric's CL
    criteria (MS, TE, FS) use: the orientation model for ``quaternion`` when the run has one,
    else the position model (the paper's RoboTasks tables are per model)."""
    return "orientation" if metric == "quaternion" and "orientation" in by_part else "position"


def summarize(
    errors: Mapping[str, Sequence[Sequence[Sequence[float] | None]]],
    thresholds: Mapping[str, float],
    num_params: Mapping[str, Sequence[float]] | None,
    stored: Sequence[float] | None,
    total_samples: float,
    train_times: Mapping[str, Sequence[float]] | None,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Accuracy matrices and CL metrics for every metric with a threshold.

    Args:
        errors: ``metric -> [i][j][demo]`` (``None`` for ``j > i``).
        thresholds: ``metric -> threshold`` in the errors' units.
        num_params, train_times: per part (``position``, ``orientation``) ``[M]`` per task;
            the ``quaternion`` metric uses the orientation model's, the others the
            position's. None (or a part missing): not known, MS / TE are left None.
        stored: ``[M]`` samples stored after each task (None: not known, SSS is None).
        total_samples: all tasks' samples.

    Returns:
        ``(accuracy, cl)``: ``metric -> R[i][j]`` (None above the diagonal) and
        ``metric -> {ACC, REM, BWT, MS, SSS, TE}``.
    """
    accuracy: dict[str, Any] = {}
    cl: dict[str, Any] = {}
    sizes_by_part = num_params or {}
    times_by_part = train_times or {}
    for metric, thr in thresholds.items():
        rows = [
            [None if e is None else [np.nan if x is None else x for x in e] for e in row]
            for row in errors[metric]
        ]
        r = accuracy_matrix(rows, thr)
        accuracy[metric] = [[None if np.isnan(v) else float(v) for v in row] for row in r]
        sizes = sizes_by_part.get(metric_part(metric, sizes_by_part))
        times = times_by_part.get(metric_part(metric, times_by_part))
        cl[metric] = cl_metrics(r, sizes, stored, total_samples, times)
    return accuracy, cl


def package_versions() -> dict[str, str]:
    """Python, platform and the versions of the packages a result depends on (provenance)."""
    out = {"python": sys.version.split()[0], "platform": platform.platform()}
    for pkg in ("clfd-bench", "torch", "torchdiffeq", "numpy", "scipy", "mink", "mujoco"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


#: Environment variables that choose the CPU kernels PyTorch and MKL run (recorded when set).
KERNEL_ENV = ("ATEN_CPU_CAPABILITY", "MKL_ENABLE_INSTRUCTIONS", "MKL_CBWR", "ONEDNN_MAX_CPU_ISA")


def cpu_provenance() -> dict[str, Any]:
    """The CPU a result was computed on and the kernels PyTorch dispatched to.

    Training is reproducible on one machine, not across CPUs: PyTorch and MKL pick vector
    kernels by instruction set (AVX2, AVX-512, ...), whose float rounding differs, and a
    sensitive run amplifies it (an sNODE orientation model learned to 3.7 degrees with AVX2
    kernels and stuck at 50 with AVX-512, same seed; docs/snode.md). Returns ``model`` (from
    ``/proc/cpuinfo`` where there is one, else ``platform.processor()``), ``torch_capability``
    (``torch.backends.cpu.get_cpu_capability()``) and ``kernel_env``: the set variables of
    :data:`KERNEL_ENV`, and ``blas``: the linear-algebra libraries and MKL's reproducibility
    mode (:func:`clfd_bench.kernels.blas_provenance`).
    """
    import os

    import torch

    from clfd_bench.kernels import blas_provenance

    model = platform.processor()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            model = next((line.split(":", 1)[1].strip() for line in fh
                          if line.startswith("model name")), model)
    except OSError:
        pass
    return {"model": model, "torch_capability": torch.backends.cpu.get_cpu_capability(),
            "kernel_env": {k: os.environ[k] for k in KERNEL_ENV if k in os.environ},
            "blas": blas_provenance()}


def dataset_provenance(ds: Dataset) -> dict[str, Any]:
    """The dataset block of ``results.json``'s provenance: name, order, tasks, source, the
    sha256 of every file."""
    return {"name": ds.name, "order": ds.order, "tasks": ds.task_names, "source": ds.source,
            "files": dict(ds.files)}


def results_document(
    config: Mapping[str, Any],
    dataset: str,
    tasks: Sequence[Task],
    state: Mapping[str, Any],
    *,
    complete: bool,
    provenance: Mapping[str, Any],
    checkpoint: str | None,
) -> dict[str, Any]:
    """The training fields of a run's ``results.json`` (:data:`SCHEMA_VERSION`), written by
    the training protocol and by the scoring of external predictions alike.

    Args:
        config: the resolved configuration as plain data (``RunConfig.to_dict()``).
        dataset: the dataset's name; tasks: every task of the run, in order.
        state: ``tasks`` (names), ``errors`` ``{metric: [i][j][demo]}`` (one row per learned
            task), and per task: ``train_time_s``, ``num_params``, ``stored_samples``
            (``[M]`` lists, or None when not known), ``train_time_s_by_part``,
            ``num_params_by_part`` (``{part: [M]}`` or None), ``iterations_per_s_by_part``,
            ``iterations_by_part`` (optimiser steps each task ran; fewer than the config's
            ``iterations`` when the stop rule ended it; missing or None: not known),
            ``final_loss_by_part``; optionally ``train_cpu_s`` (``[M]``, this process's CPU
            seconds per task, None where unknown; absent for external predictions) and
            ``solver_gap_by_part`` (per task, :meth:`~clfd_bench.harness.learner.PartLearner.
            solver_gap`: the fine solution's distance from the training solver's), and with
            it ``substeps_by_part`` (per task, the solver steps per interval its training
            ended with) and ``refine_gaps_by_part`` (per task, the gaps ``refine_gap``
            measured, ``[]`` when off).
        complete: every task of the run is learned.
        provenance: what ``results.json`` records as ``provenance``.
        checkpoint: the checkpoint file relative to the run directory (None: none).
    """
    tasks = list(tasks)[: len(state["tasks"])]
    first = tasks[0]
    thresholds = thresholds_for(dataset, first)
    metrics = metrics_for(first.is_pose)
    done = len(state["errors"][metrics[0]])
    total = float(sum(t.num_demos * t.num_steps for t in tasks))
    accuracy: dict[str, Any] = {}
    cl: dict[str, Any] = {}
    if done:
        accuracy, cl = summarize(
            state["errors"], thresholds, state["num_params_by_part"], state["stored_samples"],
            total, state["train_time_s_by_part"],
        )
    primary = "dtw" if "dtw" in cl else next(iter(cl), None)
    return json_safe({
        "schema_version": SCHEMA_VERSION,
        "complete": complete,
        "config": dict(config),
        "tasks": state["tasks"],
        "tasks_done": done,
        "units": metric_units(first),
        "metrics": list(metrics),
        "thresholds": thresholds,
        "train_time_s": state["train_time_s"],
        "train_cpu_s": state.get("train_cpu_s"),
        "train_time_s_by_part": state["train_time_s_by_part"],
        "iterations_per_s_by_part": state["iterations_per_s_by_part"],
        "iterations_by_part": state.get("iterations_by_part"),
        "final_loss_by_part": state["final_loss_by_part"],
        "solver_gap_by_part": state.get("solver_gap_by_part"),
        "substeps_by_part": state.get("substeps_by_part"),
        "refine_gaps_by_part": state.get("refine_gaps_by_part"),
        "num_params": state["num_params"],
        "num_params_by_part": state["num_params_by_part"],
        "stored_samples": state["stored_samples"],
        "total_samples": total,
        "errors": state["errors"],
        "accuracy": accuracy,
        "cl_metrics": cl.get(primary, {}),
        "cl_metrics_primary": primary,
        "cl_metrics_by_metric": cl,
        "predictions": [RunDir.predictions_name(i) for i in range(done)],
        "checkpoint": checkpoint,
        "provenance": dict(provenance),
    })
