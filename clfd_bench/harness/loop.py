"""THE training loop: every method learns every task through :func:`train_task`.

One iteration::

    k = method.pick_task(task)                  # REP may pick an earlier task
    t, y = batch of task k                      # [L], [N, L, D]
    y_hat = integrate(method.field(k), y[:, 0], t)
    loss = mean((y_hat - y)^2)                  # the original code's MSE (trajectory_loss)
    loss.backward()
    extra = method.extra_loss(ctx)              # SI / MAS penalty, HN/CHN look-ahead regulariser
    extra.backward()
    method.before_step(ctx)                     # may edit .grad (A-GEM projection, PackNet)
    optimizer.step(); schedule.step(); method.after_step()
    stop rule (stop_window > 0): may lower the lr, or end the task early

With ``stop_window > 0`` (:mod:`clfd_bench.learning.stop_rule`) ``iterations`` is a cap: the
task ends once its smoothed loss stops improving; :class:`TrainStats` records the iterations
it ran.

The batch and solver specs and the loss are pure functions of :mod:`clfd_bench.learning.objective`
(re-exported here), which methods use too.

A fresh Adam optimiser is created for each task over ``method.trainable(task)``, as in the
original implementation (its separate embedding optimiser had the same learning rate and
Adam's state is per parameter, so one optimiser is the same thing).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import torch

from clfd_bench.harness.config import PartConfig
from clfd_bench.learning.batches import BatchSampler
from clfd_bench.learning.objective import batch_spec, solver_spec, trajectory_loss
from clfd_bench.learning.stop_rule import StopRule
from clfd_bench.methods.base import Method, StepContext, TaskData
from clfd_bench.progress import progress

__all__ = [
    "TrainingDivergedError",
    "TrainStats",
    "batch_spec",
    "lr_factor",
    "solver_blew_up",
    "solver_spec",
    "stop_rule",
    "train_task",
    "warm_up",
]


class TrainingDivergedError(RuntimeError):
    """Training diverged: the loss became NaN or infinite, or the ODE solver failed on the
    model's dynamics. ``task`` is the index of the task being learned (tasks before it are
    finished), ``iteration`` the iteration it was noticed at (None: while predicting)."""

    def __init__(self, message: str, task: int, iteration: int | None = None):
        super().__init__(message)
        self.task, self.iteration = task, iteration


_SOLVER_BLOW_UP = ("underflow in dt", "dopri5 needed more than", "dopri5: non-finite")


def solver_blew_up(exc: BaseException) -> bool:
    """Whether an exception of the ODE solvers means the integrated dynamics diverged
    (non-finite error estimates, a step size that underflows, too many steps)."""
    return isinstance(exc, FloatingPointError | AssertionError | RuntimeError) and str(
        exc
    ).startswith(_SOLVER_BLOW_UP)


def _diverged(desc: str, task: int, it: int, cfg: PartConfig, what: str) -> TrainingDivergedError:
    return TrainingDivergedError(
        f"training diverged ({desc or f'task {task}'}): {what} at iteration {it}; lower lr "
        f"(now {cfg.lr:g}, e.g. --set lr={cfg.lr / 10:g}) or use a more accurate solver",
        task, it,
    )


@dataclass(frozen=True)
class TrainStats:
    """What one task's training took.

    Attributes:
        seconds: wall time of the whole task (hooks included, e.g. MAS importances).
        iterations: optimiser steps (below ``cfg.iterations`` when the stop rule ended the
            task early).
        final_loss: the task loss at the last iteration.
        loop_seconds: wall time of the iterations alone.
    """

    seconds: float
    iterations: int
    final_loss: float
    loop_seconds: float

    @property
    def iterations_per_s(self) -> float:
        """Iterations per second of the training loop (hooks excluded)."""
        return self.iterations / self.loop_seconds if self.loop_seconds > 0 else float("nan")


def _adam(params: list[torch.nn.Parameter], lr: float) -> torch.optim.Adam:
    """Adam with torch's fused CPU kernel where available (same update, one memory pass)."""
    try:
        return torch.optim.Adam(params, lr=lr, fused=True)
    except (RuntimeError, TypeError, ValueError):  # pragma: no cover - older torch
        return torch.optim.Adam(params, lr=lr)


def warm_up() -> None:
    """Pay one-time costs (torch imports its compiler stack when the first optimiser is
    built, seconds on a busy machine) before anything is timed."""
    _adam([torch.nn.Parameter(torch.zeros(1))], 1e-3)


def lr_factor(cfg: PartConfig, iteration: int) -> float:
    """Learning rate of step ``iteration`` (0-based) of a task over ``cfg.lr``: the schedule
    (``constant`` 1, ``cosine`` from 1 to ``lr_min_factor``) times the linear warm-up
    ``min(1, (iteration + 1) / n)`` over the first ``n = lr_warmup * iterations`` steps."""
    factor = 1.0
    if cfg.lr_schedule == "cosine":
        progress_frac = iteration / max(1, cfg.iterations)
        cos = 0.5 * (1.0 + math.cos(math.pi * progress_frac))
        factor = cfg.lr_min_factor + (1.0 - cfg.lr_min_factor) * cos
    warmup = cfg.lr_warmup * cfg.iterations
    if warmup > 0:
        factor *= min(1.0, (iteration + 1) / warmup)
    return factor


def stop_rule(cfg: PartConfig) -> StopRule | None:
    """The stop rule of ``cfg`` (None: ``stop_window = 0``, off). Its first window starts
    when the learning-rate warm-up and the growth of a ``trajectories`` batch's horizon are
    over."""
    if cfg.stop_window <= 0:
        return None
    start = cfg.lr_warmup * cfg.iterations
    if cfg.batch == "trajectories" and cfg.horizon_start < 1.0:
        start = max(start, cfg.horizon_ramp * cfg.iterations)
    return StopRule(cfg.stop_window, cfg.stop_rel, cfg.stop_decays, math.ceil(start))


def train_task(
    method: Method,
    task: int,
    data: TaskData,
    cfg: PartConfig,
    generator: torch.Generator,
    desc: str = "",
) -> TrainStats:
    """Learn ``task`` with ``method`` (``method.add_task()`` must have been called).

    Args:
        method: the CL method (owns the model).
        task: index of the task in the sequence.
        data: the task's normalised demonstrations.
        cfg: the part's hyperparameters.
        generator: the random generator for batches and task picks (seeded per task).
        desc: label of the progress bar.

    Raises:
        TrainingDivergedError: the loss became NaN/inf (lower ``lr``).
    """
    start = time.perf_counter()
    spec, solver = batch_spec(cfg), solver_spec(cfg)
    method.train()
    method.on_task_start(task, data)
    optimizer = _adam(method.trainable(task), cfg.lr)
    stop = stop_rule(cfg)
    if stop is None:
        schedule = torch.optim.lr_scheduler.LambdaLR(optimizer, lambda it: lr_factor(cfg, it))
    else:
        schedule = torch.optim.lr_scheduler.LambdaLR(
            optimizer, lambda it: lr_factor(cfg, it) * stop.lr_scale)
    samplers: dict[int, BatchSampler] = {}
    loss_value = float("nan")
    bar = progress(total=cfg.iterations, desc=desc or f"task {task}")
    loop_start = time.perf_counter()
    done = cfg.iterations
    for it in range(cfg.iterations):
        k = method.pick_task(task, generator)
        sampler = samplers.get(k)
        if sampler is None:
            source = data if k == task else method.replay_data(k)
            sampler = samplers[k] = source.sampler(spec, cfg.iterations)
        t, y = sampler.sample(it, generator)
        optimizer.zero_grad(set_to_none=True)
        try:
            loss = trajectory_loss(method.field(k), t, y, solver)
        except (FloatingPointError, AssertionError, RuntimeError) as exc:
            if not solver_blew_up(exc):
                raise
            bar.close()
            raise _diverged(desc, task, it, cfg, f"the ODE solver failed ({exc})") from exc
        loss.backward()
        ctx = StepContext(task=task, iteration=it, optimizer=optimizer, generator=generator)
        extra = method.extra_loss(ctx)
        if extra is not None:
            extra.backward()
        method.before_step(ctx)
        optimizer.step()
        stopping = stop is not None and stop.update(it, float(loss.detach()))
        schedule.step()
        method.after_step()
        if it % 25 == 0 or it == cfg.iterations - 1 or stopping:
            loss_value = float(loss.detach())
            if not math.isfinite(loss_value):
                bar.close()
                raise _diverged(desc, task, it, cfg, f"the loss is {loss_value}")
            bar.set_postfix(loss=f"{loss_value:.2e}", refresh=False)
        bar.update(1)
        if stopping:
            done = it + 1
            break
    bar.close()
    loop_seconds = time.perf_counter() - loop_start
    method.on_task_end(task, data)
    method.eval()
    return TrainStats(time.perf_counter() - start, done, loss_value, loop_seconds)
