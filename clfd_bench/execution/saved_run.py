"""What ``clfd-bench train`` saved in a run directory, as the execution layer sees it: the
learned tasks and their predictions after each task (read through
:class:`clfd_bench.runs.RunDir`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.runs import RunDir

__all__ = ["SavedRun", "load_run", "load_run_predictions"]


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
    def method(self) -> str:
        """The CL method that made the run (``config.method``; "" when not recorded)."""
        return str((self.results.get("config") or {}).get("method") or "")

    @property
    def complete(self) -> bool:
        """Every task of the run is learned."""
        return self.num_learned >= len(self.task_names)

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


def load_run(run_dir: str | Path) -> SavedRun:
    """Reads a run directory's ``results.json`` into a :class:`SavedRun`."""
    store = RunDir(run_dir)
    run_dir, where = store.path, store.results_path
    results = store.load_results()
    tasks = results.get("tasks")
    if not tasks:
        raise ValueError(f"{where} has no 'tasks'; was it written by `clfd-bench train`?")
    names = [t["name"] if isinstance(t, Mapping) else str(t) for t in tasks]
    cfg = results.get("config") or {}
    dataset = cfg.get("dataset") or results.get("dataset")
    if not dataset:
        raise ValueError(f"{where} names no dataset (config.dataset); cannot pick envs")
    if isinstance(results.get("tasks_done"), int):
        done = int(results["tasks_done"])
    else:
        rows = [len(v) for v in (results.get("errors") or {}).values() if isinstance(v, list)]
        done = min(rows) if rows else len(results.get("train_time_s") or [])
    return SavedRun(path=run_dir, results=results, dataset=str(dataset),
                    order=int(cfg.get("order", 0)), task_names=names, num_learned=done)


def load_run_predictions(run_dir: str | Path, after_task: int) -> dict[int, np.ndarray]:
    """The saved predictions of a run after learning task ``after_task``: task index ``j``
    (``j <= after_task``) -> ``[N, T, D]`` float64 in data units
    (:meth:`clfd_bench.runs.RunDir.load_predictions`)."""
    return RunDir(run_dir).load_predictions(after_task)
