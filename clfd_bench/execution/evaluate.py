"""Score a saved run by execution, without training (``clfd-bench evaluate``).

For every evaluation point (after task ``i``, task ``j <= i``, demo ``d``) :func:`evaluate_run`
executes the saved prediction and writes ``success``, ``sim_accuracy``, ``sim_cl_metrics`` and
a ``sim`` block (provenance, tracking errors, failure reasons and kinds, their counts) into the
run's ``results.json`` (atomically, every other key kept).

Re-running is cheap: results are cached in ``RUN_DIR/sim_cache.json`` (keys:
:mod:`clfd_bench.execution.cache`; the file: :class:`clfd_bench.runs.RunDir`), valid for one
simulator fingerprint. A run whose old tasks' predictions do not change (SG, HN, CHN) executes
each distinct prediction once, a killed evaluation resumes where it stopped, and any change to
the simulator invalidates the cache by itself. ``force=True`` ignores it.
"""

from __future__ import annotations

import dataclasses
import datetime
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from clfd_bench.envs.checks import Check, check_from_json
from clfd_bench.execution.cache import nonfinite_summary, prediction_key
from clfd_bench.execution.env_pool import get_env
from clfd_bench.execution.execute import ExecResult, checks_reason, execute
from clfd_bench.execution.fingerprint import sim_fingerprint, sim_provenance
from clfd_bench.execution.saved_run import SavedRun, load_run, load_run_predictions
from clfd_bench.execution.scoring import failed_check_counts, failure_counts, sim_fields
from clfd_bench.progress import progress
from clfd_bench.runs import RunDir

__all__ = ["EvalPoint", "RolloutObserver", "evaluate_run", "evaluation_points", "worker_init"]


def _run_job(job: tuple[str, str, int, np.ndarray, float | None]) -> tuple[str, dict, float]:
    """Worker side of :func:`evaluate_run`: (key, env id, demo, trajectory, settle) ->
    (key, summary, wall seconds)."""
    key, env_id, demo, traj, settle_s = job
    res = execute(get_env(env_id), traj, demo, settle_s=settle_s)
    return key, res.summary(), res.wall_s


def worker_init() -> None:
    """Initializer of a process executing rollouts: it dies with its parent, shows no
    progress bars and runs torch on one thread."""
    import os

    from clfd_bench.procs import die_with_parent

    die_with_parent()  # a killed evaluation leaves no worker behind
    os.environ.setdefault("CLFD_NO_PROGRESS", "1")
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # pragma: no cover - torch is a dependency
        pass


def _env_ids(dataset: str, task_names: Sequence[str]) -> list[str | None]:
    from clfd_bench.envs.registration import env_id_for

    out: list[str | None] = []
    for name in task_names:
        try:
            out.append(env_id_for(dataset, name))
        except KeyError:
            out.append(None)
    return out



@dataclasses.dataclass(frozen=True)
class EvalPoint:
    """One evaluation point of a saved run: the prediction of task ``task`` from demo
    ``demo``'s start, made after learning task ``after_task``.

    Attributes:
        after_task, task, demo: the point (``task <= after_task``).
        env_id: task ``task``'s env.
        key: its rollout-cache key (:func:`clfd_bench.execution.cache.prediction_key`).
        trajectory: the prediction ``[T, D]`` in data units.
    """

    after_task: int
    task: int
    demo: int
    env_id: str
    key: str
    trajectory: np.ndarray


def evaluation_points(run: SavedRun, settle_s: float | None = None) -> list[EvalPoint]:
    """Every evaluation point of ``run`` whose task has an env, in order (after task ``i``,
    task ``j <= i``, demo ``d``), with its cache key for settling time ``settle_s``."""
    env_ids = _env_ids(run.dataset, run.task_names[:run.num_learned])
    out: list[EvalPoint] = []
    for i in range(run.num_learned):
        preds = load_run_predictions(run.path, i)
        for j in range(i + 1):
            env_id = env_ids[j]
            if env_id is None:
                continue
            for d, traj in enumerate(preds[j]):
                out.append(EvalPoint(i, j, d, env_id,
                                     prediction_key(env_id, d, settle_s, traj), traj))
    return out


class RolloutObserver(Protocol):
    """Receives every executed evaluation point with its trace (e.g.
    ``clfd_bench.viz.rerun_log.RolloutLogger``)."""

    def log_rollout(self, entity: str, base: Any, result: ExecResult, prediction: np.ndarray,
                    demonstration: np.ndarray | None = None) -> None: ...


def _task_checks(hit: dict[str, Any]) -> list[Check]:
    """The success checks a cached ``task`` failure stored (empty for any other outcome, or an
    env that reports none)."""
    if hit.get("failure_kind") != "task":
        return []
    return [check_from_json(c) for c in hit.get("checks") or ()]


def _reason(hit: dict[str, Any], checks: list[Check]) -> str | None:
    """A cached execution's failure reason; a task failure decided at the end says it from its
    ``checks`` in today's words (:func:`~clfd_bench.execution.execute.checks_reason`), so a
    cache written before the wording changed reads as a new one."""
    named = None if hit.get("stopped_early") else checks_reason(checks)
    return named if named is not None else hit["failure_reason"]


def evaluate_run(run_dir: str | Path, observer: RolloutObserver | None = None, *,
                 force: bool = False, settle_s: float | None = None,
                 workers: int = 1) -> dict[str, Any]:
    """Scores a saved run by execution, without training.

    For every evaluation point (after task ``i``, task ``j <= i``, demo ``d``) the saved
    prediction (``predictions/after_task_{i}.npz``) is executed in task ``j``'s env; then
    ``results.json`` gains (or has replaced) ``success``, ``sim_accuracy``, ``sim_cl_metrics``
    (see :func:`sim_fields`) and ``sim`` (see :func:`sim_provenance`, plus ``tracking_error``
    ``[i][j][d]`` mean hand position error in m, ``failure_reason``, ``failure_kind`` and
    ``failed_checks`` (names of the success checks a task failure failed), all ``[i][j][d]``;
    ``failure_counts`` {kind: count} and ``failed_check_counts`` {check: count} over every
    point, rollout counts and wall time). Every other key of ``results.json`` is kept as it
    is. Tasks without an env (RoboTasks9's extra tasks) get None and are left out of
    ``sim_cl_metrics``; a prediction
    with NaN/inf counts as a failure without being executed.

    Each distinct (env, demo, prediction) is executed once: identical predictions of a task
    after later tasks (SG, HN, CHN keep them) and points already in ``RUN_DIR/sim_cache.json``
    under the same :func:`sim_fingerprint` are reused. The cache is saved as rollouts finish,
    so an interrupted evaluation resumes.

    Args:
        run_dir: a directory written by ``clfd-bench train``.
        observer: also hand every rollout, with its trace, to this observer (e.g. a rerun
            ``RolloutLogger``); every point is then executed in this process (cached ones
            too, to have their paths).
        force: ignore the execution cache.
        settle_s: seconds of settling after each trajectory (default: the rollout's).
        workers: processes executing rollouts in parallel (1: in this process).

    Returns:
        The fields written into ``results.json``.
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    run = load_run(run_dir)
    run_dir, dataset, names, m = run.path, run.dataset, run.task_names, run.num_learned
    store = RunDir(run_dir)
    if m == 0:
        raise ValueError(f"{store.results_path} has no finished task to evaluate; train at "
                         "least one task first")
    env_ids = _env_ids(dataset, names[:m])
    if not any(env_ids):
        raise ValueError(f"no task of {dataset} {names[:m]} has a simulated env; nothing to "
                         "execute")

    fingerprint = sim_fingerprint()
    cache = {} if force else store.load_cache(fingerprint)
    # Every evaluation point -> its key; the distinct keys still to execute -> their job.
    points: list[tuple[int, int, int, str, np.ndarray]] = []
    jobs: dict[str, tuple[str, str, int, np.ndarray, float | None]] = {}
    for p in evaluation_points(run, settle_s):
        points.append((p.after_task, p.task, p.demo, p.key, p.trajectory))
        if not np.isfinite(p.trajectory).all():
            cache[p.key] = nonfinite_summary(p.demo)
        elif (p.key not in cache or observer is not None) and p.key not in jobs:
            jobs[p.key] = (p.key, p.env_id, p.demo, p.trajectory, settle_s)

    # One task's env after the other: each env is built once (the env cache is bounded).
    first_seen = {env_id: k for k, env_id in enumerate(dict.fromkeys(e for e in env_ids if e))}
    jobs = dict(sorted(jobs.items(), key=lambda kv: (first_seen[kv[1][1]], kv[1][2])))
    t_start = time.perf_counter()
    wall = 0.0
    last_save = time.monotonic()

    def done(key: str, summary: dict[str, Any], seconds: float) -> None:
        nonlocal wall, last_save
        cache[key] = summary
        wall += seconds
        if time.monotonic() - last_save > 5.0:
            store.save_cache(fingerprint, cache)
            last_save = time.monotonic()

    bar = progress(total=len(jobs), desc=f"sim {run_dir.name}", unit="rollout")
    try:
        if observer is not None:
            _execute_observed(run, points, jobs, env_ids, observer, done, bar)
        elif workers == 1 or len(jobs) <= 1:
            for job in jobs.values():
                done(*_run_job(job))
                bar.update(1)
        else:
            import concurrent.futures
            import multiprocessing

            ctx = multiprocessing.get_context("spawn")  # no inherited GL / torch threads
            with concurrent.futures.ProcessPoolExecutor(
                    max_workers=min(workers, len(jobs)), mp_context=ctx,
                    initializer=worker_init) as pool:
                for result in pool.map(_run_job, jobs.values(), chunksize=1):
                    done(*result)
                    bar.update(1)
    finally:
        bar.close()
        store.save_cache(fingerprint, cache)

    success: list[list[list[bool] | None]] = [[None] * m for _ in range(m)]
    track: list[list[list[float | None] | None]] = [[None] * m for _ in range(m)]
    reasons: list[list[list[str | None] | None]] = [[None] * m for _ in range(m)]
    kinds: list[list[list[str | None] | None]] = [[None] * m for _ in range(m)]
    checks: list[list[list[list[str]] | None]] = [[None] * m for _ in range(m)]
    for i, j, _, key, _ in points:
        hit = cache[key]
        stored = _task_checks(hit)
        for table, value in ((success, bool(hit["success"])),
                             (track, hit["mean_tracking_error"]),
                             (reasons, _reason(hit, stored)),
                             (kinds, hit["failure_kind"]),
                             (checks, [c.name for c in stored if not c.passed])):
            if table[i][j] is None:
                table[i][j] = []
            table[i][j].append(value)

    fields = sim_fields(success, scored=[e is not None for e in env_ids])
    sim = sim_provenance(dataset, names[:m])
    sim.update({
        "evaluated_tasks": m,
        "settle_s": settle_s,
        "rollouts": len(points),
        "rollouts_executed": len(jobs),
        "rollouts_cached": len(points) - len(jobs),
        "rollout_wall_s": round(wall, 3),
        "wall_s": round(time.perf_counter() - t_start, 3),
        "evaluated_at": datetime.datetime.now(datetime.timezone.utc).isoformat(
            timespec="seconds"),
        "tracking_error": track,
        "failure_reason": reasons,
        "failure_kind": kinds,
        "failure_counts": failure_counts(kinds),
        "failed_checks": checks,
        "failed_check_counts": failed_check_counts(checks),
    })
    fields["sim"] = sim
    store.write_sim_results(fields)
    return fields


def _execute_observed(run: SavedRun, points, jobs, env_ids, observer: RolloutObserver, done,
                      bar) -> None:
    """Executes ``jobs`` in this process with traces and hands every point to ``observer``."""
    demos = run.demos()
    executed: dict[str, tuple[ExecResult, Any]] = {}
    # Task by task, so each env is built once (the env cache is bounded).
    for i, j, d, key, traj in sorted(points, key=lambda p: (p[1], p[0], p[2])):
        if key not in jobs:  # not executable (NaN/inf): nothing to show
            continue
        if key not in executed:
            env = get_env(env_ids[j])
            res = execute(env, traj, d, trace=True, settle_s=jobs[key][4])
            executed[key] = (res, env.unwrapped)
            done(key, res.summary(), res.wall_s)
            bar.update(1)
        res, base = executed[key]
        observer.log_rollout(f"after_task_{i}/{run.task_names[j]}/demo_{d}", base, res,
                             prediction=traj, demonstration=demos[j][d])
