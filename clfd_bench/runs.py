"""Run directories: the one module that reads and writes them.

A run directory is what ``clfd-bench train --out RUN_DIR`` fills (``clfd-bench score``, which
scores predictions made elsewhere, fills the same files but for the checkpoints)::

    RUN_DIR/
      results.json                   training (or scoring) results, then the execution fields
      checkpoint.pt                  model + progress (resumes the run)
      task_snapshot.pt               the task being learned, every few minutes (resumes it
                                     mid-task); removed once the task's checkpoint is written
      task_snapshot.json             where that snapshot stands (task, iteration, CPU), for
                                     the status line; read without torch
      checkpoints/after_task_{i}.pt  with --keep-checkpoints
      predictions/after_task_{i}.npz arrays task_{j} [N, T, D], j <= i
      sim_cache.json                 executed rollouts, per simulator fingerprint
      train.log, failed.json         a grid's log of the run and its last crash
      .lock                          held (flock) by the process writing the run

Everything above is read and written through :class:`RunDir`; no other module opens these
files. Every write is atomic (:mod:`clfd_bench.io`: temporary file, fsync, rename, fsync of
the folder), so a process killed at any moment leaves each file either old or new.

**Status.** A run is *done* only when every stage it was asked for is finished for every
learned task: training of all its tasks (``results.json`` ``complete``) and, unless it runs
without simulation, execution of every saved prediction by the current simulator
(``sim.evaluated_tasks`` equals ``tasks_done`` and ``sim.fingerprint`` is the current one).
Training that learns one more task drops the execution fields of the smaller matrix, so
no reader can mistake them for the run's.

**Exclusive writers.** :meth:`RunDir.lock` takes an ``flock`` on ``RUN_DIR/.lock``: a second
writer is refused with :class:`RunLockedError`, naming the holder's pid and command. The
kernel releases the lock when its holder dies, even by SIGKILL, so a killed run never
blocks the next one; the next holder removes the temporary files a killed write left.
"""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import fcntl
import io
import json
import os
import shutil
import zipfile
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.io import atomic_write_bytes, atomic_write_json, fsync_dir

__all__ = [
    "CACHE_FILE",
    "CHECKPOINT_FILE",
    "FAILED_FILE",
    "LOCK_FILE",
    "LOG_FILE",
    "PREDICTIONS_DIR",
    "RUN_FILES",
    "RESULTS_FILE",
    "SIM_KEYS",
    "TASK_SNAPSHOT_FILE",
    "TASK_SNAPSHOT_NOTE",
    "RunDir",
    "RunFileError",
    "RunLockedError",
    "RunStatus",
    "exclusive",
    "find_runs",
]

RESULTS_FILE = "results.json"
CHECKPOINT_FILE = "checkpoint.pt"
CHECKPOINTS_DIR = "checkpoints"
TASK_SNAPSHOT_FILE = "task_snapshot.pt"
TASK_SNAPSHOT_NOTE = "task_snapshot.json"
PREDICTIONS_DIR = "predictions"
CACHE_FILE = "sim_cache.json"
LOG_FILE = "train.log"
FAILED_FILE = "failed.json"
LOCK_FILE = ".lock"
#: What a run directory may hold (the lock last): a folder with other entries is not a run.
RUN_FILES = (RESULTS_FILE, CHECKPOINT_FILE, CHECKPOINTS_DIR, TASK_SNAPSHOT_FILE,
             TASK_SNAPSHOT_NOTE, PREDICTIONS_DIR, CACHE_FILE, LOG_FILE, FAILED_FILE, LOCK_FILE)
#: The keys of ``results.json`` that execution in simulation writes.
SIM_KEYS = ("success", "sim_accuracy", "sim_cl_metrics", "sim")
_CACHE_SCHEMA = 3  # 2: summaries carry failure_kind; 3: checks and stopped_early


class RunFileError(ValueError):
    """A run file exists but cannot be read (truncated, not what clfd-bench writes)."""


class RunLockedError(RuntimeError):
    """Another process holds the run directory (its message names the pid and command)."""


@dataclasses.dataclass(frozen=True)
class RunStatus:
    """Where a run stands.

    Attributes:
        state: ``"done"``, ``"partial"`` (started, something left to do), ``"failed"`` (its
            last attempt crashed, see ``failed.json``) or ``"missing"`` (no directory).
        trained: tasks trained so far; wanted: tasks asked for.
        executed: tasks whose predictions were executed by the current simulator (None
            without simulation).
        reason: what is left to do, in words ("" when done).
    """

    state: str
    trained: int = 0
    wanted: int = 0
    executed: int | None = None
    reason: str = ""


@contextlib.contextmanager
def exclusive(directory: str | os.PathLike[str], what: str) -> Iterator[Path]:
    """Holds ``directory/.lock`` (created, with ``directory``, if missing) for the block.

    Args:
        directory: the folder to own (a run directory, a leaderboard's output).
        what: what the holder does, shown to a refused second process.

    Raises:
        RunLockedError: another live process holds it.
    """
    folder = Path(directory)
    created = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_FILE
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    acquired = False
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                raise
            holder = os.pread(fd, 4096, 0).decode("utf-8", "replace").strip() or "unknown"
            raise RunLockedError(
                f"{folder} is in use by another process ({holder}); wait for it to finish "
                "or end it, then run this command again") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()}: {what}".encode(), 0)
        _remove_stale_temp_files(folder)
        acquired = True
        yield folder
    finally:
        if created and acquired and {p.name for p in folder.iterdir()} <= {LOCK_FILE}:
            # Nothing was written (e.g. the first task diverged): leave no folder behind.
            path.unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                folder.rmdir()
        os.close(fd)  # releases the flock


def _remove_stale_temp_files(folder: Path) -> None:
    """Temporary files of atomic writes a killed process left (only while holding the lock)."""
    for sub in (folder, folder / PREDICTIONS_DIR, folder / CHECKPOINTS_DIR):
        if sub.is_dir():
            for tmp in sub.glob(".*.tmp"):
                tmp.unlink(missing_ok=True)


def find_runs(root: str | os.PathLike[str]) -> list[RunDir]:
    """The run directories under ``root`` (a results folder: ``runs/<dataset>/<method>/...``;
    or a run directory itself): every folder holding a ``results.json``, sorted by path.
    Hidden folders (a replaced run set aside, a staging copy) are skipped."""
    root = Path(root)
    found = [p.parent for p in root.rglob(RESULTS_FILE)
             if not any(part.startswith(".") for part in p.parent.relative_to(root).parts)]
    return [RunDir(p) for p in sorted(found)]


class RunDir:
    """One run directory (see the module docstring for its files).

    Args:
        path: the directory (need not exist yet).
    """

    def __init__(self, path: str | os.PathLike[str]):
        self.path = Path(path)

    def __repr__(self) -> str:
        return f"RunDir({str(self.path)!r})"

    # ------------------------------------------------------------------ paths
    @property
    def results_path(self) -> Path:
        return self.path / RESULTS_FILE

    @property
    def checkpoint_path(self) -> Path:
        return self.path / CHECKPOINT_FILE

    @property
    def cache_path(self) -> Path:
        return self.path / CACHE_FILE

    @property
    def log_path(self) -> Path:
        return self.path / LOG_FILE

    @property
    def failed_path(self) -> Path:
        return self.path / FAILED_FILE

    def predictions_path(self, after_task: int) -> Path:
        """``predictions/after_task_{i}.npz``."""
        return self.path / self.predictions_name(after_task)

    @staticmethod
    def predictions_name(after_task: int) -> str:
        """The predictions file of ``after_task`` relative to the run directory."""
        return f"{PREDICTIONS_DIR}/after_task_{after_task}.npz"

    def kept_checkpoint_path(self, after_task: int) -> Path:
        """``checkpoints/after_task_{i}.pt`` (--keep-checkpoints)."""
        return self.path / CHECKPOINTS_DIR / f"after_task_{after_task}.pt"

    def exists(self) -> bool:
        return self.path.is_dir()

    def entries(self) -> list[str]:
        """The names in the run directory, sorted (empty when it does not exist)."""
        return sorted(p.name for p in self.path.iterdir()) if self.exists() else []

    def portable_files(self) -> list[Path]:
        """The files that make up the run, for copying it elsewhere (a shipped bundle):
        ``results.json``, ``checkpoint.pt``, the task snapshot and its note, kept
        checkpoints, every predictions file, ``sim_cache.json`` and ``train.log``; not the
        lock, ``failed.json`` or temporary files. Sorted; only those that exist."""
        fixed = [self.results_path, self.checkpoint_path, self.task_snapshot_path,
                 self.task_snapshot_note_path, self.cache_path, self.log_path]
        kept = sorted((self.path / CHECKPOINTS_DIR).glob("after_task_*.pt"))
        preds = sorted((self.path / PREDICTIONS_DIR).glob("after_task_*.npz"))
        return sorted(p for p in [*fixed, *kept, *preds] if p.is_file())

    def lock(self, what: str) -> contextlib.AbstractContextManager[Path]:
        """Exclusive ownership of the run for a writer (:func:`exclusive`)."""
        return exclusive(self.path, what)

    # ------------------------------------------------------------------ results.json
    def read_results(self) -> dict[str, Any] | None:
        """``results.json``, or None when there is none.

        Raises:
            RunFileError: it exists but is not readable JSON.
        """
        try:
            text = self.results_path.read_text(encoding="utf-8")
        except FileNotFoundError:
            return None
        try:
            doc = json.loads(text)
        except ValueError as exc:
            raise RunFileError(f"{self.results_path} is not valid JSON ({exc}); run the "
                               "`clfd-bench train` command of this run again to rewrite it"
                               ) from None
        if not isinstance(doc, dict):
            raise RunFileError(f"{self.results_path} does not hold a results object")
        return doc

    def load_results(self) -> dict[str, Any]:
        """``results.json``, which must exist.

        Raises:
            FileNotFoundError: there is none (the message says what RUN_DIR must be).
            RunFileError: it is unreadable.
        """
        doc = self.read_results()
        if doc is None:
            raise FileNotFoundError(f"{self.results_path} not found: RUN_DIR must be a "
                                    "directory written by `clfd-bench train`")
        return doc

    def write_training_results(self, results: Mapping[str, Any]) -> dict[str, Any]:
        """Writes the training fields of ``results.json`` (for a run scored from external
        predictions, its scoring fields); returns what was written.

        Keys other than the training fields are kept, except execution fields (`SIM_KEYS`)
        that cover another number of tasks than ``results["tasks_done"]``: they are dropped,
        to be written again by the execution step.
        """
        merged = dict(results)
        try:
            existing = self.read_results() or {}
        except RunFileError:
            existing = {}  # rewritten below from the training state
        done = results.get("tasks_done")
        sim_current = (existing.get("sim") or {}).get("evaluated_tasks") == done
        for key, value in existing.items():
            if key in results or (key in SIM_KEYS and not sim_current):
                continue
            merged[key] = value
        atomic_write_json(self.results_path, merged)
        return merged

    def write_sim_results(self, fields: Mapping[str, Any]) -> dict[str, Any]:
        """Writes the execution fields (`SIM_KEYS`) into ``results.json``, every other key
        kept; returns the whole document."""
        unknown = set(fields) - set(SIM_KEYS)
        if unknown:
            raise ValueError(f"not execution fields: {sorted(unknown)}")
        doc = self.load_results()
        doc.update(fields)
        atomic_write_json(self.results_path, doc)
        return doc

    # ------------------------------------------------------------------ predictions
    def save_predictions(self, after_task: int, predictions: Sequence[np.ndarray]) -> None:
        """Writes ``predictions/after_task_{i}.npz``: ``task_{j}`` = ``predictions[j]``
        ``[N, T, D]``."""
        buf = io.BytesIO()
        np.savez(buf, **{f"task_{j}": np.asarray(p) for j, p in enumerate(predictions)})
        atomic_write_bytes(self.predictions_path(after_task), buf.getvalue())

    def predictions_sha256(self, after_task: int) -> str | None:
        """The hex sha256 of ``predictions/after_task_{i}.npz`` (None when there is none)."""
        from clfd_bench.io import sha256_file

        path = self.predictions_path(after_task)
        return sha256_file(path) if path.is_file() else None

    def load_predictions(self, after_task: int) -> dict[int, np.ndarray]:
        """The predictions after learning task ``after_task``: task ``j`` (j <= after_task)
        -> ``[N, T, D]`` float64, data units.

        Raises:
            FileNotFoundError: none were saved (the message says how to regenerate them).
            RunFileError: the file is unreadable or lacks a task.
        """
        path = self.predictions_path(after_task)
        if not path.is_file():
            raise FileNotFoundError(
                f"{path} not found: the run saved no predictions after task {after_task}; "
                "re-run `clfd-bench train` with the same arguments (it resumes and rewrites "
                "them)")
        out: dict[int, np.ndarray] = {}
        try:
            with np.load(path, allow_pickle=False) as npz:
                keys = list(npz.files)
                for key in keys:
                    digits = key[5:] if key.startswith("task_") else key
                    if digits.isdigit():
                        out[int(digits)] = np.asarray(npz[key], dtype=np.float64)
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise RunFileError(f"{path} is unreadable ({exc}); delete it and re-run the "
                               "`clfd-bench train` command of this run") from None
        missing = [j for j in range(after_task + 1) if j not in out]
        if missing:
            raise RunFileError(f"{path} holds no predictions of tasks {missing} (keys: {keys})")
        return out

    # ------------------------------------------------------------------ checkpoint
    def has_checkpoint(self) -> bool:
        return self.checkpoint_path.is_file()

    def write_checkpoint(self, data: bytes, keep_as: int | None = None) -> None:
        """Writes ``checkpoint.pt`` (bytes of :mod:`clfd_bench.harness.checkpoint`), and
        ``checkpoints/after_task_{keep_as}.pt`` too when ``keep_as`` is given."""
        atomic_write_bytes(self.checkpoint_path, data)
        if keep_as is not None:
            atomic_write_bytes(self.kept_checkpoint_path(keep_as), data)

    def read_checkpoint(self) -> bytes:
        """The bytes of ``checkpoint.pt``.

        Raises:
            FileNotFoundError: the run has none yet.
        """
        if not self.checkpoint_path.is_file():
            raise FileNotFoundError(f"{self.checkpoint_path} does not exist: {self.path} is "
                                    "not a (started) run directory")
        return self.checkpoint_path.read_bytes()

    def checkpoint_mtime(self) -> float:
        """Modification time of ``checkpoint.pt`` (-1 when there is none)."""
        try:
            return self.checkpoint_path.stat().st_mtime
        except FileNotFoundError:
            return -1.0

    def checkpoint_sha256(self) -> str:
        """The hex sha256 of ``checkpoint.pt``."""
        from clfd_bench.io import sha256_file

        return sha256_file(self.checkpoint_path)

    # ------------------------------------------------------------------ task snapshot
    @property
    def task_snapshot_path(self) -> Path:
        """``task_snapshot.pt``: the task being learned, mid-way (bytes of
        :func:`clfd_bench.harness.checkpoint.encode_snapshot`)."""
        return self.path / TASK_SNAPSHOT_FILE

    @property
    def task_snapshot_note_path(self) -> Path:
        """``task_snapshot.json``: where the task snapshot stands, for :meth:`status`."""
        return self.path / TASK_SNAPSHOT_NOTE

    def has_task_snapshot(self) -> bool:
        return self.task_snapshot_path.is_file()

    def write_task_snapshot(self, data: bytes, note: Mapping[str, Any] | None = None) -> None:
        """Writes ``task_snapshot.pt`` (atomically: a kill leaves the old one or the new), then
        ``note`` (JSON: ``task``, ``task_name``, ``parts`` {part: "learned" | "iteration N"},
        ``cpu_s``) to ``task_snapshot.json`` for :meth:`status`; without ``note`` an older
        note is removed. A kill between the two writes leaves the note one snapshot behind:
        the status then names an earlier iteration, never a later one."""
        atomic_write_bytes(self.task_snapshot_path, data)
        if note is None:
            self.task_snapshot_note_path.unlink(missing_ok=True)
        else:
            atomic_write_json(self.task_snapshot_note_path, dict(note))

    def task_snapshot_note(self) -> dict[str, Any] | None:
        """``task_snapshot.json`` as written with the snapshot (None: no snapshot, no note,
        or a note that cannot be read; it is only for the status line)."""
        if not self.has_task_snapshot():
            return None
        try:
            doc = json.loads(self.task_snapshot_note_path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        return doc if isinstance(doc, dict) else None

    def read_task_snapshot(self) -> bytes:
        """The bytes of ``task_snapshot.pt`` (FileNotFoundError: there is none)."""
        return self.task_snapshot_path.read_bytes()

    def clear_task_snapshot(self) -> None:
        """Removes ``task_snapshot.pt`` (its task is finished and checkpointed, or the
        snapshot is of an older task), and its note."""
        self.task_snapshot_path.unlink(missing_ok=True)
        self.task_snapshot_note_path.unlink(missing_ok=True)

    # ------------------------------------------------------------------ rollout cache
    def load_cache(self, fingerprint: str) -> dict[str, dict[str, Any]]:
        """The executed rollouts of this simulator ``fingerprint`` (empty when the cache is
        missing, unreadable or of another simulator: it is only a cache)."""
        try:
            with open(self.cache_path, encoding="utf-8") as fh:
                doc = json.load(fh)
        except (OSError, ValueError):
            return {}
        if (not isinstance(doc, dict) or doc.get("schema") != _CACHE_SCHEMA
                or doc.get("fingerprint") != fingerprint):
            return {}
        return dict(doc.get("entries") or {})

    def save_cache(self, fingerprint: str, entries: Mapping[str, Any]) -> None:
        """Writes the rollout cache of simulator ``fingerprint``."""
        atomic_write_json(self.cache_path, {"schema": _CACHE_SCHEMA, "fingerprint": fingerprint,
                                            "entries": dict(entries)}, indent=None)

    # ------------------------------------------------------------------ grid bookkeeping
    def open_log(self):
        """``train.log`` opened for appending (binary); creates the directory."""
        self.path.mkdir(parents=True, exist_ok=True)
        return open(self.log_path, "ab")

    def log_tail(self, size: int = 4000) -> str:
        """The last ``size`` bytes of ``train.log`` as text ("" when there is none)."""
        try:
            with open(self.log_path, "rb") as fh:
                fh.seek(max(0, fh.seek(0, os.SEEK_END) - size))
                return fh.read().decode("utf-8", "replace")
        except FileNotFoundError:
            return ""

    def mark_failed(self, record: Mapping[str, Any]) -> None:
        """Records the last attempt's crash (``failed.json``)."""
        atomic_write_json(self.failed_path, dict(record))

    def clear_failed(self) -> None:
        self.failed_path.unlink(missing_ok=True)

    def failure(self) -> dict[str, Any] | None:
        """``failed.json`` (None when the last attempt did not crash)."""
        try:
            doc = json.loads(self.failed_path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            return None
        except ValueError:
            return {"error": "failed (failed.json unreadable)"}
        return doc if isinstance(doc, dict) else {"error": str(doc)}

    # ------------------------------------------------------------------ status
    def status(self, tasks: int, sim: bool, fingerprint: str | None = None) -> RunStatus:
        """Whether the run is done (module docstring).

        Args:
            tasks: the number of tasks the run must learn.
            sim: whether its predictions must be executed in simulation.
            fingerprint: the current simulator's fingerprint (None: any fingerprint counts).
        """
        if not self.exists():
            return RunStatus("missing", wanted=tasks, reason="not started")
        try:
            results = self.read_results() or {}
        except RunFileError:
            results = {}
        trained = int(results.get("tasks_done") or 0)
        sim_doc = results.get("sim") or {}
        executed = None
        stale = None  # the other simulator's fingerprint the executions were made by
        if sim:
            executed = int(sim_doc.get("evaluated_tasks") or 0)
            if results.get("success") is None:
                executed = 0
            elif fingerprint is not None and sim_doc.get("fingerprint") != fingerprint:
                stale, executed = str(sim_doc.get("fingerprint")), 0
        if not results.get("complete") or trained < tasks:
            reason = f"trained {trained}/{tasks} tasks"
            if self.has_task_snapshot():
                reason += f" ({self._snapshot_reason(trained)})"
        elif stale is not None:
            reason = (f"executed by simulator {stale}, but this one is {fingerprint} (its "
                      "files changed since): run it again to re-execute the predictions")
        elif sim and executed != trained:
            reason = f"executed {executed}/{trained} tasks in simulation"
        else:
            return RunStatus("done", trained, tasks, executed)
        state = "failed" if self.failed_path.is_file() else "partial"
        return RunStatus(state, trained, tasks, executed, reason)

    def _snapshot_reason(self, task: int) -> str:
        """"task 1 'e' resumes from its snapshot: position iteration 1088, 12 min of CPU
        in the task" (the note's details when it is of ``task``)."""
        note = self.task_snapshot_note()
        if not note or note.get("task") != task:
            return f"task {task} resumes from its snapshot"
        name = f" {note['task_name']!r}" if note.get("task_name") else ""
        parts = ", ".join(f"{kind} {where}" for kind, where in (note.get("parts") or {}).items())
        cpu = note.get("cpu_s")
        spent = f", {cpu / 60:.0f} min of CPU in the task" if isinstance(cpu, int | float) else ""
        return f"task {task}{name} resumes from its snapshot: {parts or 'started'}{spent}"

    # ------------------------------------------------------------------ replace (Ray)
    def replace_with(self, staging: str | os.PathLike[str]) -> None:
        """Puts the directory ``staging`` (a sibling, e.g. a run trained elsewhere) in place
        of this run directory. The old directory is renamed aside first and removed after, so
        at every moment one complete version is at a known name; a leftover aside copy of a
        killed swap is restored by the next call or removed once the new one is in place."""
        staging = Path(staging)
        aside = self.path.with_name(f".{self.path.name}.replaced")
        if aside.exists() and not self.path.exists():
            os.replace(aside, self.path)  # a killed swap: put the old version back first
        if aside.exists():
            shutil.rmtree(aside)
        if self.path.exists():
            os.replace(self.path, aside)
        os.replace(staging, self.path)
        fsync_dir(self.path.parent)
        if aside.exists():
            shutil.rmtree(aside)

