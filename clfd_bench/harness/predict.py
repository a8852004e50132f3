"""Predictions from a trained run: ``predict(run_dir_or_model, task, starts, times)``.

Later stages (simulation rollouts, ``clfd-bench evaluate``) regenerate trajectories from a
run's checkpoint with this function instead of re-training.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from clfd_bench.harness.learner import Learner
from clfd_bench.harness.protocol import load_learner
from clfd_bench.runs import RunDir

__all__ = ["predict"]

_CACHE: dict[tuple[str, float], Learner] = {}


def _learner(run_dir: str | os.PathLike[str]) -> Learner:
    path = Path(run_dir).resolve()
    key = (str(path), RunDir(path).checkpoint_mtime())
    if key not in _CACHE:
        _CACHE.clear()
        _CACHE[key] = load_learner(path)[0]
    return _CACHE[key]


def predict(
    run_dir_or_model: str | os.PathLike[str] | Learner,
    task_index: int,
    starts: np.ndarray,
    times: np.ndarray,
    goals: np.ndarray | None = None,
) -> np.ndarray:
    """Trajectories of a learned task, integrated from arbitrary starts.

    Args:
        run_dir_or_model: a run directory (its latest ``checkpoint.pt`` is loaded, once per
            file version) or a :class:`~clfd_bench.harness.learner.Learner`.
        task_index: position of the task in the run's task order.
        starts: ``[N, D]`` start states in data units (D = 2, or 7 = position in metres +
            unit quaternion w, x, y, z).
        times: ``[T]`` seconds from the start (the demos' ``task.times`` reproduces them).
        goals: pose data only: ``[N, 4]`` goal quaternions for the tangent map (default: the
            task's goal orientation; the protocol passes each demo's final quaternion when the
            run's ``tangent_goal`` is ``demo``, as the paper does).

    Returns:
        ``[N, T, D]`` in data units.
    """
    learner = run_dir_or_model if isinstance(run_dir_or_model, Learner) else _learner(
        run_dir_or_model
    )
    return learner.predict(task_index, starts, times, goals)
