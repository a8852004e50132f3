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

__all__ = ["SavedRun", "TaskExecution", "load_run", "load_run_predictions"]

#: ``results.json`` ``sim`` keys that hold one value per evaluation point (not provenance).
_SIM_POINT_KEYS = ("tracking_error", "failure_reason", "failure_kind")


@dataclasses.dataclass(frozen=True)
class TaskExecution:
    """How one task's predictions after one learned task fared when executed, per demo.

    Attributes:
        after_task: the learned task after which the predictions were made.
        task: the executed task's index; name: its name.
        success: per demo, whether the execution succeeded.
        reasons, kinds: per demo, why it failed and the failure's kind
            (:data:`clfd_bench.execution.execute.FAILURE_KINDS`); None on success.
    """

    after_task: int
    task: int
    name: str
    success: list[bool]
    reasons: list[str | None]
    kinds: list[str | None]


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

    @property
    def executed(self) -> bool:
        """Whether the run's predictions were executed in simulation (``success`` present)."""
        return bool(self.results.get("success"))

    def accuracy_matrices(self) -> dict[str, list[list[float | None]]]:
        """The run's R matrices, ``R[i][j]`` = accuracy on task ``j`` after learning task
        ``i`` (None above the diagonal): one per trajectory metric with a threshold (e.g.
        ``dtw``) and ``execution`` (success rate in simulation) when the run executed."""
        out = {str(k): v for k, v in (self.results.get("accuracy") or {}).items()
               if isinstance(v, list)}
        if isinstance(self.results.get("sim_accuracy"), list):
            out["execution"] = self.results["sim_accuracy"]
        return out

    def execution(self, task: int, after_task: int | None = None) -> TaskExecution | None:
        """How task ``task``'s predictions after learning ``after_task`` (default: the last
        learned task) fared in simulation; None when they were not executed (no simulation,
        or a task without an env)."""
        i = self.num_learned - 1 if after_task is None else after_task
        if not 0 <= task <= i < self.num_learned:
            raise ValueError(f"{self.path}: no predictions of task {task} after task {i} "
                             f"(learned {self.num_learned})")
        try:
            success = self.results["success"][i][task]
        except (KeyError, IndexError, TypeError):
            return None
        if success is None:
            return None
        sim = self.results.get("sim") or {}

        def per_demo(key: str) -> list:
            try:
                values = sim[key][i][task]
            except (KeyError, IndexError, TypeError):
                values = None
            return list(values) if values is not None else [None] * len(success)

        return TaskExecution(i, task, self.task_names[task], [bool(v) for v in success],
                             per_demo("failure_reason"), per_demo("failure_kind"))

    def provenance(self) -> dict[str, dict[str, Any]]:
        """What the run records about how it was made: ``training`` (package versions,
        dataset files and their sha256, seed, CPU) and, when executed, ``execution`` (the
        simulator's fingerprint and versions, env ids, when it was evaluated, rollout counts),
        without the per-point tables."""
        out = {"training": dict(self.results.get("provenance") or {})}
        sim = self.results.get("sim")
        if isinstance(sim, Mapping):
            out["execution"] = {k: v for k, v in sim.items() if k not in _SIM_POINT_KEYS}
        return out


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
