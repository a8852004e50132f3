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

:func:`train_tasks` runs this loop for several runs in lockstep (runs that differ only in
seed or task order): each keeps its own batches, optimiser, stop rule, hooks and global RNG
state; the task losses of the runs whose batches stack are computed in one pass.

**Task snapshots.** A paper-size task takes hours; :func:`train_tasks` can hand, every
``snapshot_every`` seconds, each run's whole loop state to a callback (weights, the method's
:meth:`~clfd_bench.methods.base.Method.step_state`, optimiser, schedule, stop rule, batch
generator and global RNG, the iteration), and a :class:`TaskRun` given such a snapshot
(``resume``) continues from it. The task's start is replayed first (``add_task`` and
``on_task_start`` on the task's starting weights, the RNGs seeded as for a fresh start),
then the snapshot is loaded, so the task ends bit for bit where the uninterrupted one does.

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

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import torch
from torch import Tensor

from clfd_bench.harness.config import PartConfig
from clfd_bench.learning.batches import BatchSampler
from clfd_bench.learning.fields import Field
from clfd_bench.learning.objective import (
    batch_spec,
    solver_spec,
    stack_key,
    stacked_trajectory_losses,
    trajectory_loss,
)
from clfd_bench.learning.part_config import REFINE_MAX_SUBSTEPS
from clfd_bench.learning.stop_rule import StopRule
from clfd_bench.methods.base import Method, StepContext, TaskData
from clfd_bench.progress import progress

__all__ = [
    "TaskRun",
    "TrainingDivergedError",
    "TrainStats",
    "batch_spec",
    "finished_snapshot",
    "lr_factor",
    "solver_blew_up",
    "solver_spec",
    "stop_rule",
    "train_task",
    "train_tasks",
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
        substeps: the solver steps per interval the task ended with (``cfg.substeps``, more
            where ``refine_gap`` refined it).
        refine_gaps: with ``refine_gap`` on, the solver gap measured each time the stop rule
            ended the task (positions: data units; orientations: degrees); empty when off.
    """

    seconds: float
    iterations: int
    final_loss: float
    loop_seconds: float
    substeps: int = 1
    refine_gaps: tuple[float, ...] = ()

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


def stop_rule(cfg: PartConfig, start: int | None = None) -> StopRule | None:
    """The stop rule of ``cfg`` (None: ``stop_window = 0``, off). Its first window starts
    at ``start``; by default when the learning-rate warm-up and the growth of a
    ``trajectories`` batch's horizon are over."""
    if cfg.stop_window <= 0:
        return None
    if start is None:
        begin = cfg.lr_warmup * cfg.iterations
        if cfg.batch == "trajectories" and cfg.horizon_start < 1.0:
            begin = max(begin, cfg.horizon_ramp * cfg.iterations)
        start = math.ceil(begin)
    return StopRule(cfg.stop_window, cfg.stop_rel, cfg.stop_decays, start)


@dataclass
class TaskRun:
    """One run's share of a lockstep training (:func:`train_tasks`): the arguments of
    :func:`train_task`, the global torch RNG state the run's hooks see (None: the current
    one; runs trained together each keep their own), and ``resume``: a snapshot of this task
    to continue from (``train_tasks``' ``on_snapshot``, or :func:`finished_snapshot`), given
    to a run whose method, data, generator and RNG state are those of the task's start;
    ``gap``: ``gap(substeps)``, the solver gap of the task's model integrated with that many
    steps per interval (:meth:`~clfd_bench.harness.learner.PartLearner.solver_gap`), which
    ``cfg.refine_gap > 0`` needs."""

    method: Method
    task: int
    data: TaskData
    cfg: PartConfig
    generator: torch.Generator
    desc: str = ""
    rng_state: torch.Tensor | None = None
    resume: dict[str, Any] | None = None
    gap: Callable[[int], float | None] | None = None


def finished_snapshot(run: TaskRun, stats: TrainStats) -> dict[str, Any]:
    """The snapshot of a run whose task is learned (``stats``, from :func:`train_tasks`):
    given back as ``resume``, its task is not trained again and ``stats`` is its result.
    The tensors are copies (the method may learn on)."""
    method = run.method
    return {"finished": True,
            "method": {k: v.detach().clone() for k, v in method.state_dict().items()},
            "step_state": method.step_state(),
            "rng": (run.rng_state if run.rng_state is not None
                    else torch.get_rng_state()).clone(),
            "stats": dataclasses.asdict(stats)}


class _Lane:
    """The loop state of one :class:`TaskRun`: optimiser, schedule, stop rule, samplers,
    progress bar, its own global RNG state."""

    def __init__(self, run: TaskRun):
        self.run, self.cfg = run, run.cfg
        resume = run.resume or {}
        now = time.perf_counter()
        self.start = now - float(resume.get("seconds", 0.0))
        self.rng = run.rng_state if run.rng_state is not None else torch.get_rng_state()
        self.spec, self.solver = batch_spec(run.cfg), solver_spec(run.cfg)
        self.samplers: dict[int, BatchSampler] = {}
        self.error: TrainingDivergedError | None = None
        self.stats: TrainStats | None = None
        self.it = 0  # the next iteration
        if resume.get("finished"):
            self._load_finished(resume)
            return
        with self.own_rng():
            run.method.train()
            run.method.on_task_start(run.task, run.data)
        self.optimizer = _adam(run.method.trainable(run.task), run.cfg.lr)
        self.stop = stop_rule(run.cfg)
        cfg = run.cfg
        if cfg.refine_gap > 0 and run.gap is None:
            raise ValueError("refine_gap > 0 needs the task's solver gap (TaskRun.gap)")
        self.substeps, self.refine_gaps = cfg.substeps, []
        self.lr_carry = 1.0  # the lr decays of the rules refining replaced
        if self.stop is None:
            factor = lambda it: lr_factor(cfg, it)  # noqa: E731
        else:  # self.stop, not a local: refining replaces the rule
            factor = lambda it: (  # noqa: E731
                lr_factor(cfg, it) * self.lr_carry * self.stop.lr_scale)
        self.schedule = torch.optim.lr_scheduler.LambdaLR(self.optimizer, factor)
        self.loss_value = float("nan")
        if resume:
            self._load(resume)
        self.bar = progress(total=cfg.iterations, desc=run.desc or f"task {run.task}",
                            initial=self.it)
        self.loop_start = time.perf_counter() - float(resume.get("loop_seconds", 0.0))
        self.done = cfg.iterations
        self.finished = False

    def _load(self, snap: dict[str, Any]) -> None:
        """Continue from a snapshot of an unfinished task (after ``on_task_start``)."""
        run = self.run
        run.method.load_state_dict(snap["method"], strict=True)
        run.method.load_step_state(snap["step_state"])
        self.optimizer.load_state_dict(snap["optimizer"])
        self.schedule.load_state_dict(snap["schedule"])
        if (self.stop is None) != (snap["stop"] is None):
            raise ValueError("the task snapshot was taken with another stop_window setting")
        if self.stop is not None:
            self.stop.load_state(snap["stop"])
        run.generator.set_state(snap["generator"])
        self.rng = snap["rng"]
        self.loss_value = float(snap["loss_value"])
        self.it = int(snap["iteration"])
        refine = snap.get("refine")  # absent: not refined (or a snapshot from before)
        if refine is not None:
            self.stop = stop_rule(self.cfg, int(refine["stop_start"]))
            self.stop.load_state(snap["stop"])
            self._set_substeps(int(refine["substeps"]))
            self.refine_gaps = [float(g) for g in refine["gaps"]]
            self.lr_carry = float(refine["lr_carry"])

    def _load_finished(self, snap: dict[str, Any]) -> None:
        """Take a learned task's snapshot (:func:`finished_snapshot`) as this lane's end."""
        method = self.run.method
        method.load_state_dict(snap["method"], strict=True)
        method.load_step_state(snap["step_state"])
        method.eval()
        self.rng = snap["rng"]
        # a snapshot from before the refinement was recorded: the config's steps
        self.stats = TrainStats(**({"substeps": self.cfg.substeps} | snap["stats"]))
        self.done = self.it = self.stats.iterations
        self.finished = True

    def snapshot(self) -> dict[str, Any] | None:
        """This lane's state between two iterations (None: it failed): what ``resume``
        takes. Unfinished lanes' tensors are the live ones: encode them before the next
        iteration."""
        if self.error is not None:
            return None
        if self.finished:
            run = dataclasses.replace(self.run, rng_state=self.rng)
            return finished_snapshot(run, self.stats)
        now = time.perf_counter()
        method = self.run.method
        snap = {"finished": False, "iteration": self.it, "method": method.state_dict(),
                "step_state": method.step_state(), "optimizer": self.optimizer.state_dict(),
                "schedule": self.schedule.state_dict(),
                "stop": None if self.stop is None else self.stop.state(),
                "generator": self.run.generator.get_state(), "rng": self.rng,
                "loss_value": self.loss_value, "seconds": now - self.start,
                "loop_seconds": now - self.loop_start}
        if self.refine_gaps:
            snap["refine"] = {"substeps": self.substeps, "gaps": list(self.refine_gaps),
                              "stop_start": self.stop.start, "lr_carry": self.lr_carry}
        return snap

    def _set_substeps(self, substeps: int) -> None:
        self.substeps = substeps
        self.solver = dataclasses.replace(self.solver, substeps=substeps)

    def refine(self, it: int, stopped: bool) -> bool:
        """The task ended after iteration ``it`` (``stopped``: by the stop rule, else at the
        cap): with ``refine_gap`` on, measure and record the solver gap; when the stop rule
        ended the task and the gap is above ``refine_gap`` (and steps and iterations are
        left), double the solver steps and give the task a fresh stop rule from the next
        iteration, at the lr the old one left. True: the task trains on."""
        cfg, run = self.cfg, self.run
        if cfg.refine_gap <= 0:
            return False
        with self.own_rng():
            gap = run.gap(self.substeps)
            run.method.train()
        if gap is None:
            return False
        self.refine_gaps.append(gap)
        if (not stopped or gap <= cfg.refine_gap or 2 * self.substeps > REFINE_MAX_SUBSTEPS
                or it + 1 >= cfg.iterations):
            return False
        self._set_substeps(2 * self.substeps)
        # the lr goes on where the old rule left it (the weights are near a solution:
        # refining fine-tunes them, it does not start the task again); the new rule may
        # lower it further
        self.lr_carry *= self.stop.lr_scale
        self.stop = stop_rule(cfg, it + 1)
        self.bar.set_postfix(loss=f"{self.loss_value:.2e}", gap=f"{gap:.3g}",
                             substeps=self.substeps, refresh=False)
        return True

    def own_rng(self):
        """A context in which the global torch RNG is this run's."""
        return _OwnRng(self)

    def batch(self, it: int) -> tuple[Field, Tensor, Tensor]:
        """Pick the task, draw the batch, zero the gradients: ``(field, t, y)``."""
        run = self.run
        with self.own_rng():
            k = run.method.pick_task(run.task, run.generator)
            sampler = self.samplers.get(k)
            if sampler is None:
                source = run.data if k == run.task else run.method.replay_data(k)
                sampler = self.samplers[k] = source.sampler(self.spec, self.cfg.iterations)
            t, y = sampler.sample(it, run.generator)
            self.optimizer.zero_grad(set_to_none=True)
            return run.method.field(k), t, y

    def fail(self, it: int | None, what: str, cause: BaseException | None = None) -> None:
        self.bar.close()
        run = self.run
        self.error = _diverged(run.desc, run.task, it, run.cfg, what)
        self.error.__cause__ = cause
        self.finished = True

    def step(self, it: int, loss: Tensor) -> None:
        """Everything of iteration ``it`` after the task loss's backward pass."""
        run, cfg = self.run, self.cfg
        with self.own_rng():
            ctx = StepContext(task=run.task, iteration=it, optimizer=self.optimizer,
                              generator=run.generator)
            extra = run.method.extra_loss(ctx)
            if extra is not None:
                extra.backward()
            run.method.before_step(ctx)
            self.optimizer.step()
            stopping = self.stop is not None and self.stop.update(it, float(loss.detach()))
            self.schedule.step()
            run.method.after_step()
        if it % 25 == 0 or it == cfg.iterations - 1 or stopping:
            self.loss_value = float(loss.detach())
            if not math.isfinite(self.loss_value):
                self.fail(it, f"the loss is {self.loss_value}")
                return
            self.bar.set_postfix(loss=f"{self.loss_value:.2e}", refresh=False)
        self.bar.update(1)
        if stopping or it == cfg.iterations - 1:
            if self.refine(it, stopping):
                return
            self.done = it + 1
            self.end()

    def end(self) -> None:
        self.bar.close()
        loop_seconds = time.perf_counter() - self.loop_start
        run = self.run
        with self.own_rng():
            run.method.on_task_end(run.task, run.data)
            run.method.eval()
        self.stats = TrainStats(time.perf_counter() - self.start, self.done, self.loss_value,
                                loop_seconds, self.substeps, tuple(self.refine_gaps))
        self.finished = True


class _OwnRng:
    """Swaps a lane's global RNG state in for the duration of a ``with`` block."""

    def __init__(self, lane: _Lane):
        self.lane = lane

    def __enter__(self) -> None:
        self.saved = torch.get_rng_state()
        torch.set_rng_state(self.lane.rng)

    def __exit__(self, *exc) -> None:
        self.lane.rng = torch.get_rng_state()
        torch.set_rng_state(self.saved)


def _losses(lanes: list[_Lane], batches: list[tuple[Field, Tensor, Tensor]]
            ) -> list[Tensor | None]:
    """The task loss of every lane's batch: lanes whose batches stack (same
    :func:`stack_key`) in one pass, the others alone as :func:`trajectory_loss`; None for a
    lane whose solver failed (marked failed)."""
    groups: dict[object, list[int]] = {}
    for i, (lane, (field, t, y)) in enumerate(zip(lanes, batches, strict=True)):
        key = stack_key(field, t, y, lane.solver)
        groups.setdefault(i if key is None else key, []).append(i)
    losses: list[Tensor | None] = [None] * len(lanes)
    for members in groups.values():
        if len(members) > 1:
            parts = [batches[i] for i in members]
            values = stacked_trajectory_losses([p[0] for p in parts], [p[1] for p in parts],
                                               [p[2] for p in parts], lanes[members[0]].solver)
            for i, value in zip(members, values, strict=True):
                losses[i] = value
            continue
        i = members[0]
        field, t, y = batches[i]
        try:
            losses[i] = trajectory_loss(field, t, y, lanes[i].solver)
        except (FloatingPointError, AssertionError, RuntimeError) as exc:
            if not solver_blew_up(exc):
                raise
            lanes[i].fail(lanes[i].it, f"the ODE solver failed ({exc})", exc)
    return losses


def train_tasks(runs: list[TaskRun], *, snapshot_every: float = 0.0,
                on_snapshot: Callable[[list[dict[str, Any] | None]], None] | None = None,
                ) -> list[TrainStats | TrainingDivergedError]:
    """Learn several runs' tasks in lockstep: the same loop as :func:`train_task` for each
    run, with the task losses of the runs whose batches stack computed in one pass and
    back-propagated together (:func:`~clfd_bench.learning.objective.stacked_trajectory_losses`;
    each run's loss depends on its own weights only, so each run gets its own gradient).
    Everything else is each run's own: its batches and task picks (its generator), its
    optimiser, schedule and stop rule (a run that stops leaves the others going), its hooks,
    run with its own global RNG state. Each run's result is :func:`train_task`'s for it
    alone, bit for bit (the stacked pass is used only where it is exact: see
    :func:`~clfd_bench.learning.objective.stacked_trajectory_losses`). Runs resumed from
    snapshots may be at different iterations; each keeps its own count.

    Args:
        snapshot_every: seconds between two calls of ``on_snapshot`` (0: never).
        on_snapshot: called between two iterations with every run's snapshot (None for a
            run that failed; see :class:`TaskRun`'s ``resume``), while a run is unfinished.
            It must encode the tensors before it returns.

    Returns:
        per run, its :class:`TrainStats`, or the :class:`TrainingDivergedError` that ended it
        (the other runs go on).
    """
    lanes = [_Lane(run) for run in runs]
    last_snapshot = time.perf_counter()
    while True:
        active = [lane for lane in lanes if not lane.finished]
        if not active:
            break
        batches = [lane.batch(lane.it) for lane in active]
        losses = _losses(active, batches)
        live = [(lane, loss) for lane, loss in zip(active, losses, strict=True)
                if loss is not None]
        if live:
            total = live[0][1] if len(live) == 1 else torch.stack([v for _, v in live]).sum()
            total.backward()
        for lane, loss in live:
            lane.step(lane.it, loss)
            lane.it += 1
        if (on_snapshot is not None and snapshot_every > 0
                and time.perf_counter() - last_snapshot >= snapshot_every
                and any(not lane.finished for lane in lanes)):
            on_snapshot([lane.snapshot() for lane in lanes])
            last_snapshot = time.perf_counter()
    for run, lane in zip(runs, lanes, strict=True):
        run.rng_state = lane.rng
    return [lane.error if lane.error is not None else lane.stats for lane in lanes]


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
    run = TaskRun(method, task, data, cfg, generator, desc)
    (result,) = train_tasks([run])
    torch.set_rng_state(run.rng_state)  # where the run's hooks left the global RNG
    if isinstance(result, TrainingDivergedError):
        raise result
    return result
