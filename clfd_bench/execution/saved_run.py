"""Reading what ``clfd-bench train`` saved in a run directory: ``results.json`` and the
predictions after each task (the execution layer's view of a run)."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["PREDICTIONS_DIR", "RESULTS_FILE", "SavedRun", "load_run", "load_run_predictions",
           "read_results"]

RESULTS_FILE = "results.json"
PREDICTIONS_DIR = "predictions"

@dataclasses.dataclass(frozen=True)
class SavedRun:
    """What a run directory of ``clfd-bench train`` says about itself.

    Attributes:
        path: the run directory.
        results: its ``results.json``.
        dataset: the dataset name; order: the task order.
        task_names: names of every task of the run, in order.
        num_learned: tasks learned so far (evaluation rows present).
    """

    path: Path
    results: dict[str, Any]
    dataset: str
    order: int
    task_names: list[str]
    num_learned: int

    @property
    def learned(self) -> list[str]:
        """Names of the learned tasks."""
        return self.task_names[: self.num_learned]

    def demos(self) -> list[np.ndarray]:
        """The learned tasks' demonstrations ``[N, T, D]`` (data layer), in task order."""
        from clfd_bench.data import load_dataset

        ds = load_dataset(self.dataset, order=self.order)
        if list(ds.task_names[: len(self.task_names)]) != self.task_names:
            raise ValueError(f"{self.path}: results.json tasks {self.task_names} differ from "
                             f"{self.dataset} order {self.order} ({list(ds.task_names)})")
        return [np.asarray(ds.tasks[j].demos) for j in range(self.num_learned)]


def read_results(run_dir: str | Path) -> dict[str, Any]:
    """``RUN_DIR/results.json``.

    Raises:
        FileNotFoundError: it does not exist (the message says what RUN_DIR must be).
    """
    path = Path(run_dir) / RESULTS_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: RUN_DIR must be a directory written by "
                                "`clfd-bench train` (it holds results.json)")
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def load_run(run_dir: str | Path) -> SavedRun:
    """Reads a run directory's ``results.json`` into a :class:`SavedRun`."""
    run_dir = Path(run_dir)
    results = read_results(run_dir)
    tasks = results.get("tasks")
    if not tasks:
        raise ValueError(f"{run_dir / RESULTS_FILE} has no 'tasks'; was it written by "
                         "`clfd-bench train`?")
    names = [t["name"] if isinstance(t, Mapping) else str(t) for t in tasks]
    cfg = results.get("config") or {}
    dataset = cfg.get("dataset") or results.get("dataset")
    if not dataset:
        raise ValueError(f"{run_dir / RESULTS_FILE} names no dataset (config.dataset); cannot "
                         "pick envs")
    if isinstance(results.get("tasks_done"), int):
        done = int(results["tasks_done"])
    else:
        rows = [len(v) for v in (results.get("errors") or {}).values() if isinstance(v, list)]
        done = min(rows) if rows else len(results.get("train_time_s") or [])
    return SavedRun(path=run_dir, results=results, dataset=str(dataset),
                    order=int(cfg.get("order", 0)), task_names=names, num_learned=done)


def load_run_predictions(run_dir: str | Path, after_task: int) -> dict[int, np.ndarray]:
    """The saved predictions of a run after learning task ``after_task``.

    Reads ``RUN_DIR/predictions/after_task_{i}.npz`` (written by the training protocol).

    Returns:
        task index ``j`` (``j <= after_task``) -> ``[N, T, D]`` float64 in data units.

    Raises:
        FileNotFoundError: the file is missing (the message says how to regenerate it).
    """
    path = Path(run_dir) / PREDICTIONS_DIR / f"after_task_{after_task}.npz"
    if not path.is_file():
        raise FileNotFoundError(
            f"{path} not found: the run saved no predictions after task {after_task}; re-run "
            "`clfd-bench train` with the same arguments (it resumes and rewrites them)")
    out: dict[int, np.ndarray] = {}
    with np.load(path, allow_pickle=False) as npz:
        for key in npz.files:
            j = _task_key(key)
            if j is not None:
                out[j] = np.asarray(npz[key], dtype=np.float64)
    missing = [j for j in range(after_task + 1) if j not in out]
    if missing:
        raise ValueError(f"{path} holds no predictions of tasks {missing} (keys: {npz.files})")
    return out


def _task_key(key: str) -> int | None:
    """Task index of an npz key "task_{j}" (or "{j}")."""
    digits = key[5:] if key.startswith("task_") else key
    return int(digits) if digits.isdigit() else None
