"""A run cut in the middle of a task resumes from its task snapshot and ends bit for bit as
the uninterrupted run: for every registered method, at a cut early in the first task and one
late in the last (after PackNet's pruning, the learning-rate warm-up and the horizon's
growth), with the stop rule on, in a pose run between its two models, and for runs learned
in lockstep. A negative control shows the cuts can see what a method keeps between
iterations. A stale, foreign or corrupt snapshot is removed or refused with a clear error.

The cut here raises right after the n-th snapshot is written (the process goes on to the
next run); tests/test_kill_resume.py kills the CLI with SIGKILL mid-task instead.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from run_checks import comparable

import clfd_bench.runs as runs
from clfd_bench.harness.checkpoint import CheckpointError
from clfd_bench.harness.protocol import (
    RunMismatchError,
    TrainingJob,
    run_training,
    run_trainings,
)
from clfd_bench.harness.run import TrainSpec
from clfd_bench.methods import list_methods
from clfd_bench.methods.packnet import PackNet
from clfd_bench.runs import TASK_SNAPSHOT_NOTE, RunDir

EVERY_ROUND = 1e-12
"""snapshot_every: a snapshot after every iteration but a model's last (which ends its task);
so a model of K iterations writes K - 1 snapshots, at iterations 1..K-1, and a pose run one
more when its position model is learned."""


class _Cut(Exception):
    """Stands for the end of the machine, right after a snapshot was written."""


@pytest.fixture
def cut_after(monkeypatch):
    """``cut_after(n)``: the n-th task snapshot written from now on ends the process's run
    (raises :class:`_Cut` once it is on disk); returns the counter's list."""
    written = []
    original = runs.RunDir.write_task_snapshot

    def arm(n: int) -> list[Path]:
        written.clear()

        def write(self, data: bytes, note=None) -> None:
            original(self, data, note)
            written.append(self.path)
            if len(written) == n:
                raise _Cut(f"cut after snapshot {n}")

        monkeypatch.setattr(runs.RunDir, "write_task_snapshot", write)
        return written

    yield arm
    monkeypatch.setattr(runs.RunDir, "write_task_snapshot", original)


def _config(method: str, dataset: str = "helloworld", seed: int = 0,
            overrides: tuple[str, ...] = ()):
    return TrainSpec(method, dataset, "smoke", seed=seed, tasks=2,
                     overrides=overrides).config()


def _predictions(out: Path) -> dict[int, np.ndarray]:
    return RunDir(out).load_predictions(1)


def _same(a: Path, b: Path) -> bool:
    pa, pb = _predictions(a), _predictions(b)
    return sorted(pa) == sorted(pb) and all(np.array_equal(pa[j], pb[j]) for j in pa)


def _results(out: Path) -> dict:
    return comparable(RunDir(out).load_results(), frozenset(
        {"train_time_s", "train_time_s_by_part", "train_cpu_s", "iterations_per_s_by_part",
         "provenance", "TE", "CL_score", "CL_stability", "rank"}))


def _cut_and_resume(config, out: Path, cut_after, n: int) -> list[str]:
    """Train ``config`` into ``out`` with a snapshot every iteration, cut after the n-th
    snapshot, resume without snapshots; returns the resumed run's log."""
    cut_after(n)
    with pytest.raises(_Cut):
        run_training(config, out, log=None, snapshot_every=EVERY_ROUND)
    assert RunDir(out).has_task_snapshot()
    # the status line says where the snapshot stands, as the resumed run's log does
    status = RunDir(out).status(99, sim=False).reason
    cut_after(0)
    log: list[str] = []
    run_training(config, out, log=log.append, snapshot_every=0)
    assert not RunDir(out).has_task_snapshot(), "the finished task removes its snapshot"
    assert not (out / TASK_SNAPSHOT_NOTE).exists(), "and its note"
    resumed = next(line for line in log if "from its snapshot: " in line)
    task, name, where = re.search(r"in task (\d+) \((\w+)\) from its snapshot: (.*)$",
                                  resumed).groups()
    assert f"(task {task} '{name}' resumes from its snapshot: {where}, " in status, status
    return log


@pytest.mark.parametrize("method", list_methods())
def test_every_method_resumes_mid_task_bit_for_bit(method, tmp_path, cut_after):
    config = _config(method)
    iterations = config.parts[0][1].iterations
    run_training(config, tmp_path / "ref", log=None, snapshot_every=0)
    # early in task 0; late in task 1 (iteration iterations - 3, after PackNet's pruning)
    for n, where in ((3, "task 0 (h) from its snapshot: position iteration 3"),
                     (iterations - 1 + iterations - 3, "task 1 (e) from its snapshot: position "
                                                       f"iteration {iterations - 3}")):
        out = tmp_path / f"cut{n}"
        log = _cut_and_resume(config, out, cut_after, n)
        assert any(where in line for line in log), log
        assert _same(tmp_path / "ref", out), f"{method}: cut after snapshot {n} changed it"
        assert _results(out) == _results(tmp_path / "ref")
        resumed = RunDir(out).load_results()["provenance"]["resumed_in_task"]
        assert [r["task"] for r in resumed] == [0 if n == 3 else 1]


def test_a_method_that_forgets_its_step_state_is_caught(tmp_path, cut_after, monkeypatch):
    """Negative control: PackNet without its step state ("pruned") prunes its task twice when
    resumed after pruning, and the comparison above sees it."""
    config = _config("packnet")
    iterations = config.parts[0][1].iterations
    run_training(config, tmp_path / "ref", log=None, snapshot_every=0)
    monkeypatch.setattr(PackNet, "step_state", lambda self: {})
    monkeypatch.setattr(PackNet, "load_step_state", lambda self, state: None)
    _cut_and_resume(config, tmp_path / "cut", cut_after, iterations - 1 + iterations - 3)
    assert not _same(tmp_path / "ref", tmp_path / "cut")


def test_the_stop_rule_and_its_lr_decays_resume(tmp_path, cut_after):
    """With the stop rule on (windows of 3, one lr decay), a cut in its middle ends the task
    at the same iteration with the same weights."""
    config = _config("hn", overrides=("stop_window=3", "stop_rel=0.3", "stop_decays=1",
                                      "horizon_ramp=0", "horizon_start=1"))
    run_training(config, tmp_path / "ref", log=None, snapshot_every=0)
    ref = RunDir(tmp_path / "ref").load_results()["iterations_by_part"]["position"]
    assert ref[1] < config.parts[0][1].iterations, "the stop rule should end task 1 early"
    _cut_and_resume(config, tmp_path / "cut", cut_after, ref[0] - 1 + ref[1] - 1)
    assert RunDir(tmp_path / "cut").load_results()["iterations_by_part"]["position"] == ref
    assert _same(tmp_path / "ref", tmp_path / "cut")


def test_a_task_refined_by_refine_gap_resumes(tmp_path, cut_after):
    """With ``refine_gap`` past every gap, each task ends with finer solver steps under a
    fresh stop rule; a cut in that last phase resumes with its steps, gaps and rule."""
    config = _config("hn", overrides=("stop_window=3", "stop_rel=0.3", "stop_decays=1",
                                      "horizon_ramp=0", "horizon_start=1", "iterations=300",
                                      "refine_gap=1e-12"))
    run_training(config, tmp_path / "ref", log=None, snapshot_every=0)
    ref = RunDir(tmp_path / "ref").load_results()
    iterations = ref["iterations_by_part"]["position"]
    assert min(ref["substeps_by_part"]["position"]) > 1, "both tasks should be refined"
    _cut_and_resume(config, tmp_path / "cut", cut_after, iterations[0] - 1 + iterations[1] - 2)
    assert _same(tmp_path / "ref", tmp_path / "cut")
    assert _results(tmp_path / "cut") == _results(tmp_path / "ref")


@pytest.mark.parametrize("method", ["hn", "sg"])
def test_a_pose_run_resumes_between_and_inside_its_two_models(method, tmp_path, cut_after):
    """RoboTasks learns a position and an orientation model per task: a cut while the
    orientation model learns keeps the learned position model (not learned again), and a
    cut in the second task's position model resumes there."""
    config = _config(method, "robotasks")
    pos, ori = (cfg.iterations for _, cfg in config.parts)
    run_training(config, tmp_path / "ref", log=None, snapshot_every=0)
    # task 0: pos - 1 snapshots, one when the position model is learned, ori - 1 more
    cases = ((pos + 5, "task 0 (openbox) from its snapshot: position learned, "
                       "orientation iteration 5"),
             (pos + ori - 1 + 4, "task 1 (bottle2shelf) from its snapshot: position "
                                 "iteration 4"))
    for n, where in cases:
        out = tmp_path / f"cut{n}"
        log = _cut_and_resume(config, out, cut_after, n)
        assert any(where in line for line in log), log
        assert _same(tmp_path / "ref", out)
        assert _results(out) == _results(tmp_path / "ref")


def test_runs_in_lockstep_resume_mid_task(tmp_path, cut_after):
    """Two seeds learned in lockstep, cut mid-task, resumed in lockstep: each ends as it
    does alone (their snapshots are their own)."""
    configs = [_config("hn", seed=s) for s in (0, 1)]
    for s, config in enumerate(configs):
        run_training(config, tmp_path / f"alone{s}", log=None, snapshot_every=0)
    jobs = [TrainingJob(c, tmp_path / f"lock{s}", None, snapshot_every=EVERY_ROUND)
            for s, c in enumerate(configs)]
    written = cut_after(2 * 40)  # both snapshot each round: task 0 has 29 rounds, so task 1
    with pytest.raises(_Cut):
        run_trainings(jobs)
    assert {p.name for p in written} == {"lock0", "lock1"}
    cut_after(0)
    outcomes = run_trainings([TrainingJob(c, tmp_path / f"lock{s}", None, snapshot_every=0)
                              for s, c in enumerate(configs)])
    assert not any(isinstance(o, Exception) for o in outcomes), outcomes
    for s in (0, 1):
        assert _same(tmp_path / f"alone{s}", tmp_path / f"lock{s}")


def test_a_stale_snapshot_is_removed_and_changes_nothing(tmp_path, cut_after):
    """A snapshot of a task already checkpointed (the process died between the checkpoint
    and the snapshot's removal) is removed with a line saying so."""
    config = _config("hn")
    run_training(config, tmp_path / "ref", log=None, snapshot_every=0)
    cut_after(5)
    with pytest.raises(_Cut):
        run_training(config, tmp_path / "early", log=None, snapshot_every=EVERY_ROUND)
    stale = RunDir(tmp_path / "early").read_task_snapshot()  # of task 0
    cut_after(0)
    only0 = TrainSpec("hn", "helloworld", "smoke", tasks=1).config()
    run_training(only0, tmp_path / "one", log=None, snapshot_every=0)  # task 0 checkpointed
    one = RunDir(tmp_path / "one")
    one.write_task_snapshot(stale)
    log: list[str] = []
    run_training(config, one.path, log=log.append, snapshot_every=0)
    assert any("is of task 0, not of the next task 1: removed" in line for line in log), log
    assert not one.has_task_snapshot()
    assert _same(tmp_path / "ref", one.path)


def test_a_snapshot_of_another_configuration_is_refused(tmp_path, cut_after):
    cut_after(3)
    with pytest.raises(_Cut):
        run_training(_config("hn"), tmp_path / "run", log=None, snapshot_every=EVERY_ROUND)
    cut_after(0)
    other = _config("hn", overrides=("lr=0.001",))
    with pytest.raises(RunMismatchError, match=r"task_snapshot\.pt is of a run with a different "
                                               r"configuration \(.*lr"):
        run_training(other, tmp_path / "run", log=None)


def test_a_corrupt_snapshot_is_refused_with_the_fix(tmp_path, cut_after):
    cut_after(3)
    with pytest.raises(_Cut):
        run_training(_config("hn"), tmp_path / "run", log=None, snapshot_every=EVERY_ROUND)
    cut_after(0)
    run = RunDir(tmp_path / "run")
    run.task_snapshot_path.write_bytes(run.read_task_snapshot()[:100])
    with pytest.raises(CheckpointError, match=r"task_snapshot\.pt is not a readable clfd-bench "
                                              r"task snapshot .*delete it"):
        run_training(_config("hn"), run.path, log=None)
