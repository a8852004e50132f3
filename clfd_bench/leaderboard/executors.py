"""Executors: run the grid's training commands on local processes or on a Ray cluster.

Both run exactly the same command (``clfd-bench train ...``) with the same environment
(``CLFD_THREADS=1``, no progress bars), so they give the same results. A run that
crashes is recorded in ``<run_dir>/failed.json`` with the end of its log and does not stop
the grid.

Ray: each run is shipped to a worker as a tarball of its run directory (empty, or the
checkpoints of a half-finished run), trained there in a temporary directory, and shipped
back; the cluster needs no shared filesystem.
"""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import tarfile
import tempfile
import time
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

from clfd_bench.io import atomic_write_json
from clfd_bench.leaderboard.grid import FAILED_FILE, RunSpec

__all__ = ["EXECUTORS", "RunOutcome", "execute_grid"]

LOG_FILE = "train.log"
_LOG_TAIL = 4000


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


def _run_command(argv: list[str], run_dir: Path) -> tuple[int, str]:
    """Run ``argv`` with its output appended to ``run_dir/train.log``; return (code, tail)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    log_path = run_dir / LOG_FILE
    with open(log_path, "ab") as log:
        log.write(f"\n$ {' '.join(argv)}\n".encode())
        log.flush()
        code = subprocess.run(
            argv, stdout=log, stderr=subprocess.STDOUT, env=_run_env(), check=False
        ).returncode
    tail = log_path.read_bytes()[-_LOG_TAIL:].decode("utf-8", "replace")
    return code, tail


def _record(spec: RunSpec, root: Path, code: int, tail: str, seconds: float) -> RunOutcome:
    failed = spec.run_dir(root) / FAILED_FILE
    if code == 0:
        failed.unlink(missing_ok=True)
        return RunOutcome(spec, True, None, seconds)
    lines = [ln for ln in tail.strip().splitlines() if ln.strip()]
    error = lines[-1] if lines else f"exit code {code}"
    atomic_write_json(
        failed, {"exit_code": code, "error": error, "log_tail": tail, "spec": spec.to_dict()}
    )
    return RunOutcome(spec, False, error, seconds)


def _local_one(spec: RunSpec, root: Path) -> RunOutcome:
    start = time.perf_counter()
    code, tail = _run_command(spec.train_argv(root), spec.run_dir(root))
    return _record(spec, root, code, tail, time.perf_counter() - start)


def _local(
    specs: list[RunSpec], root: Path, workers: int, on_done: Callable[[RunOutcome], None]
) -> list[RunOutcome]:
    outcomes = []
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        futures = [pool.submit(_local_one, spec, root) for spec in specs]
        for future in as_completed(futures):
            outcome = future.result()
            on_done(outcome)
            outcomes.append(outcome)
    return outcomes


def _pack(directory: Path) -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tar:
        if directory.exists():
            for path in sorted(directory.rglob("*")):
                tar.add(path, arcname=str(path.relative_to(directory)), recursive=False)
    return buffer.getvalue()


def _unpack(payload: bytes, directory: Path) -> None:
    directory.mkdir(parents=True, exist_ok=True)
    with tarfile.open(fileobj=io.BytesIO(payload), mode="r:gz") as tar:
        try:
            tar.extractall(directory, filter="data")
        except TypeError:  # Python < 3.10.12 has no extraction filters; our own tarballs
            tar.extractall(directory)  # noqa: S202


def _remote_train(spec_dict: dict, payload: bytes) -> tuple[int, str, bytes, float]:
    """Runs on a Ray worker: unpack the run directory, train, pack it again."""
    spec = RunSpec(**spec_dict)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="clfd-ray-") as tmp:
        root = Path(tmp)
        run_dir = spec.run_dir(root)
        _unpack(payload, run_dir)
        code, tail = _run_command(spec.train_argv(root), run_dir)
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
                if run_dir.exists():
                    shutil.rmtree(run_dir)
                staging.rename(run_dir)
            outcome = _record(spec, root, code, tail, seconds)
            on_done(outcome)
            outcomes.append(outcome)
        return outcomes
    finally:
        if started_here:
            ray.shutdown()


EXECUTORS = ("local", "ray")


def execute_grid(
    specs: Iterable[RunSpec],
    root: Path,
    executor: str = "local",
    workers: int = 1,
    address: str | None = None,
    on_done: Callable[[RunOutcome], None] = lambda outcome: None,
) -> list[RunOutcome]:
    """Run (or resume) every spec; returns one outcome per spec, in completion order.

    Args:
        specs: the runs still to do.
        root: the leaderboard's output directory (runs go to ``root/runs/...``).
        executor: ``"local"`` (processes on this machine) or ``"ray"``.
        workers: parallel processes for the local executor.
        address: Ray cluster address (None: start a local Ray instance).
        on_done: called with each outcome as it arrives (progress bars).
    """
    specs = list(specs)
    if executor == "local":
        return _local(specs, Path(root), workers, on_done)
    if executor == "ray":
        return _ray(specs, Path(root), address, on_done)
    raise ValueError(f"unknown executor {executor!r}; valid: {', '.join(EXECUTORS)}")
