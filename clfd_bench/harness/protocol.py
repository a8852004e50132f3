"""The sequential protocol: learn the tasks in order; after each, predict every seen task.

:func:`run_training` is what a training run runs (:func:`clfd_bench.harness.run.run`, behind
``clfd-bench train`` and the grid's workers). For task ``i`` of the dataset order:

1. seed the RNGs from ``(seed, i)`` (so a resumed run draws the same numbers), add task ``i``
   to every part's model and train it with the one training loop;
2. predict tasks ``0..i`` from each demo's start (in data units) and score them;
3. write ``predictions/after_task_{i}.npz``, then ``checkpoint.pt`` (model + progress), then
   ``results.json`` -- each atomically, through the run directory's owner
   (:class:`clfd_bench.runs.RunDir`).

A run directory that already holds a checkpoint of the same configuration resumes after its
last finished task and ends with the same results as an uninterrupted run; one with a
different configuration is refused.

**Within a task.** While a task is learned, every ``snapshot_every`` seconds (default
:data:`SNAPSHOT_EVERY_S`) and after each of its parts, the run writes ``task_snapshot.pt``
(the loop state of :func:`clfd_bench.harness.loop.train_tasks`, the parts already learned,
the task's CPU time so far); the task's checkpoint removes it. A run killed mid-task resumes
from it, after its last finished task has been restored, and ends bit for bit as the
uninterrupted run (on the same CPU and kernels). A paper-size task of hours thus loses at
most minutes when its machine goes. A snapshot of another task than the next one (a kill
between the checkpoint and the snapshot's removal) is stale and removed.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from clfd_bench.data import load_dataset
from clfd_bench.data.types import Dataset
from clfd_bench.harness.checkpoint import (
    decode_checkpoint,
    decode_snapshot,
    encode_checkpoint,
    encode_snapshot,
)
from clfd_bench.harness.config import PartConfig
from clfd_bench.harness.evaluation import (
    SCHEMA_VERSION,
    cpu_provenance,
    dataset_provenance,
    metrics_for,
    package_versions,
    results_document,
    task_errors,
)
from clfd_bench.harness.learner import Learner
from clfd_bench.harness.loop import (
    TaskRun,
    TrainingDivergedError,
    TrainStats,
    finished_snapshot,
    train_tasks,
    warm_up,
)
from clfd_bench.harness.run_config import RunConfig
from clfd_bench.io import json_safe
from clfd_bench.kernels import set_threads
from clfd_bench.runs import CHECKPOINT_FILE, RunDir

__all__ = [
    "SCHEMA_VERSION",
    "SNAPSHOT_EVERY_S",
    "RunMismatchError",
    "TrainingJob",
    "available_cores",
    "default_threads",
    "load_learner",
    "run_training",
    "run_trainings",
    "task_seed",
]

class RunMismatchError(RuntimeError):
    """The output directory holds a run with a different configuration."""


SNAPSHOT_EVERY_S = 600.0
"""Default seconds between two task snapshots: a paper-size RoboTasks snapshot (weights and
Adam's moments) takes about a second to write."""


def available_cores() -> int:
    """CPU cores this process may use (``os.sched_getaffinity``), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def default_threads() -> int:
    """Torch threads for training: 1, unless ``CLFD_THREADS`` says otherwise.

    The NODEs here are small (batches of 8 states), so an iteration is thousands of tiny
    operations and intra-op threads only add synchronisation. Measured on a 2-core machine
    shared with other work: RK4 training of a 3 x 100 NODE took 16 ms per iteration with 1
    thread and 69 ms with 2; the HN fast profile ran at 34 it/s with 1 thread and 0.4 it/s
    with 2 (every parallel region waits for the busy core). Use the cores by running several
    runs (methods, seeds) side by side instead; ``--threads`` overrides this.
    """
    value = os.environ.get("CLFD_THREADS", "")
    return max(1, int(value)) if value.strip() else 1


def task_seed(seed: int, task: int) -> int:
    """The RNG seed used while learning ``task`` of a run seeded with ``seed``."""
    return (int(seed) * 1_000_003 + int(task) * 7_919 + 17) % (2**63 - 1)


def _provenance(config: RunConfig, ds: Dataset, threads: int) -> dict[str, Any]:
    return {
        "packages": package_versions(),
        "dataset": dataset_provenance(ds),
        "seed": config.seed,
        "torch_threads": threads,
        "cpu": cpu_provenance(),
        "cpu_by_task": [],
        "lockstep_by_task": [],
    }


def _saved_cpus(saved: dict[str, Any], done: int) -> list[dict[str, Any] | None]:
    """The CPU of each of a resumed run's ``done`` learned tasks, from its saved provenance
    (``None`` per task for a run saved before ``cpu_by_task`` was recorded: its ``cpu`` was
    only the last process's)."""
    cpus = list(saved.get("cpu_by_task") or [])[:done]
    return cpus + [None] * (done - len(cpus))


def _where(parts: dict[str, dict[str, Any]]) -> dict[str, str]:
    """Where a snapshot's parts stand: {part: "learned" | "iteration N"}."""
    return {kind: ("learned" if p["finished"] else f"iteration {p['iteration']}")
            for kind, p in parts.items()}


def _cpu_change(saved: list[dict[str, Any] | None], now: dict[str, Any]) -> str:
    """Describe how the CPUs (model and kernel capability) of a run's saved tasks differ from
    this process's ``now``; ``""`` when every recorded one matches."""
    def key(cpu: dict[str, Any]) -> tuple[str, str, str]:
        env = ", ".join(f"{k}={v}" for k, v in sorted(cpu.get("kernel_env", {}).items()))
        return str(cpu.get("model")), str(cpu.get("torch_capability")), env

    others = sorted({key(c) for c in saved if c is not None} - {key(now)})
    return "; ".join(f"{m} with {cap} kernels{f' ({env})' if env else ''}"
                     for m, cap, env in others)


def _config_without_tasks(d: dict[str, Any]) -> dict[str, Any]:
    out = {k: v for k, v in d.items() if k not in ("tasks", "overrides")}
    if isinstance(out.get("parts"), dict):  # a key added since the run was saved: its default
        out["parts"] = {name: _PART_DEFAULTS | values for name, values in out["parts"].items()}
    return out


_PART_DEFAULTS = {f.name: list(f.default) if isinstance(f.default, tuple) else f.default
                  for f in dataclasses.fields(PartConfig) if f.default is not dataclasses.MISSING}


def _diff(a: Any, b: Any, prefix: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += _diff(a.get(k), b.get(k), f"{prefix}{k}.")
        return out
    return [] if a == b else [f"{prefix.rstrip('.')}: {a!r} -> {b!r}"]


def _check_same_config(saved: dict[str, Any], config: RunConfig, subject: str) -> None:
    """Refuse to go on with a saved run (a checkpoint, a task snapshot) whose configuration
    differs from ``config`` but for the task count: RunMismatchError("``subject`` a run with a
    different configuration (what differs); ...")."""
    diff = _diff(_config_without_tasks(saved), _config_without_tasks(config.to_dict()))
    if diff:
        raise RunMismatchError(f"{subject} a run with a different configuration "
                               f"({'; '.join(diff)}); use another --out directory or delete "
                               "this one")


def _empty_state(task_names: list[str], metrics: tuple[str, ...], parts: list[str]) -> dict:
    return {
        "tasks": task_names,
        "train_time_s": [],
        "train_cpu_s": [],
        "train_time_s_by_part": {p: [] for p in parts},
        "iterations_per_s_by_part": {p: [] for p in parts},
        "iterations_by_part": {p: [] for p in parts},
        "final_loss_by_part": {p: [] for p in parts},
        "solver_gap_by_part": {p: [] for p in parts},
        "substeps_by_part": {p: [] for p in parts},
        "refine_gaps_by_part": {p: [] for p in parts},
        "num_params": [],
        "num_params_by_part": {p: [] for p in parts},
        "stored_samples": [],
        "errors": {m: [] for m in metrics},
    }


def _results(config: RunConfig, ds: Dataset, state: dict, complete: bool,
             provenance: dict) -> dict[str, Any]:
    return results_document(config.to_dict(), ds.name, ds.tasks, state, complete=complete,
                            provenance=provenance, checkpoint=CHECKPOINT_FILE)


def _checkpoint_payload(learner: Learner) -> tuple[dict[str, Any], dict[str, torch.Tensor]]:
    headers, tensors = {}, {}
    for kind, part in learner.parts.items():
        headers[kind] = part.header()
        for name, t in part.method.state_dict().items():
            tensors[f"{kind}/{name}"] = t
    return headers, tensors


def load_learner(run_dir: str | os.PathLike[str], *,
                 threads: int | None = None) -> tuple[Learner, dict[str, Any]]:
    """Rebuild the trained model of a run from its checkpoint -> ``(learner, header)``.

    Also sets torch's CPU threads to ``threads`` (default :func:`default_threads`, i.e. 1):
    predicting runs the same thousands of tiny operations as training, and with torch's
    default of one thread per core a prediction beside another busy process ran ~4x slower
    (an sNODE's LASA predictions over 50x the demo's duration, 101 starts: 5 min 12 s for one
    shape with two threads, against 16 s per 10x with one).
    """
    set_threads(threads or default_threads())
    run = RunDir(run_dir)
    header, tensors = decode_checkpoint(run.read_checkpoint(), str(run.checkpoint_path))
    config = RunConfig.from_dict(header["config"])
    learner = Learner.from_config(config, header["dim"])
    for kind, part in learner.parts.items():
        prefix = f"{kind}/"
        part.restore(header["parts"][kind],
                     {k[len(prefix):]: v for k, v in tensors.items() if k.startswith(prefix)})
    return learner, header


@dataclass(frozen=True)
class TrainingJob:
    """One run of :func:`run_trainings`: the arguments of :func:`run_training` that are the
    run's own.

    Attributes:
        config: the resolved run configuration. out_dir: the run directory. log: where its
            one-line summaries go (None: silent). after_task: called with the task index
            after each of its finished tasks. keep_checkpoints: keep every task's checkpoint.
            snapshot_every: seconds between two task snapshots (0: none; None:
            :data:`SNAPSHOT_EVERY_S`; module docstring).
    """

    config: RunConfig
    out_dir: str | os.PathLike[str]
    log: Callable[[str], None] | None = print
    after_task: Callable[[int], Any] | None = None
    keep_checkpoints: bool = False
    snapshot_every: float | None = None


class _ProtocolRun:
    """One run of the protocol, task by task: its run directory, learner and results state
    (resumed from the directory's checkpoint), then per task the training units of its
    parts (:meth:`part_run`) and what follows training (:meth:`finish_task`)."""

    def __init__(self, job: TrainingJob, threads: int):
        self.job, self.log = job, job.log
        run = self.run = RunDir(job.out_dir)
        out = run.path
        config = job.config
        ds = self.ds = load_dataset(config.dataset, order=config.order)
        n_tasks = self.n_tasks = len(ds) if config.tasks is None else min(config.tasks, len(ds))
        config = self.config = dataclasses.replace(config, tasks=n_tasks)
        tasks = self.tasks = ds.tasks[:n_tasks]
        self.dim = tasks[0].dim
        metrics = self.metrics = metrics_for(tasks[0].is_pose)
        log = job.log

        torch.manual_seed(config.seed)
        learner = self.learner = Learner.from_config(config, self.dim)
        parts = list(learner.parts)
        state = _empty_state([t.name for t in tasks], metrics, parts)
        provenance = self.provenance = _provenance(config, ds, threads)
        if run.has_checkpoint():
            header, tensors = decode_checkpoint(run.read_checkpoint(), str(run.checkpoint_path))
            _check_same_config(header["config"], config, f"{out} holds")
            for kind, part in learner.parts.items():
                prefix = f"{kind}/"
                part.restore(header["parts"][kind], {k[len(prefix):]: v for k, v in
                                                     tensors.items() if k.startswith(prefix)})
            saved_state = header["state"]
            done = len(saved_state["train_time_s"])
            # runs saved before the stop rule existed ran every iteration of every task
            saved_state.setdefault("iterations_by_part", {
                kind: [config.part(kind).iterations] * done for kind in learner.parts})
            # runs saved before the solver gap was measured: unknown for their tasks
            saved_state.setdefault("solver_gap_by_part", {
                kind: [None] * done for kind in learner.parts})
            # runs saved before refine_gap existed: every task at the config's steps
            saved_state.setdefault("substeps_by_part", {
                kind: [config.part(kind).substeps] * done for kind in learner.parts})
            saved_state.setdefault("refine_gaps_by_part", {
                kind: [[] for _ in range(done)] for kind in learner.parts})
            if done > n_tasks:
                raise RunMismatchError(
                    f"{out} already holds {done} learned tasks, more than the {n_tasks} asked "
                    "for; use another --out directory"
                )
            # the CPU each saved task was learned on (None: a run saved before this was recorded)
            saved_prov = header.get("provenance") or {}
            provenance["cpu_by_task"] = _saved_cpus(saved_prov, done)
            provenance["lockstep_by_task"] = (list(saved_prov.get("lockstep_by_task") or [])
                                              + [1] * done)[:done]
            moved = _cpu_change(provenance["cpu_by_task"], provenance["cpu"])
            if log and moved and done < n_tasks:
                log(f"warning: {out} was learned on another CPU or kernel setting ({moved}); "
                    "its results will mix those float kernels with this one's "
                    "(provenance.cpu_by_task records which task was learned where; seeds "
                    "reproduce a run on one CPU only)")
            saved_state["tasks"] = state["tasks"]
            # a run saved before CPU time was recorded: unknown for its finished tasks
            saved_state["train_cpu_s"] = (list(saved_state.get("train_cpu_s") or [])
                                          + [None] * done)[:done]
            for metric in metrics:  # widen saved rows to the (possibly larger) task count
                saved_state["errors"][metric] = [
                    (row + [None] * n_tasks)[:n_tasks] for row in saved_state["errors"][metric]
                ]
            state = saved_state
            if log and done < n_tasks:
                log(f"resuming {out} after task {done - 1} ({done}/{n_tasks} tasks done)")
        else:
            out.mkdir(parents=True, exist_ok=True)
            done = 0
        self.state, self.done = state, done
        self.label = f"{config.method}/{config.dataset}"
        self._times: dict[str, float] = {}
        self.snapshot_parts: dict[str, dict[str, Any]] = {}  # task `done`'s, by part
        self.snapshot_cpu_s = 0.0  # the CPU time of task `done` before this process
        provenance.setdefault("resumed_in_task", [])
        if done < n_tasks:
            self._read_snapshot()

    def _read_snapshot(self) -> None:
        """Take up ``task_snapshot.pt`` if it is of task ``done`` (a stale one is removed)."""
        run, done = self.run, self.done
        if not run.has_task_snapshot():
            return
        body = decode_snapshot(run.read_task_snapshot(), str(run.task_snapshot_path))
        if body.get("task") != done:
            if self.log:
                self.log(f"{run.task_snapshot_path} is of task {body.get('task')}, not of "
                         f"the next task {done}: removed")
            run.clear_task_snapshot()
            return
        _check_same_config(json.loads(body["config"]), self.config,
                           f"{run.task_snapshot_path} is of")
        self.snapshot_parts = dict(body["parts"])
        self.snapshot_cpu_s = float(body["cpu_s"])
        where = _where(self.snapshot_parts)
        self.provenance["resumed_in_task"].append(
            {"task": done, "parts": where, "cpu": body.get("cpu")})
        if self.log:
            parts = ", ".join(f"{kind} {w}" for kind, w in where.items())
            self.log(f"resuming {run.path} in task {done} ({self.tasks[done].name}) from its "
                     f"snapshot: {parts}")
            moved = _cpu_change([body.get("cpu")], self.provenance["cpu"])
            if moved:
                self.log(f"warning: task {done} was begun on another CPU or kernel setting "
                         f"({moved}); it will end on this one's float kernels")

    def write_snapshot(self, i: int, parts: dict[str, dict[str, Any]], cpu_s: float) -> None:
        """Write task ``i``'s snapshot: ``parts`` (the loop's, by part) over the parts already
        learned; ``cpu_s``: this process's CPU time on the task so far."""
        body = {"task": i, "config": json.dumps(json_safe(self.config.to_dict())),
                "cpu_s": self.snapshot_cpu_s + cpu_s, "cpu": self.provenance["cpu"],
                "parts": self.snapshot_parts | parts}
        note = {"task": i, "task_name": self.tasks[i].name, "parts": _where(body["parts"]),
                "cpu_s": round(body["cpu_s"], 1)}
        self.run.write_task_snapshot(encode_snapshot(body), note)

    def part_learned(self, i: int, unit: TaskRun, kind: str, stats: TrainStats,
                     cpu_s: float) -> None:
        """Part ``kind`` learned task ``i`` (``unit``): kept for the task's snapshot, which is
        written at once when another part of the task is still to learn."""
        self.snapshot_parts[kind] = finished_snapshot(unit, stats)
        if set(self.snapshot_parts) != set(self.learner.parts):
            self.write_snapshot(i, {}, cpu_s)

    def part_run(self, i: int, kind: str) -> TaskRun:
        """Task ``i`` added to part ``kind``'s model, with the RNGs seeded from
        ``(seed, i)``: what the training loop runs for it."""
        task = self.tasks[i]
        seed_i = task_seed(self.config.seed, i)
        part = self.learner.parts[kind]
        torch.manual_seed(seed_i)
        generator = torch.Generator().manual_seed(seed_i + 1)
        data = part.add_next(i, task)
        # handed over, not kept: a learned part comes back through part_learned
        resume = self.snapshot_parts.pop(kind, None) if i == self.done else None

        def gap(substeps: int) -> float | None:  # what refine_gap compares
            return self.learner.solver_gap(kind, i, task, substeps=substeps)

        return TaskRun(part.method, i, data, part.cfg, generator,
                       f"{self.label} {kind} task {i} {task.name}", torch.get_rng_state(),
                       resume, gap)

    def record_part(self, kind: str, stats: TrainStats, share: int = 1) -> None:
        """What training part ``kind`` on the current task took; ``share``: the runs it was
        learned with in lockstep, whose wall time is divided between them (the run's share;
        so a run's seconds and it/s do not depend on how many runs shared its process)."""
        if share > 1:
            stats = dataclasses.replace(stats, seconds=stats.seconds / share,
                                        loop_seconds=stats.loop_seconds / share)
        state = self.state
        self._times[kind] = stats.seconds
        state["train_time_s_by_part"][kind].append(stats.seconds)
        state["iterations_per_s_by_part"][kind].append(stats.iterations_per_s)
        state["iterations_by_part"][kind].append(stats.iterations)
        state["final_loss_by_part"][kind].append(stats.final_loss)
        state["substeps_by_part"][kind].append(stats.substeps)
        state["refine_gaps_by_part"][kind].append(list(stats.refine_gaps))
        state["num_params_by_part"][kind].append(self.learner.parts[kind].method.num_params())

    def finish_task(self, i: int, cpu_s: float, lockstep: int) -> None:
        """After every part learned task ``i``: predict tasks ``0..i``, score them, write the
        predictions, the checkpoint and ``results.json``, then the run's ``after_task``.

        Args:
            cpu_s: the CPU time of training the task (a lockstep batch's, shared equally).
            lockstep: how many runs trained the task together (1: alone).
        """
        state, learner, tasks, n_tasks = self.state, self.learner, self.tasks, self.n_tasks
        task = tasks[i]
        cpu_s += self.snapshot_cpu_s
        self.provenance["cpu_by_task"].append(self.provenance["cpu"])
        self.provenance["lockstep_by_task"].append(lockstep)
        state["train_time_s"].append(sum(self._times.values()))
        self._times = {}
        state["train_cpu_s"].append(cpu_s)
        state["num_params"].append(sum(p.method.num_params() for p in learner.parts.values()))
        state["stored_samples"].append(
            max(p.method.stored_samples() for p in learner.parts.values())
        )
        preds = []
        for metric in self.metrics:
            state["errors"][metric].append([None] * n_tasks)
        for j in range(i + 1):
            tj = tasks[j]
            pred = learner.predict(j, tj.demos[:, 0], tj.times, learner.demo_goals(tj))
            preds.append(pred)
            for metric, values in task_errors(tj, pred).items():
                state["errors"][metric][i][j] = values
        substeps = {kind: values[-1] for kind, values in state["substeps_by_part"].items()}
        for kind, gap in learner.solver_gaps(i, task, preds[i], substeps).items():
            state["solver_gap_by_part"][kind].append(gap)
        self.run.save_predictions(i, preds)
        headers, tensors = _checkpoint_payload(learner)
        header = json_safe({"config": self.config.to_dict(), "dim": self.dim, "parts": headers,
                            "state": state, "provenance": self.provenance})
        self.run.write_checkpoint(encode_checkpoint(header, tensors),
                                  keep_as=i if self.job.keep_checkpoints else None)
        self.run.clear_task_snapshot()
        self.snapshot_parts, self.snapshot_cpu_s = {}, 0.0
        results = _results(self.config, self.ds, state, complete=i == n_tasks - 1,
                           provenance=self.provenance)
        self.run.write_training_results(results)
        self.done = i + 1
        if self.log:
            self.log(_summary_line(self.config, task.name, i, n_tasks, state, results))
        if self.job.after_task is not None:
            self.job.after_task(i)

    def results(self) -> dict[str, Any]:
        """Write and return the final ``results.json``."""
        results = _results(self.config, self.ds, self.state, complete=True,
                           provenance=self.provenance)
        return self.run.write_training_results(results)


def run_trainings(jobs: Sequence[TrainingJob], *, threads: int | None = None
                  ) -> list[dict[str, Any] | Exception]:
    """Run (or resume) several runs of the protocol in lockstep, in this process: task ``i``
    of every run that needs it is learned by one :func:`~clfd_bench.harness.loop.train_tasks`
    (the runs' task losses computed together where they stack), then each run predicts,
    scores and writes its files as :func:`run_training` does. Runs may resume at different
    tasks (a run waits until the others reach its next task). Meant for runs that differ
    only in seed or task order; any runs are correct together.

    A run that fails (diverged training, a directory holding another run, an exception of
    its ``after_task``) stops there, its finished tasks kept, and the others go on.

    Returns:
        per job, its final ``results.json``, or the exception that stopped it.
    """
    threads = threads or default_threads()
    set_threads(threads)
    runs: list[_ProtocolRun | None] = []
    outcome: list[dict[str, Any] | Exception | None] = []
    for job in jobs:
        try:
            runs.append(_ProtocolRun(job, threads))
            outcome.append(None)
        except Exception as exc:  # noqa: BLE001 - this run's failure, reported as its outcome
            runs.append(None)
            outcome.append(exc)

    def alive(k: int) -> bool:
        return runs[k] is not None and outcome[k] is None

    pending = [k for k in range(len(jobs)) if alive(k) and runs[k].done < runs[k].n_tasks]
    if pending:
        warm_up()
    for i in range(min((runs[k].done for k in pending), default=0),
                   max((runs[k].n_tasks for k in pending), default=0)):
        active = [k for k in range(len(jobs))
                  if alive(k) and runs[k].done == i and i < runs[k].n_tasks]
        if not active:
            continue
        cpu_start = time.process_time()

        def cpu_share(n: int = len(active), start: float = cpu_start) -> float:
            return (time.process_time() - start) / max(1, n)

        for kind in dict.fromkeys(kind for k in active for kind in runs[k].learner.parts):
            members = [k for k in active if alive(k) and kind in runs[k].learner.parts]
            units = [runs[k].part_run(i, kind) for k in members]

            def on_snapshot(snaps: list[dict[str, Any] | None], members: list[int] = members,
                            kind: str = kind, i: int = i) -> None:
                for k, snap in zip(members, snaps, strict=True):
                    if snap is not None and alive(k):
                        runs[k].write_snapshot(i, {kind: snap}, cpu_share())

            every = min((SNAPSHOT_EVERY_S if jobs[k].snapshot_every is None
                         else jobs[k].snapshot_every for k in members), default=0.0)
            results = train_tasks(units, snapshot_every=every, on_snapshot=on_snapshot)
            for k, unit, result in zip(members, units, results, strict=True):
                if isinstance(result, TrainingDivergedError):
                    outcome[k] = result
                else:
                    runs[k].record_part(kind, result, share=len(members))
                    if every > 0:
                        runs[k].part_learned(i, unit, kind, result, cpu_share())
        trained = [k for k in active if alive(k)]
        cpu_s = cpu_share()
        for k in trained:
            try:
                runs[k].finish_task(i, cpu_s, len(active))
            except Exception as exc:  # noqa: BLE001 - stops this run only
                outcome[k] = exc
    for k in range(len(jobs)):
        if alive(k):
            outcome[k] = runs[k].results()
    return outcome  # type: ignore[return-value]


def run_training(
    config: RunConfig,
    out_dir: str | os.PathLike[str],
    *,
    threads: int | None = None,
    log: Callable[[str], None] | None = print,
    after_task: Callable[[int], None] | None = None,
    keep_checkpoints: bool = False,
    snapshot_every: float | None = None,
) -> dict[str, Any]:
    """Run (or resume) the sequential protocol and return the results dict.

    Args:
        config: the resolved run configuration.
        out_dir: the run directory (created if missing).
        threads: torch CPU threads (default: :func:`default_threads`, i.e. 1).
        log: where the one-line summaries go (None: silent).
        after_task: called with the task index after each finished task (after all files
            are written); an exception from it stops the run, which can then be resumed.
        keep_checkpoints: also keep ``checkpoints/after_task_{i}.pt`` for every task.
        snapshot_every: seconds between two snapshots of the task being learned (0: none;
            None: :data:`SNAPSHOT_EVERY_S`).

    Raises:
        RunMismatchError: ``out_dir`` holds a run with a different configuration.
        TrainingDivergedError: training diverged (the tasks finished before stay).
    """
    (result,) = run_trainings(
        [TrainingJob(config, out_dir, log, after_task, keep_checkpoints, snapshot_every)],
        threads=threads)
    if isinstance(result, Exception):
        raise result
    return result


def _summary_line(config: RunConfig, name: str, i: int, n: int, state: dict,
                  results: dict) -> str:
    units = results["units"]["dtw"]
    scale, shown = (100.0, "cm") if units == "m" else (1.0, units)
    seen = [np.nanmean([np.nan if x is None else x for x in row])
            for row in state["errors"]["dtw"][i][: i + 1]]
    acc = results["accuracy"].get("dtw")
    acc_txt = ""
    if acc:
        r = np.array([[np.nan if v is None else v for v in row] for row in acc])
        acc_txt = f", ACC(dtw) so far {np.nanmean(r[np.tril_indices(i + 1)]):.2f}"
    speeds = ", ".join(
        f"{v[-1]:.0f} it/s" for v in state["iterations_per_s_by_part"].values()
    )
    stopped = [f"{kind} stopped at {its[-1]}/{config.part(kind).iterations} it"
               for kind, its in state["iterations_by_part"].items()
               if config.part(kind).stop_window > 0]
    if stopped:
        speeds += "; " + ", ".join(stopped)
    gaps = [(kind, values[-1]) for kind, values in state["solver_gap_by_part"].items()
            if values and values[-1] is not None]
    shown_gaps = [f"{kind} {gap * scale:.1f} {shown}" if kind == "position"
                  else f"{kind} {gap:.1f} deg" for kind, gap in gaps
                  if (gap * scale if kind == "position" else gap) >= 0.1]
    if shown_gaps:  # display precision, not a verdict (results.json has every value)
        speeds += ("; the fine solution is off the training solver's by "
                   + ", ".join(shown_gaps))
    return (
        f"[{config.method} {config.dataset} seed {config.seed}] task {i + 1}/{n} {name!r}: "
        f"trained in {state['train_time_s'][-1]:.1f}s ({speeds}); mean DTW of seen tasks "
        f"{np.mean(seen) * scale:.1f} {shown}{acc_txt}"
    )
