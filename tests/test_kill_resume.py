"""Runs and grids killed with SIGKILL at chosen moments, then started again, end with the same
results as uninterrupted ones; a killed grid leaves no process behind; a run directory is never
written by two processes.

Every kill here is a real SIGKILL of a real process (the CLI in a subprocess). Moments: while
training (after the first task's files are written), in the middle of an atomic write (the
temporary file complete, not yet renamed: ``CLFD_KILL_BEFORE_REPLACE``), while the last task's
predictions are executed, and the grid's parent process.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from run_checks import RUN_TIMING, cli, comparable, finish, kill_when

from clfd_bench.runs import RunDir

TRAIN = ["train", "--method", "hn", "--dataset", "helloworld", "--profile", "smoke",
         "--tasks", "2", "--quiet"]


def _results(run_dir: Path) -> dict:
    return comparable(RunDir(run_dir).load_results())


def _temp_files(run_dir: Path) -> list[Path]:
    return [p for p in Path(run_dir).rglob(".*.tmp")]


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict:
    """An uninterrupted run (2 tasks, executed in simulation)."""
    out = tmp_path_factory.mktemp("reference")
    finish(cli(*TRAIN, "--out", str(out)))
    results = _results(out)
    assert results["tasks_done"] == 2 and results["sim"]["evaluated_tasks"] == 2
    return results


def test_kill_while_training_then_resume(reference, tmp_path):
    run = RunDir(tmp_path / "run")
    proc = cli(*TRAIN, "--out", str(run.path))
    kill_when(proc, lambda: run.predictions_path(0).is_file())
    status = run.status(2, sim=True)
    assert status.state == "partial", status
    finish(cli(*TRAIN, "--out", str(run.path)))
    assert _results(run.path) == reference
    assert not _temp_files(run.path)


@pytest.mark.parametrize("file_name, nth", [("results.json", 2), ("checkpoint.pt", 2),
                                            ("sim_cache.json", 2)])
def test_kill_in_the_middle_of_a_write_then_resume(reference, tmp_path, file_name, nth):
    """Killed with the new file complete in its temporary copy and the old one in place."""
    run = RunDir(tmp_path / "run")
    proc = cli(*TRAIN, "--out", str(run.path),
                env={"CLFD_KILL_BEFORE_REPLACE": f"{file_name}:{nth}"})
    proc.communicate(timeout=900)
    assert proc.returncode == -signal.SIGKILL
    assert _temp_files(run.path), "the kill should leave the temporary file"
    assert run.status(2, sim=True).state == "partial"
    finish(cli(*TRAIN, "--out", str(run.path)))
    assert _results(run.path) == reference
    assert not _temp_files(run.path)  # the next owner of the run removed them


def test_kill_while_executing_the_last_task_then_resume(reference, tmp_path):
    """Killed after the last task's training files are written (``complete`` is true), while
    its predictions execute: the run is not done, and resuming executes them."""
    run = RunDir(tmp_path / "run")
    proc = cli(*TRAIN, "--out", str(run.path))

    def executing_last() -> bool:
        try:
            doc = run.read_results() or {}
        except ValueError:
            return False
        return doc.get("tasks_done") == 2

    kill_when(proc, executing_last)
    doc = run.load_results()
    assert doc["complete"] and doc["tasks_done"] == 2
    assert "success" not in doc  # the smaller matrix of task 0 was dropped, not kept
    status = run.status(2, sim=True)
    assert status.state == "partial" and "executed" in status.reason
    finish(cli(*TRAIN, "--out", str(run.path)))
    assert _results(run.path) == reference


def test_kill_in_the_middle_of_a_task_resumes_from_its_snapshot(tmp_path):
    """Killed while the second task learns, with a task snapshot written every iteration: the
    resumed run starts at the snapshot's iteration (not at the task's start) and ends with the
    uninterrupted run's results and predictions, bit for bit."""
    slow = [*TRAIN, "--no-sim", "--set", "iterations=1500"]
    finish(cli(*slow, "--out", str(tmp_path / "ref"), "--snapshot-every", "0"))
    run = RunDir(tmp_path / "run")
    proc = cli(*slow, "--out", str(run.path), "--snapshot-every", "0.000001")

    def in_second_task() -> bool:
        try:
            return (run.has_task_snapshot() and run.has_checkpoint()
                    and run.task_snapshot_path.stat().st_mtime > run.checkpoint_mtime() + 0.3)
        except FileNotFoundError:  # replaced while looked at
            return False

    kill_when(proc, in_second_task)
    assert run.has_task_snapshot()
    out = finish(cli(*[a for a in slow if a != "--quiet"], "--out", str(run.path)))
    resumed = [line for line in out.splitlines() if "from its snapshot" in line]
    assert len(resumed) == 1 and "in task 1 (e) from its snapshot: position iteration" in \
        resumed[0], out
    iteration = int(resumed[0].rsplit(" ", 1)[1])
    assert 0 < iteration < 1500
    (record,) = run.load_results()["provenance"]["resumed_in_task"]
    assert record["task"] == 1 and record["parts"] == {"position": f"iteration {iteration}"}
    assert not run.has_task_snapshot()
    ignore = RUN_TIMING | {"resumed_in_task"}
    assert comparable(run.load_results(), ignore) == comparable(
        RunDir(tmp_path / "ref").load_results(), ignore)
    ref, got = RunDir(tmp_path / "ref").load_predictions(1), run.load_predictions(1)
    assert all(np.array_equal(ref[j], got[j]) for j in ref)


def test_a_second_trainer_of_the_same_run_is_refused(tmp_path):
    run = RunDir(tmp_path / "run")
    with run.lock("test holder"):
        proc = cli(*TRAIN, "--no-sim", "--out", str(run.path))
        out, err = proc.communicate(timeout=300)
    assert proc.returncode == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and f"pid {os.getpid()}" in lines[0] and "test holder" in lines[0]
    assert not run.results_path.exists()  # it trained nothing
    assert not run.path.exists()  # and neither holder left anything behind


def _processes_mentioning(text: str) -> list[int]:
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        if text in cmd:
            pids.append(int(entry.name))
    return pids


GRID = ["leaderboard", "--dataset", "helloworld", "--methods", "sg,hn", "--profile", "smoke",
        "--tasks", "2", "--no-sim", "--workers", "2"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="parent-death signal: Linux")
def test_kill_the_grid_parent_leaves_no_orphans_and_resumes(tmp_path):
    reference = tmp_path / "reference"
    finish(cli(*GRID, "--out", str(reference)))
    out = tmp_path / "grid"
    proc = cli(*GRID, "--out", str(out))
    runs = out / "runs" / "helloworld"
    kill_when(proc, lambda: any(runs.glob("*/*/train.log")))  # children are training
    # Only the grid's own process was killed (not its children's groups): the children
    # must end by themselves.
    deadline = time.monotonic() + 20
    while _processes_mentioning(str(out)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not _processes_mentioning(str(out)), "a killed grid left training processes"
    finish(cli(*GRID, "--out", str(out)))
    ref = json.loads((reference / "leaderboard.json").read_text())
    got = json.loads((out / "leaderboard.json").read_text())
    assert comparable(got["rows"]) == comparable(ref["rows"])
    for run_ref in sorted((reference / "runs").rglob("results.json")):
        run_got = out / run_ref.relative_to(reference)
        assert _results(run_got.parent) == _results(run_ref.parent), run_got


LOCKSTEP = ["leaderboard", "--dataset", "helloworld", "--methods", "hn", "--profile", "smoke",
            "--tasks", "2", "--seeds", "0,1,2", "--workers", "1", "--no-sim"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="parent-death signal: Linux")
def test_kill_a_lockstep_batch_in_the_middle_then_resume(tmp_path):
    """Three seeds trained in lockstep by one worker, killed (SIGKILL of the grid; its worker
    dies with it) once the batch has written some of its first task's files; resumed in
    lockstep, every run ends bit for bit as the same run trained alone without a kill."""
    alone = tmp_path / "alone"
    finish(cli(*LOCKSTEP, "--no-lockstep", "--out", str(alone)))
    out = tmp_path / "grid"
    proc = cli(*LOCKSTEP, "--out", str(out))
    runs = out / "runs" / "helloworld" / "hn"
    kill_when(proc, lambda: any(runs.glob("*/predictions/after_task_0.npz")))
    deadline = time.monotonic() + 20
    while _processes_mentioning(str(out)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not _processes_mentioning(str(out)), "a killed grid left its lockstep worker"
    states = [RunDir(d).status(2, sim=False).state for d in sorted(runs.iterdir())]
    assert "done" not in states and len(states) == 3, states
    finish(cli(*LOCKSTEP, "--out", str(out)))
    for ref in sorted((alone / "runs").rglob("results.json")):
        got = out / ref.relative_to(alone)
        assert _results(got.parent) == _results(ref.parent), got
        for pred in sorted(ref.parent.glob("predictions/*.npz")):
            a, b = np.load(pred), np.load(got.parent / "predictions" / pred.name)
            assert a.files == b.files and all(np.array_equal(a[k], b[k]) for k in a.files)
        assert "runs in lockstep" in RunDir(got.parent).log_path.read_text()
