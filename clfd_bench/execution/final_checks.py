"""Every executed prediction of saved runs with its env's final checks (the input of the
borderline gallery, :mod:`clfd_bench.execution.borderline`).

:func:`gather_executions` scores each run by execution first (:func:`evaluate_run`, which
executes only what the run's ``sim_cache.json`` lacks; a cache written before executions kept
their checks is of an older schema and is executed again), then reads every evaluation point's
summary from the cache. A rollout that stopped on a decided failure has checks of its partial
episode only, so its prediction is run once more to the horizon (same success, whole-episode
checks) and that execution is cached too, under its own key
(:func:`clfd_bench.execution.cache.prediction_key` with ``to_horizon=True``).
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from clfd_bench.envs.checks import check_from_json
from clfd_bench.execution.borderline import Execution
from clfd_bench.execution.cache import prediction_key
from clfd_bench.execution.env_pool import get_env
from clfd_bench.execution.evaluate import EvalPoint, evaluate_run, evaluation_points
from clfd_bench.execution.execute import execute
from clfd_bench.execution.fingerprint import sim_fingerprint
from clfd_bench.execution.saved_run import SavedRun, load_run
from clfd_bench.progress import progress
from clfd_bench.runs import RunDir

__all__ = ["Gathered", "gather_executions"]

#: Failure kinds whose rollout still ran to its horizon (the checks describe the episode).
_WHOLE_EPISODE_KINDS = (None, "task")


@dataclasses.dataclass
class Gathered:
    """What :func:`gather_executions` found.

    Attributes:
        executions: every executed evaluation point with checks, and those whose episode
            ended early (incomplete, with or without checks) (label: ``run`` path,
            ``method``, ``dataset``, ``task`` name, ``task_index``, ``after_task``, ``demo``,
            ``env_id``, ``prediction_key``).
        runs: the runs read, in order.
        skipped: runs left out, with the reason (path -> text).
        no_checks: env ids whose whole-episode executions report no checks (their envs do
            not fill ``info["checks"]``), with how many distinct executions.
        executed_to_horizon: rollouts run again to the horizon in this call.
        wall_s: wall-clock seconds of the whole call.
    """

    executions: list[Execution]
    runs: list[SavedRun]
    skipped: dict[str, str]
    no_checks: dict[str, int]
    executed_to_horizon: int
    wall_s: float


def gather_executions(run_dirs: Sequence[str | os.PathLike[str]], *, workers: int = 1,
                      settle_s: float | None = None) -> Gathered:
    """Executes what the runs' caches lack and returns every execution with its checks.

    Args:
        run_dirs: run directories (e.g. from :func:`clfd_bench.runs.find_runs`).
        workers: processes executing rollouts (:func:`evaluate_run`'s and the to-horizon
            ones).
        settle_s: settling time of the executions (default: the rollout's; the cache keys
            depend on it).

    Returns:
        A :class:`Gathered`. Each run is held (its lock) while it is evaluated, so a run in
        use by another process is skipped with that reason.
    """
    from clfd_bench.runs import RunLockedError

    t0 = time.perf_counter()
    fingerprint = sim_fingerprint()
    executions: list[Execution] = []
    runs: list[SavedRun] = []
    skipped: dict[str, str] = {}
    no_checks: dict[str, set[str]] = {}
    redone = 0
    for run_dir in run_dirs:
        store = RunDir(run_dir)
        try:
            run = load_run(store.path)
            if run.num_learned == 0:
                skipped[str(store.path)] = "no finished task"
                continue
            with store.lock(f"clfd-bench gallery {store.path}"):
                evaluate_run(store.path, workers=workers, settle_s=settle_s)
                run = load_run(store.path)
                cache = store.load_cache(fingerprint)
                points = evaluation_points(run, settle_s)
                redone += _run_to_horizon(store, fingerprint, cache, points, settle_s, workers)
        except (RunLockedError, FileNotFoundError, ValueError, KeyError) as exc:
            skipped[str(store.path)] = str(exc)
            continue
        runs.append(run)
        for p in points:
            summary = cache.get(p.key)
            if summary is None:  # pragma: no cover - evaluate_run filled every key
                continue
            key = p.key
            if summary.get("stopped_early"):
                key = prediction_key(p.env_id, p.demo, settle_s, p.trajectory, to_horizon=True)
                summary = cache[key]
            raw, kind = summary.get("checks"), summary.get("failure_kind")
            if kind == "diverged":  # not executed: nothing was measured
                continue
            complete = kind in _WHOLE_EPISODE_KINDS and not summary.get("stopped_early")
            if raw is None and complete:
                no_checks.setdefault(p.env_id, set()).add(key)
                continue
            # An episode that ended early (motion limit, tracking, reach, collision) may
            # carry no checks: it is kept, incomplete, so that it is counted as left out.
            executions.append(Execution(
                env_id=p.env_id, key=key, checks=tuple(check_from_json(c) for c in raw or ()),
                complete=complete, success=bool(summary.get("success")),
                label=_label(run, p)))
    return Gathered(executions, runs, skipped, {e: len(k) for e, k in no_checks.items()}, redone,
                    time.perf_counter() - t0)


def _label(run: SavedRun, p: EvalPoint) -> dict[str, Any]:
    return {"run": str(run.path), "method": run.method, "dataset": run.dataset,
            "task": run.task_names[p.task], "task_index": p.task, "after_task": p.after_task,
            "demo": p.demo, "env_id": p.env_id, "prediction_key": p.key}


def _run_to_horizon(store: RunDir, fingerprint: str, cache: dict[str, Any],
                    points: Sequence[EvalPoint], settle_s: float | None, workers: int) -> int:
    """Runs every prediction whose cached rollout stopped early once more to its horizon
    (cached under its to-horizon key); returns how many rollouts ran."""
    jobs: dict[str, EvalPoint] = {}
    for p in points:
        summary = cache.get(p.key) or {}
        if not summary.get("stopped_early"):
            continue
        key = prediction_key(p.env_id, p.demo, settle_s, p.trajectory, to_horizon=True)
        if key not in cache and key not in jobs:
            jobs[key] = p
    if not jobs:
        return 0
    bar = progress(total=len(jobs), desc=f"to horizon {Path(store.path).name}", unit="rollout")
    last_save = time.monotonic()
    ordered = [(key, p.env_id, p.demo, p.trajectory, settle_s) for key, p in
               sorted(jobs.items(), key=lambda kv: (kv[1].env_id, kv[1].demo))]
    try:
        if workers == 1 or len(ordered) == 1:
            results: Iterable[tuple[str, dict[str, Any]]] = map(_to_horizon_job, ordered)
            pool = None
        else:
            import concurrent.futures
            import multiprocessing

            from clfd_bench.execution.evaluate import worker_init

            pool = concurrent.futures.ProcessPoolExecutor(
                max_workers=min(workers, len(ordered)),
                mp_context=multiprocessing.get_context("spawn"), initializer=worker_init)
            results = pool.map(_to_horizon_job, ordered, chunksize=1)
        try:
            for key, summary in results:
                cache[key] = summary
                bar.update(1)
                if time.monotonic() - last_save > 5.0:
                    store.save_cache(fingerprint, cache)
                    last_save = time.monotonic()
        finally:
            if pool is not None:
                pool.shutdown(cancel_futures=True)
    finally:
        bar.close()
        store.save_cache(fingerprint, cache)
    return len(jobs)


def _to_horizon_job(job: tuple[str, str, int, Any, float | None]) -> tuple[str, dict[str, Any]]:
    """(key, env id, demo, trajectory, settle) -> (key, summary of the rollout run to its
    horizon)."""
    key, env_id, demo, traj, settle_s = job
    res = execute(get_env(env_id), traj, demo, settle_s=settle_s, stop_when_decided=False)
    return key, res.summary()
