"""A grid's worker: one training run in a process of its own, started as
``python -m clfd_bench.harness.worker JOB``, or several runs trained in lockstep in one
process (:func:`clfd_bench.harness.run.run_lockstep`), started as
``python -m clfd_bench.harness.worker --outcomes FILE JOB JOB ...``.

JOB is a JSON object (:class:`Job`): what to train (:class:`~clfd_bench.harness.run.TrainSpec`),
the run directory, whether to execute in simulation. The grid's executors
(:mod:`clfd_bench.leaderboard.executors`) start it with its output appended to the run's
``train.log``; it runs the run with :func:`clfd_bench.harness.run.run`, as ``clfd-bench train``
does, and resumes a half-finished run after its last finished task. First thing, it asks to
be killed when the grid that started it dies (:func:`clfd_bench.procs.die_with_parent_from_env`),
so even a SIGKILLed grid leaves no worker training behind.

Exit codes (:func:`clfd_bench.harness.run.checked_run`): 0 done; 2 a bad job, input or run
directory (one line, ``clfd-bench worker: error: ...``); 1 training diverged, or a crash (its
traceback).

With several jobs, each run's lines (progress, summary, its one-line error or a bug's
traceback) are appended to its own ``train.log`` by the worker itself, and echoed on stdout
prefixed with the run's directory; each run's exit code is written to FILE as a JSON object
``{run directory: code}`` once all are done (a run missing from it, or no FILE at all: the
worker was killed or crashed, and its own exit code and stdout say how). The process exits
with the largest run code.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from clfd_bench.harness.run import TrainSpec

__all__ = ["ENTRY_POINT", "Job", "lockstep_argv", "main"]

ENTRY_POINT = "clfd_bench.harness.worker"
"""The module a worker process runs (``python -m``)."""

_PROG = "clfd-bench worker"


@dataclass(frozen=True)
class Job:
    """One run for a worker: what to train, where, and whether to execute in simulation."""

    train: TrainSpec
    out: str
    sim: bool = True
    sim_workers: int = 1

    def to_json(self) -> str:
        return json.dumps({"train": self.train.to_dict(), "out": self.out, "sim": self.sim,
                           "sim_workers": self.sim_workers})

    @classmethod
    def from_json(cls, text: str) -> Job:
        """The job of :meth:`to_json`'s text.

        Raises:
            ValueError: not such a JSON object.
        """
        try:
            doc: Any = json.loads(text)
            return cls(TrainSpec(**doc["train"]), str(doc["out"]), bool(doc.get("sim", True)),
                       int(doc.get("sim_workers", 1)))
        except (ValueError, TypeError, KeyError) as exc:
            raise ValueError(f"not a worker job ({type(exc).__name__}: {exc}); expected "
                             "{\"train\": {...}, \"out\": DIR, \"sim\": BOOL}") from None

    def argv(self) -> list[str]:
        """The command that runs (or resumes) this job."""
        return [sys.executable, "-m", ENTRY_POINT, self.to_json()]


def lockstep_argv(jobs: Sequence[Job], outcomes: str) -> list[str]:
    """The command that runs ``jobs`` in lockstep in one worker, writing each run's exit code
    to ``outcomes`` (module docstring)."""
    return [sys.executable, "-m", ENTRY_POINT, "--outcomes", outcomes,
            *(job.to_json() for job in jobs)]


def _run_log(out: str) -> Callable[[str], None]:
    """A log that appends each line to run ``out``'s ``train.log`` and echoes it on stdout."""
    from clfd_bench.runs import RunDir

    run = RunDir(out)
    name = Path(out).name

    def log(line: str) -> None:
        with run.open_log() as fh:
            fh.write(f"{line}\n".encode())
        print(f"[{name}] {line}")

    return log


def _lockstep(outcomes_path: str, texts: Sequence[str]) -> int:
    """Several jobs in lockstep (module docstring)."""
    from clfd_bench.harness.run import Training, checked_lockstep, failure
    from clfd_bench.harness.validate import check_env_count, check_thread_invariance
    from clfd_bench.io import atomic_write_json

    try:
        jobs = [Job.from_json(text) for text in texts]
        check_env_count("CLFD_THREADS")
        check_thread_invariance()
    except ValueError as exc:
        print(f"{_PROG}: error: {exc}", file=sys.stderr)
        return 2
    logs = [_run_log(job.out) for job in jobs]
    codes: dict[str, int] = {}
    trainings, members = [], []
    for k, (job, log) in enumerate(zip(jobs, logs, strict=True)):
        try:
            trainings.append(Training(job.train.config()))
            members.append(k)
        except Exception as exc:  # noqa: BLE001 - this job's bad input
            codes[job.out] = failure(exc, job.out, _PROG, write=log)
    sims = {(jobs[k].sim, jobs[k].sim_workers) for k in members}
    if len(sims) > 1:
        print(f"{_PROG}: error: jobs run in lockstep must agree on sim and sim_workers, got "
              f"{sorted(sims)}", file=sys.stderr)
        return 2
    sim, sim_workers = sims.pop() if sims else (False, 1)
    results = checked_lockstep(trainings, [jobs[k].out for k in members], sim=sim,
                               sim_workers=sim_workers, logs=[logs[k] for k in members],
                               prog=_PROG)
    codes.update({jobs[k].out: code for k, code in zip(members, results, strict=True)})
    atomic_write_json(outcomes_path, codes)
    return max(codes.values(), default=0)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the job given as the one argument; return the exit code (module docstring)."""
    from clfd_bench.harness.run import Training, checked_run, failure
    from clfd_bench.harness.validate import check_env_count, check_thread_invariance
    from clfd_bench.procs import die_with_parent_from_env, keep_parent_priority

    die_with_parent_from_env()  # started by a grid: end with it, even if it is SIGKILLed
    keep_parent_priority()  # in its own session: yield the CPU as the grid does
    if hasattr(sys.stdout, "reconfigure"):  # whole lines reach train.log as they are printed
        sys.stdout.reconfigure(line_buffering=True)
    argv = sys.argv[1:] if argv is None else list(argv)
    if len(argv) >= 3 and argv[0] == "--outcomes":
        return _lockstep(argv[1], argv[2:])
    if len(argv) != 1:
        print(f"usage: python -m {ENTRY_POINT} JOB_JSON\n"
              f"       python -m {ENTRY_POINT} --outcomes FILE JOB_JSON [JOB_JSON ...]",
              file=sys.stderr)
        return 2
    try:
        job = Job.from_json(argv[0])
    except ValueError as exc:
        print(f"{_PROG}: error: {exc}", file=sys.stderr)
        return 2
    try:
        check_env_count("CLFD_THREADS")
        check_thread_invariance()
        training = Training(job.train.config())
    except Exception as exc:
        return failure(exc, job.out, _PROG)
    return checked_run(training, job.out, sim=job.sim, sim_workers=job.sim_workers, log=print,
                       prog=_PROG)


if __name__ == "__main__":
    sys.exit(main())
