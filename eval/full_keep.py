"""Keeps the `full` profile's finished runs in the repository, and puts them back.

A `full` run (issue 38) takes one to several hours of CPU, longer than the machines this
project's sessions run on live, and a run directory outside the repository is lost with its
machine. So every finished run of ``eval/full_runs.sh`` is kept here as one deterministic
archive (:func:`clfd_bench.pretrained.make_archive`) of its directory **without its
checkpoint** (``checkpoint.pt`` and ``checkpoints/``: 9-40 MB a run, and a finished run
needs no resume): ``results.json``, every ``predictions/after_task_{i}.npz``,
``sim_cache.json`` and ``train.log``. That is all a leaderboard reads, and all that
re-executing the predictions under another simulator needs (``restore`` does it: see
below). What a kept run cannot do
is continue training or be rendered from its model: videos execute the predictions, so they
still work.

    python eval/full_keep.py save results/full docs/studies/full-runs
    python eval/full_keep.py save --partial results/full docs/studies/full-runs   # session end
    python eval/full_keep.py restore docs/studies/full-runs results/full

**Half-finished runs (``--partial``).** A run of several hours does not fit one session's
machine (CHN HelloWorld on an AMD EPYC: about 1 000 s of CPU a letter, 2 h for seven). With
``--partial``, ``save`` also keeps every unfinished run that has learned at least one task,
**with** its checkpoint (the last finished task's: the run resumes after it, as a killed run
does), so the next machine continues it instead of starting again; the manifest marks it
``"partial": true``. Only checkpoints up to ``--max-mb`` (default 20) are kept, because each
one stays in the repository's history: CHN's HelloWorld checkpoint is 7.6 MB, a RoboTasks SG
run's four networks about 100 MB (refused, said in one line). The run may go on training
meanwhile: its files are copied first, and the copy is kept only when its checkpoint, its
``results.json`` and its predictions describe the same finished tasks (a task that finishes
during the copy makes ``save`` copy again, up to three times, else skip the run for this
time); ``eval/full_runs.sh`` does it every 30 minutes while its runs train, so a machine that
ends without warning loses at most the task being learned. ``restore`` extracts a partial run
with its checkpoint and does not execute it again: the grid resumes it, trains what is left
and executes it. Once it is done, ``save`` archives it again without its checkpoint, in place
of the partial archive. A run's
``task_snapshot.pt`` (the task being learned, with the optimiser's moments: about three times
its checkpoint, over 100 MB for a RoboTasks run) is never kept, nor its note: it resumes the
task mid-way on the machine that wrote it, which sessions on a machine that lives on use (a
killed run continues there from its last snapshot, at most ten minutes back).

``save`` archives every run under OUT (``OUT/<dataset>/runs/<dataset>/<method>/<run>``, as
``eval/full_runs.sh`` lays them out) that is done (every task trained and executed by the
current simulator) and not kept yet, as ``KEEP/<the same path>.tar.xz``, and records its
sha256 and size in ``KEEP/MANIFEST.json``.
``restore`` extracts every kept run whose directory is missing under OUT, after checking its
sha256 (it never replaces a run directory that exists), and executes again the predictions of
a kept run that another simulator executed (``clfd-bench evaluate``'s step): without a
checkpoint the grid could not resume such a run, it would train it from the start.
``eval/full_runs.sh`` restores before it starts, so the leaderboard skips the kept runs.
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

from clfd_bench.execution.fingerprint import sim_fingerprint
from clfd_bench.harness.checkpoint import decode_checkpoint
from clfd_bench.io import atomic_write_json, sha256_file
from clfd_bench.pretrained import Bundle, PretrainedError, extract_archive, make_archive
from clfd_bench.runs import TASK_SNAPSHOT_FILE, TASK_SNAPSHOT_NOTE, RunDir, find_runs

MANIFEST = "MANIFEST.json"
#: Held while ``save`` writes into KEEP (full_runs.sh's periodic save and a stage's save).
KEEP_LOCK = ".full_keep.lock"
#: How many times ``save --partial`` copies a training run before it skips it this time.
COPY_TRIES = 3
#: What a partial run's archive leaves out (its checkpoint.pt goes in); a finished one's
#: leaves its checkpoint out too (LEFT_OUT).
PARTIAL_LEFT_OUT = ("checkpoints", TASK_SNAPSHOT_FILE, TASK_SNAPSHOT_NOTE)
LEFT_OUT = ("checkpoint.pt", *PARTIAL_LEFT_OUT)


def _manifest(keep: Path) -> dict:
    path = keep / MANIFEST
    return json.loads(path.read_text()) if path.is_file() else {}


def save(out: Path, keep: Path, partial: bool = False, max_mb: float = 20.0) -> int:
    """Archives the finished runs of ``out`` not kept yet, and those kept from an earlier
    simulator that this one has executed again (restored and refreshed: archived again, so
    the next restore needs no execution); with ``partial``, also the unfinished runs that
    learned a task since they were last kept, with their checkpoint when it is at most
    ``max_mb`` MB (module docstring). Returns how many it archived."""
    with _locked(keep):
        return _save(out, keep, partial, max_mb)


@contextlib.contextmanager
def _locked(keep: Path):
    """Holds ``KEEP/.full_keep.lock`` (waiting for another ``save`` to finish)."""
    fd = os.open(keep / KEEP_LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _save(out: Path, keep: Path, partial: bool, max_mb: float) -> int:
    manifest, fingerprint, saved = _manifest(keep), sim_fingerprint(), 0
    for run in find_runs(out):
        key = run.path.relative_to(out).as_posix()
        entry = manifest.get(key) or {}
        kept = None if entry.get("partial") else entry or None  # a finished run, archived
        if kept and kept.get("simulator") == fingerprint:
            continue
        results, tasks, state = _state(run, fingerprint)
        if kept and (state.state != "done" or tasks != kept["tasks"]):
            continue  # kept; not (yet) executed by this simulator
        if state.state == "done" and tasks > 0:
            sha = _archive(run, keep, key, left_out=LEFT_OUT)
            manifest[key] = _entry(keep, key, sha, results, tasks)
        elif partial and state.state == "partial" and tasks > 0:
            if tasks <= entry.get("tasks", 0):
                continue  # kept partial at this task already
            ckpt = run.checkpoint_path
            mb = ckpt.stat().st_size / 1e6 if ckpt.is_file() else 0.0
            if mb == 0 or mb > max_mb:
                why = ("no checkpoint" if mb == 0
                       else f"checkpoint {mb:.1f} MB > --max-mb {max_mb:g}")
                print(f"  {key}: not kept (unfinished, {tasks} tasks learned; {why})")
                continue
            copied = _archive_consistent(run, keep, key)
            if copied is None:
                print(f"  {key}: not kept this time (a task finished during each of "
                      f"{COPY_TRIES} copies; the next save tries again)")
                continue
            sha, results, tasks = copied
            manifest[key] = _entry(keep, key, sha, results, tasks) | {"partial": True}
        else:
            print(f"  {key}: not kept ({state.reason or state.state})")
            continue
        atomic_write_json(keep / MANIFEST, dict(sorted(manifest.items())))
        saved += 1
        what = "partial, with its checkpoint, " if manifest[key].get("partial") else ""
        print(f"  {key}: kept ({what}{tasks} tasks, "
              f"{manifest[key]['size'] / 1e6:.2f} MB, simulator {fingerprint})")
    return saved


def _archive(run: RunDir, keep: Path, key: str, left_out: tuple[str, ...]) -> str:
    """Writes ``KEEP/<key>.tar.xz`` from the run without ``left_out``; returns its sha256."""
    with _staged(run, keep, key, left_out) as (copy, archive):
        return make_archive(copy.path, archive)


@contextlib.contextmanager
def _staged(run: RunDir, keep: Path, key: str, left_out: tuple[str, ...]):
    """Yields ``(copy, archive)``: a copy of the run without ``left_out`` in a temporary
    folder under KEEP (removed after the block), and the path of its archive."""
    archive = keep / f"{key}.tar.xz"
    archive.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".keep-", dir=keep) as tmp:
        staging = Path(tmp) / run.path.name
        _copy_run(run.path, staging, left_out)
        yield RunDir(staging), archive


def _copy_run(source: Path, staging: Path, left_out: tuple[str, ...]) -> None:
    shutil.copytree(source, staging, ignore=shutil.ignore_patterns(*left_out))


def _archive_consistent(run: RunDir, keep: Path, key: str) -> tuple[str, dict, int] | None:
    """A partial run's archive, with its checkpoint, from a copy whose files agree (the run
    may be training: a task finishing during the copy leaves a checkpoint of one more task
    than the copied ``results.json``, or predictions missing). Returns ``(sha256, results,
    tasks)`` of the copy archived, or None when ``COPY_TRIES`` copies all disagreed."""
    for _ in range(COPY_TRIES):
        with _staged(run, keep, key, PARTIAL_LEFT_OUT) as (copy, archive):
            try:  # RunFileError and CheckpointError are ValueErrors
                results = copy.read_results() or {}
                header, _ = decode_checkpoint(copy.read_checkpoint(), str(copy.checkpoint_path))
            except (OSError, ValueError):
                continue
            tasks = int(results.get("tasks_done") or 0)
            learned = len(header["state"]["train_time_s"])
            if tasks == learned and all(copy.predictions_path(i).is_file()
                                        for i in range(tasks)):
                return make_archive(copy.path, archive), results, tasks
    return None


def _entry(keep: Path, key: str, sha: str, results: dict, tasks: int) -> dict:
    archive = keep / f"{key}.tar.xz"
    return {"sha256": sha, "size": archive.stat().st_size, "tasks": tasks,
            "train_cpu_s": results.get("train_cpu_s"),
            "simulator": (results.get("sim") or {}).get("fingerprint")}


def restore(keep: Path, out: Path, refresh=None) -> int:
    """Extracts the kept runs missing under ``out``, then executes again the predictions of
    every kept run there that another simulator executed (``refresh``, default
    :func:`clfd_bench.execution.evaluate.evaluate_run`): a kept run has no checkpoint, so the
    grid, finding it stale, would train it again from the start. Returns how many it
    extracted."""
    if refresh is None:
        from clfd_bench.execution.evaluate import evaluate_run as refresh
    restored = 0
    for key, entry in _manifest(keep).items():
        target = out / key
        partial = bool(entry.get("partial"))
        if target.exists():
            if not partial:
                _refresh_if_stale(RunDir(target), key, refresh)
            continue
        archive = keep / f"{key}.tar.xz"
        if not archive.is_file() or sha256_file(archive) != entry["sha256"]:
            raise PretrainedError(f"{archive}: missing or not the archive {MANIFEST} "
                                  "records; check it out again (git checkout -- "
                                  f"{archive})")
        bundle = Bundle(name=key, file=archive.name, sha256=entry["sha256"],
                        description="a kept full run", dataset=key.split("/")[0],
                        profile="full",
                        methods=(), made_with_version="", size=int(entry["size"]))
        extract_archive(archive, target, bundle)
        restored += 1
        if partial:  # the grid resumes it after its last kept task, and executes it
            print(f"  {key}: restored, unfinished ({entry['tasks']} tasks, with its checkpoint)")
            continue
        print(f"  {key}: restored")
        _refresh_if_stale(RunDir(target), key, refresh)
    return restored


def _state(run: RunDir, fingerprint: str):
    """``(results, tasks learned, status)`` of a run, judged as done only when every task it
    learned was executed by the simulator ``fingerprint``."""
    results = run.read_results() or {}
    tasks = int(results.get("tasks_done") or 0)
    return results, tasks, run.status(tasks, sim=True, fingerprint=fingerprint)


def _refresh_if_stale(run: RunDir, key: str, refresh) -> None:
    if _state(run, sim_fingerprint())[2].state != "done":
        print(f"  {key}: executed by another simulator; executing its predictions again")
        refresh(run.path)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="what", required=True)
    s = sub.add_parser("save", help="archive OUT's finished runs into KEEP")
    s.add_argument("out", type=Path)
    s.add_argument("keep", type=Path)
    s.add_argument("--partial", action="store_true",
                   help="also keep unfinished runs with their checkpoint (they may be "
                        "training: a copy whose files agree is kept)")
    s.add_argument("--max-mb", type=float, default=20.0,
                   help="largest checkpoint --partial keeps, in MB (default 20)")
    r = sub.add_parser("restore", help="extract KEEP's runs missing under OUT")
    r.add_argument("keep", type=Path)
    r.add_argument("out", type=Path)
    args = parser.parse_args()
    try:
        if args.what == "save":
            if not args.out.is_dir():
                raise PretrainedError(f"{args.out}: no such folder (the OUT of "
                                      "eval/full_runs.sh)")
            args.keep.mkdir(parents=True, exist_ok=True)
            n = save(args.out, args.keep, partial=args.partial, max_mb=args.max_mb)
            print(f"full_keep: {n} run(s) archived into {args.keep}")
        else:
            print(f"full_keep: {restore(args.keep, args.out)} run(s) restored into {args.out}")
    except PretrainedError as exc:
        print(f"full_keep: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
