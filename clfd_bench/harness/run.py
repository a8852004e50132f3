"""One run from start to end: its predictions (trained here, or made elsewhere), their
execution in simulation, the scores; the function every way of running a run calls.

:func:`run` is what ``clfd-bench train`` (:mod:`clfd_bench.cli.train`), a grid's workers
(:mod:`clfd_bench.harness.worker`, started by :mod:`clfd_bench.leaderboard.executors`) and
``clfd-bench score`` (:func:`clfd_bench.harness.external.score_predictions`) run. It owns the
run directory for the whole run (its lock: a second writer is refused), has the predictions
made by a :class:`Source` -- :class:`Training` learns the tasks in order
(:func:`~clfd_bench.harness.protocol.run_training`); a scoring of predictions made elsewhere
trains nothing -- and, with simulation, executes every saved prediction not executed yet
(:func:`~clfd_bench.execution.evaluate.evaluate_run`): after each task while training, so a
killed run resumes with the executions of its finished tasks cached, and once at the end for
what is left (a run killed while executing, one trained before without simulation).

The command line and the grid's workers run a training run the same way
(:func:`checked_run`): its inputs checked first, and the same exit codes and one-line
messages at the end (:func:`failure`): 0 done; 2 a bad input or a run directory that is not
this run's or is held by another process; 1 training diverged.
"""

from __future__ import annotations

import os
import sys
import traceback
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from clfd_bench.runs import RunDir

if TYPE_CHECKING:
    from clfd_bench.harness.run_config import RunConfig

__all__ = [
    "Source",
    "TrainSpec",
    "Training",
    "checked_lockstep",
    "checked_run",
    "execute_after_task",
    "failure",
    "finish_execution",
    "run",
    "run_lockstep",
    "summary_lines",
]

Log = Callable[[str], None]
AfterTask = Callable[[int], Any]


class Source(Protocol):
    """Where a run's predictions come from (:class:`Training`, or predictions scored from
    elsewhere in :mod:`clfd_bench.harness.external`)."""

    def owner(self, out: Path) -> str:
        """Who holds the run directory while the run writes it, in words (named by a
        second writer that is refused)."""

    def produce(self, out: Path, after_task: AfterTask | None, log: Log | None
                ) -> dict[str, Any]:
        """Writes the predictions and the training (or scoring) fields of ``results.json``
        into ``out``; calls ``after_task(i)`` after each task whose files are written, if it
        makes its predictions task by task; returns ``results.json`` as written."""


@dataclass(frozen=True)
class TrainSpec:
    """What to train: the arguments that resolve a run's configuration.

    Attributes:
        method: CL method name or plugin spec. dataset: dataset name. profile:
            hyperparameter profile. seed, order, node, tasks: as ``clfd-bench train``'s
            options. overrides: ``key=value`` strings, as ``--set`` takes them.
            config_file: the method's hyperparameter file (None: its default).
    """

    method: str
    dataset: str
    profile: str = "fast"
    seed: int = 0
    order: int = 0
    node: str = "t"
    tasks: int | None = None
    overrides: tuple[str, ...] = ()
    config_file: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "overrides", tuple(self.overrides))

    def config(self, arg_names: dict[str, str] | None = None) -> RunConfig:
        """The resolved configuration (:func:`~clfd_bench.harness.config.resolve_config`;
        ``arg_names`` names the options run-level values came from in its errors).

        Raises:
            ConfigError, UnknownMethodError, MethodClassError: a bad key, value or method.
        """
        from clfd_bench.harness.config import resolve_config

        return resolve_config(
            self.method, self.dataset, self.profile, seed=self.seed, order=self.order,
            node=self.node, tasks=self.tasks, overrides=list(self.overrides),
            config_file=self.config_file, arg_names=arg_names,
        )  # fmt: skip

    def to_dict(self) -> dict[str, Any]:
        """Plain data; ``TrainSpec(**spec.to_dict())`` gives it back."""
        return {**asdict(self), "overrides": list(self.overrides)}


@dataclass(frozen=True)
class Training:
    """The run's predictions come from learning its tasks in order with ``config``.

    Attributes:
        config: the resolved configuration. threads: torch CPU threads (None: the default,
            :func:`~clfd_bench.harness.protocol.default_threads`). keep_checkpoints: keep a
            checkpoint after every task. snapshot_every: seconds between two snapshots of
            the task being learned (0: none; None: the protocol's ``SNAPSHOT_EVERY_S``).
    """

    config: RunConfig
    threads: int | None = None
    keep_checkpoints: bool = False
    snapshot_every: float | None = None

    def owner(self, out: Path) -> str:
        c = self.config
        return (f"clfd-bench train --method {c.method} --dataset {c.dataset} --seed {c.seed} "
                f"--out {out}")

    def produce(self, out: Path, after_task: AfterTask | None, log: Log | None
                ) -> dict[str, Any]:
        from clfd_bench.harness.protocol import run_training

        return run_training(self.config, out, threads=self.threads, log=log,
                            keep_checkpoints=self.keep_checkpoints, after_task=after_task,
                            snapshot_every=self.snapshot_every)


def execute_after_task(out: str | os.PathLike[str], workers: int, log: Log | None
                       ) -> AfterTask:
    """The step after each learned task: execute every saved prediction not executed yet
    (cached in the run) and write ``success`` / ``sim_accuracy`` / ``sim_cl_metrics`` /
    ``sim`` into ``results.json``; one line to ``log`` per task."""
    from clfd_bench.execution.evaluate import evaluate_run

    def after_task(i: int) -> dict[str, Any]:
        fields = evaluate_run(out, workers=workers)
        if log is not None:
            row = fields["success"][i]
            done = [s for cell in row[: i + 1] if cell for s in cell]
            sim = fields["sim"]
            acc = fields["sim_cl_metrics"].get("ACC")
            log(f"  executed in simulation after task {i}: {sum(done)}/{len(done)} rollouts "
                f"succeed, exec ACC so far {acc if acc is None else format(acc, '.2f')} "
                f"({sim['rollouts_executed']} new rollouts, {sim['wall_s']:.1f} s)")
        return fields

    return after_task


def finish_execution(run: RunDir, tasks_done: int, workers: int) -> dict[str, Any]:
    """Executes what the per-task step left undone (a run killed while executing its last
    task, trained before without simulation, or scored from elsewhere); nothing when every
    prediction was executed by this simulator. Returns the execution fields of
    ``results.json``."""
    from clfd_bench.execution.evaluate import evaluate_run
    from clfd_bench.execution.fingerprint import sim_fingerprint
    from clfd_bench.runs import SIM_KEYS

    if run.status(tasks_done, sim=True, fingerprint=sim_fingerprint()).state == "done":
        results = run.load_results()
        return {k: results[k] for k in SIM_KEYS if k in results}
    return evaluate_run(run.path, workers=workers)


def run(
    source: Source,
    out: str | os.PathLike[str],
    *,
    sim: bool = True,
    sim_workers: int = 1,
    log: Log | None = None,
) -> dict[str, Any]:
    """Runs (or resumes) one run into ``out``: its predictions from ``source``, then, with
    ``sim``, their execution in simulation; returns ``results.json`` as written.

    Args:
        source: where the predictions come from (:class:`Training`, or a scoring of
            predictions made elsewhere).
        out: the run directory (created if missing).
        sim: execute the predictions in simulation.
        sim_workers: processes executing rollouts in parallel.
        log: where progress lines go (None: nowhere).

    Raises:
        RunLockedError: another process holds ``out``.
        RunMismatchError: ``out`` holds a run with a different configuration.
        TrainingDivergedError: training diverged (the tasks finished before stay in ``out``).
    """
    directory = RunDir(out)
    hook = execute_after_task(out, sim_workers, log) if sim else None
    with directory.lock(source.owner(directory.path)):
        results = source.produce(directory.path, hook, log)
        if sim:
            results.update(finish_execution(directory, results["tasks_done"], sim_workers))
    return results


def run_lockstep(
    trainings: Sequence[Training],
    outs: Sequence[str | os.PathLike[str]],
    *,
    sim: bool = True,
    sim_workers: int = 1,
    logs: Sequence[Log | None] | None = None,
) -> list[dict[str, Any] | Exception]:
    """Runs (or resumes) several training runs in this process, their tasks learned in
    lockstep (:func:`~clfd_bench.harness.protocol.run_trainings`); each run is what
    :func:`run` makes of it alone, bit for bit: its directory locked for the whole call, its
    predictions, checkpoints and results, with ``sim`` its executions after each task and at
    the end.

    Args:
        trainings: the runs (differing in seed or order; the first one's ``threads`` is used).
        outs: their run directories, one per training.
        logs: per run, where its progress lines go (None: nowhere).

    Returns:
        per run, its ``results.json`` as written, or the exception that stopped it (a run
        directory held by another process or holding another run, diverged training, ...);
        the other runs are not affected by one that stops.
    """
    from clfd_bench.harness.protocol import TrainingJob, run_trainings

    logs = list(logs) if logs is not None else [None] * len(trainings)
    outcomes: list[dict[str, Any] | Exception | None] = [None] * len(trainings)
    with ExitStack() as stack:
        jobs, members = [], []
        for k, (training, out) in enumerate(zip(trainings, outs, strict=True)):
            directory = RunDir(out)
            try:
                stack.enter_context(directory.lock(training.owner(directory.path)))
            except Exception as exc:  # noqa: BLE001 - held elsewhere: this run's outcome
                outcomes[k] = exc
                continue
            hook = execute_after_task(out, sim_workers, logs[k]) if sim else None
            jobs.append(TrainingJob(training.config, directory.path, logs[k], hook,
                                    training.keep_checkpoints, training.snapshot_every))
            members.append(k)
        threads = trainings[0].threads if trainings else None
        for k, result in zip(members, run_trainings(jobs, threads=threads), strict=True):
            if not isinstance(result, Exception) and sim:
                try:
                    result.update(finish_execution(RunDir(outs[k]), result["tasks_done"],
                                                   sim_workers))
                except Exception as exc:  # noqa: BLE001 - stops this run only
                    result = exc
            outcomes[k] = result
    return outcomes  # type: ignore[return-value]


def summary_lines(results: dict[str, Any], results_path: Path) -> list[str]:
    """What a finished run prints: its CL metrics (and executed ones); none without any."""
    cl = results.get("cl_metrics")
    if not cl:
        return []

    def shown(metrics: dict[str, Any]) -> str:
        return ", ".join(f"{k} {'n/a' if v is None else format(v, '.3f')}"
                         for k, v in metrics.items())

    lines = [f"done: {results_path} ({results['cl_metrics_primary']}: {shown(cl)})"]
    if results.get("sim_cl_metrics"):
        lines.append(f"executed in simulation: {shown(results['sim_cl_metrics'])}")
    return lines


def failure(exc: BaseException, out: str | os.PathLike[str], prog: str,
            write: Log | None = None) -> int:
    """How a command ends a run that raised ``exc``: for a reason of the user's or of the
    run's, one line on stderr (``<prog>: error: ...``) and the exit code -- 2 for a bad input
    (:data:`~clfd_bench.harness.validate.USER_ERRORS`), a run directory holding another run
    or held by another process; 1 for diverged training. Any other ``exc`` is a bug: raised
    again (its traceback is the report). ``write`` takes the line instead of stderr."""
    from clfd_bench.harness.loop import TrainingDivergedError
    from clfd_bench.harness.protocol import RunMismatchError
    from clfd_bench.harness.validate import USER_ERRORS, one_line
    from clfd_bench.runs import RunLockedError

    if isinstance(exc, TrainingDivergedError):  # the run failed; its finished tasks stay
        kept = (f"tasks 0..{exc.task - 1} stay in {out}" if exc.task > 0
                else "no task was finished")
        code, message = 1, f"{exc}; {kept} (another lr needs another --out)"
    elif isinstance(exc, (RunMismatchError, RunLockedError, *USER_ERRORS)):
        code, message = 2, one_line(exc)
    else:
        raise exc
    line = f"{prog}: error: {message}"
    if write is None:
        print(line, file=sys.stderr)
    else:
        write(line)
    return code


def checked_run(training: Training, out: str | os.PathLike[str], *, sim: bool,
                sim_workers: int, log: Log | None, prog: str) -> int:
    """A training run as a command runs it (``clfd-bench train``, a grid's worker): what it
    needs checked before anything is written (``out`` new, empty or this run's; the dataset's
    files; with ``sim``, the robot model), then :func:`run`, then its summary to ``log``.
    Returns the exit code: 0 done, else :func:`failure`'s."""
    from clfd_bench.harness.validate import check_dataset, check_robot_model, check_run_out_dir

    config = training.config
    try:
        check_run_out_dir(out)
        check_dataset(config.dataset, config.order)
        if sim:
            check_robot_model()
        results = run(training, out, sim=sim, sim_workers=sim_workers, log=log)
    except Exception as exc:
        return failure(exc, out, prog)
    if log is not None:
        for line in summary_lines(results, RunDir(out).results_path):
            log(line)
    return 0


def checked_lockstep(trainings: Sequence[Training], outs: Sequence[str | os.PathLike[str]],
                     *, sim: bool, sim_workers: int, logs: Sequence[Log], prog: str
                     ) -> list[int]:
    """:func:`checked_run` for several runs trained in lockstep (:func:`run_lockstep`):
    each run's inputs checked, then all run together; each run's outcome (its summary, or
    its one-line error, or for a bug its traceback) goes to its own ``logs[k]``. Returns
    each run's exit code, as :func:`checked_run` would give it alone."""
    from clfd_bench.harness.validate import check_dataset, check_robot_model, check_run_out_dir

    codes: list[int | None] = [None] * len(trainings)
    ready = []
    for k, (training, out) in enumerate(zip(trainings, outs, strict=True)):
        try:
            check_run_out_dir(out)
            check_dataset(training.config.dataset, training.config.order)
            if sim:
                check_robot_model()
            ready.append(k)
        except Exception as exc:  # noqa: BLE001 - reported per run below
            codes[k] = _reported(exc, out, prog, logs[k])
    results = run_lockstep([trainings[k] for k in ready], [outs[k] for k in ready], sim=sim,
                           sim_workers=sim_workers, logs=[logs[k] for k in ready])
    for k, result in zip(ready, results, strict=True):
        if isinstance(result, Exception):
            codes[k] = _reported(result, outs[k], prog, logs[k])
            continue
        for line in summary_lines(result, RunDir(outs[k]).results_path):
            logs[k](line)
        codes[k] = 0
    return [int(c) for c in codes]  # type: ignore[arg-type]


def _reported(exc: Exception, out: str | os.PathLike[str], prog: str, log: Log) -> int:
    """:func:`failure` for one run of several: a bug's traceback goes to the run's log
    (exit code 1) instead of ending the others."""
    try:
        return failure(exc, out, prog, write=log)
    except Exception:  # noqa: BLE001 - a bug in this run: its report
        log("".join(traceback.format_exception(exc)).rstrip())
        return 1
