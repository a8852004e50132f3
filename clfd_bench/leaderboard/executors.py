"""Executors: run the grid's training commands on local processes or on a Ray cluster.

Both run exactly the same command, a grid worker (``python -m clfd_bench.harness.worker JOB``,
:mod:`clfd_bench.harness.worker`, which runs the run with :func:`clfd_bench.harness.run.run`),
with the same environment (``CLFD_THREADS=1``, no progress bars), so they give the same
results; the worker's output is appended to the run's ``train.log``. The local executor
trains runs that differ only in seed or order in one worker, in lockstep
(:func:`~clfd_bench.leaderboard.grid.lockstep_batches`; each run's lines and outcome stay its
own); Ray runs every run in a worker of its own. A run that
crashes is recorded in ``<run_dir>/failed.json`` with the end of its log and does not stop
the grid.

Local runs are child processes in their own process group, which the grid ends (with every
process in it) when it stops for any reason it can see (an exception, Ctrl-C, SIGTERM); and
each child asks the kernel to SIGKILL it when the grid process dies, so even ``kill -9`` of
the grid leaves no training behind (:func:`clfd_bench.procs.die_with_parent`). The run
directory's lock (:meth:`clfd_bench.runs.RunDir.lock`) makes a second trainer of the same run
refuse to start in any case.

Ray: each run is shipped to a worker as a tarball of its run directory (empty, or the
checkpoints of a half-finished run), trained there in a temporary directory, and shipped
back; the cluster needs no shared filesystem.
"""

from __future__ import annotations

import io
import os
import signal
import subprocess
import tarfile
import tempfile
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

from clfd_bench.harness.worker import lockstep_argv
from clfd_bench.leaderboard.grid import (
    DEFAULT_OPTIONS,
    EXECUTORS,
    GridOptions,
    RunSpec,
    lockstep_batches,
)
from clfd_bench.procs import child_env
from clfd_bench.runs import RunDir

__all__ = ["EXECUTORS", "RunOutcome", "execute_grid"]

_LOG_TAIL = 4000
_CHILDREN: set[subprocess.Popen] = set()
_CHILDREN_LOCK = threading.Lock()


@dataclass(frozen=True)
class RunOutcome:
    """What happened to one run: ok, the error (log tail) if not, and its wall time."""

    spec: RunSpec
    ok: bool
    error: str | None
    seconds: float


def _run_env() -> dict[str, str]:
    env = dict(os.environ)
    env["CLFD_THREADS"] = "1"
    env["CLFD_NO_PROGRESS"] = "1"
    return env


def end_children() -> None:
    """SIGKILLs the process group of every running child (a grid that stops early)."""
    with _CHILDREN_LOCK:
        children = list(_CHILDREN)
    for child in children:
        try:
            os.killpg(child.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass


def _child(argv: list[str], log) -> int:
    """Run ``argv`` with stdout and stderr to the open file ``log``; its exit code."""
    # Own session and process group; the child arms its death signal itself (no
    # preexec_fn: it is unsafe in a threaded parent), given this process's pid, and takes
    # this process's priority for its own scheduling group (clfd_bench.procs).
    env = child_env(_run_env())
    child = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=env,
                             start_new_session=True)
    with _CHILDREN_LOCK:
        _CHILDREN.add(child)
    try:
        return child.wait()
    finally:
        with _CHILDREN_LOCK:
            _CHILDREN.discard(child)


def _run_command(argv: list[str], run_dir: Path) -> tuple[int, str]:
    """Run ``argv`` with its output appended to ``run_dir/train.log``; return (code, tail)."""
    run = RunDir(run_dir)
    with run.open_log() as log:
        log.write(f"\n$ {' '.join(argv)}\n".encode())
        log.flush()
        code = _child(argv, log)
    return code, run.log_tail(_LOG_TAIL)


def _run_lockstep(specs: list[RunSpec], root: Path) -> list[tuple[int, str]]:
    """Run ``specs`` in one lockstep worker (``--outcomes FILE JOB ...``): each run's lines
    reach its own ``train.log`` from the worker; the worker's own output goes to a file
    beside the runs, copied into the log of every run it left without an outcome (a crash,
    a kill). Returns each run's (code, log tail)."""
    import json

    root = Path(root)
    (root / "runs").mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=".lockstep-", suffix=".json", dir=root / "runs")
    os.close(fd)
    outcomes_path = Path(name)
    outcomes_path.unlink()
    argv = lockstep_argv([spec.job(root) for spec in specs], str(outcomes_path))
    runs = [RunDir(spec.run_dir(root)) for spec in specs]
    names = ", ".join(spec.name for spec in specs)
    for run in runs:
        with run.open_log() as log:
            log.write(f"\n$ clfd-bench worker, {len(specs)} runs in lockstep: {names}\n".encode())
    with tempfile.TemporaryFile() as out:
        code = _child(argv, out)
        try:
            codes = json.loads(outcomes_path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            codes = {}
        finally:
            outcomes_path.unlink(missing_ok=True)
        out.seek(max(0, out.seek(0, os.SEEK_END) - _LOG_TAIL))
        tail = out.read().decode("utf-8", "replace")
    results = []
    for spec, run in zip(specs, runs, strict=True):
        run_code = codes.get(str(spec.run_dir(root)))
        if run_code is None:  # the worker ended before this run's outcome
            run_code = code or 1
            with run.open_log() as log:
                log.write(f"the lockstep worker ended with exit code {code} before this "
                          f"run finished; its last output:\n{tail}\n".encode())
        results.append((int(run_code), run.log_tail(_LOG_TAIL)))
    return results


def _record(spec: RunSpec, root: Path, code: int, tail: str, seconds: float) -> RunOutcome:
    run = RunDir(spec.run_dir(root))
    if code == 0:
        run.clear_failed()
        return RunOutcome(spec, True, None, seconds)
    lines = [ln for ln in tail.strip().splitlines() if ln.strip()]
    error = lines[-1] if lines else f"exit code {code}"
    run.mark_failed({"exit_code": code, "error": error, "log_tail": tail,
                     "spec": spec.to_dict()})
    return RunOutcome(spec, False, error, seconds)


def _local_batch(batch: list[RunSpec], root: Path) -> list[RunOutcome]:
    """One run in a worker of its own, or several in one lockstep worker."""
    start = time.perf_counter()
    if len(batch) == 1:
        (spec,) = batch
        code, tail = _run_command(spec.worker_argv(root), spec.run_dir(root))
        return [_record(spec, root, code, tail, time.perf_counter() - start)]
    results = _run_lockstep(batch, root)
    seconds = time.perf_counter() - start
    return [_record(spec, root, code, tail, seconds)
            for spec, (code, tail) in zip(batch, results, strict=True)]


def _local(
    specs: list[RunSpec], root: Path, workers: int, on_done: Callable[[RunOutcome], None],
    lockstep: bool = True,
) -> list[RunOutcome]:
    outcomes = []
    previous = signal.getsignal(signal.SIGTERM)
    main = threading.current_thread() is threading.main_thread()
    if main:  # SIGTERM ends the grid like Ctrl-C: children first
        signal.signal(signal.SIGTERM, _raise_keyboard_interrupt)
    pool = ThreadPoolExecutor(max_workers=max(1, workers))
    try:
        batches = lockstep_batches(specs, workers, lockstep)
        futures = [pool.submit(_local_batch, batch, root) for batch in batches]
        for future in as_completed(futures):
            for outcome in future.result():
                on_done(outcome)
                outcomes.append(outcome)
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        end_children()
        raise
    finally:
        pool.shutdown(wait=True)
        if main:
            signal.signal(signal.SIGTERM, previous)
    return outcomes


def _raise_keyboard_interrupt(signum, frame) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def _pack(directory: Path) -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tar:
        if directory.exists():
            for path in sorted(directory.rglob("*")):
                tar.add(path, arcname=str(path.relative_to(directory)), recursive=False)
    return buffer.getvalue()


def _unpack(payload: bytes, directory: Path) -> None:
    """Extracts a run tarball into ``directory``, refusing anything but plain files and folders
    inside it (with the "data" filter where Python has it, and our own check everywhere)."""
    directory.mkdir(parents=True, exist_ok=True)
    root = directory.resolve()
    with tarfile.open(fileobj=io.BytesIO(payload), mode="r:gz") as tar:
        members = tar.getmembers()
        for member in members:
            target = (root / member.name).resolve()
            if not (member.isfile() or member.isdir()) or (
                    target != root and root not in target.parents):
                raise ValueError(f"unsafe member {member.name!r} in a run tarball (only files "
                                 "and folders inside the run directory are accepted)")
        if hasattr(tarfile, "data_filter"):
            tar.extractall(directory, members=members, filter="data")
        else:  # Python < 3.10.12: no filters; the members were checked above
            tar.extractall(directory, members=members)  # noqa: S202


def _remote_train(spec_dict: dict, payload: bytes) -> tuple[int, str, bytes, float]:
    """Runs on a Ray worker: unpack the run directory, train, pack it again."""
    spec = RunSpec(**spec_dict)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="clfd-ray-") as tmp:
        root = Path(tmp)
        run_dir = spec.run_dir(root)
        _unpack(payload, run_dir)
        code, tail = _run_command(spec.worker_argv(root), run_dir)
        return code, tail, _pack(run_dir), time.perf_counter() - start


def _ray(
    specs: list[RunSpec],
    root: Path,
    address: str | None,
    on_done: Callable[[RunOutcome], None],
) -> list[RunOutcome]:
    try:
        import ray
    except ModuleNotFoundError:
        raise SystemExit(
            "--executor ray needs Ray: install it with `pip install 'clfd-bench[dist]'` "
            "(or `pip install 'ray[default]'`)"
        ) from None
    started_here = not ray.is_initialized()
    if started_here:
        ray.init(address=address, include_dashboard=False, log_to_driver=False)
    try:
        remote = ray.remote(num_cpus=1)(_remote_train)
        pending = {
            remote.remote(spec.to_dict(), _pack(spec.run_dir(root))): spec for spec in specs
        }
        outcomes = []
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            spec = pending.pop(done[0])
            try:
                code, tail, payload, seconds = ray.get(done[0])
            except Exception as exc:  # a worker died: report, keep going
                code, tail, payload, seconds = 1, f"ray task failed: {exc}", b"", 0.0
            run_dir = spec.run_dir(root)
            if payload:
                run_dir.parent.mkdir(parents=True, exist_ok=True)
                staging = Path(tempfile.mkdtemp(prefix=".incoming-", dir=run_dir.parent))
                _unpack(payload, staging)
                RunDir(run_dir).replace_with(staging)
            outcome = _record(spec, root, code, tail, seconds)
            on_done(outcome)
            outcomes.append(outcome)
        return outcomes
    finally:
        if started_here:
            ray.shutdown()



def execute_grid(
    specs: Iterable[RunSpec],
    root: Path,
    options: GridOptions = DEFAULT_OPTIONS,
    on_done: Callable[[RunOutcome], None] = lambda outcome: None,
) -> list[RunOutcome]:
    """Run (or resume) every spec; returns one outcome per spec, in completion order.

    Args:
        specs: the runs still to do.
        root: the leaderboard's output directory (runs go to ``root/runs/...``).
        options: where they run: ``executor`` (``"local"``: processes on this machine, or
            ``"ray"``), ``workers`` (parallel processes of the local executor), ``address``
            (the Ray cluster's; None: start a local Ray instance).
        on_done: called with each outcome as it arrives (progress bars).
    """
    specs = list(specs)
    if options.executor == "local":
        return _local(specs, Path(root), options.workers, on_done, options.lockstep)
    if options.executor == "ray":
        return _ray(specs, Path(root), options.address, on_done)
    raise ValueError(f"unknown executor {options.executor!r}; valid: {', '.join(EXECUTORS)}")
