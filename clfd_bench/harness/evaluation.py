"""Scoring predictions: trajectory errors per demo, accuracy matrices and CL metrics.

Errors are computed in the data's units (``m`` for HelloWorld/RoboTasks positions, LASA's
own units, degrees for orientation) and compared with the paper's thresholds converted to
those units (:func:`clfd_bench.metrics.thresholds.threshold`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from clfd_bench.data.types import Task
from clfd_bench.metrics import trajectory_errors
from clfd_bench.metrics.cl import accuracy_matrix, cl_metrics
from clfd_bench.metrics.thresholds import threshold

__all__ = [
    "POSITION_METRICS",
    "metric_part",
    "metric_units",
    "metrics_for",
    "summarize",
    "task_errors",
    "thresholds_for",
]

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
    num_params: Mapping[str, Sequence[float]],
    stored: Sequence[float],
    total_samples: float,
    train_times: Mapping[str, Sequence[float]],
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Accuracy matrices and CL metrics for every metric with a threshold.

    Args:
        errors: ``metric -> [i][j][demo]`` (``None`` for ``j > i``).
        thresholds: ``metric -> threshold`` in the errors' units.
        num_params, train_times: per part (``position``, ``orientation``) per task; the
            ``quaternion`` metric uses the orientation model's, the others the position's.
        stored: samples stored after each task. total_samples: all tasks' samples.

    Returns:
        ``(accuracy, cl)``: ``metric -> R[i][j]`` (None above the diagonal) and
        ``metric -> {ACC, REM, BWT, MS, SSS, TE}``.
    """
    accuracy: dict[str, Any] = {}
    cl: dict[str, Any] = {}
    for metric, thr in thresholds.items():
        rows = [
            [None if e is None else [np.nan if x is None else x for x in e] for e in row]
            for row in errors[metric]
        ]
        r = accuracy_matrix(rows, thr)
        accuracy[metric] = [[None if np.isnan(v) else float(v) for v in row] for row in r]
        part = metric_part(metric, num_params)
        cl[metric] = cl_metrics(r, num_params[part], stored, total_samples, train_times[part])
    return accuracy, cl
