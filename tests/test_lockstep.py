"""Runs trained in lockstep (several runs, one process, their task losses computed in one
stacked pass where that is exact) end exactly as each run alone: parameters, predictions,
checkpoints and results bit for bit, for every built-in method, with per-run task picks
(REP), padding (batches of different sizes), per-run stop rules and a run that diverges;
at the protocol level with runs resuming at different tasks; and in a grid's worker, where
one run's failure is its own.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess

import numpy as np
import pytest
import torch
from run_checks import RUN_TIMING, comparable

from clfd_bench.harness.config import PartConfig, resolve_config
from clfd_bench.harness.loop import TaskRun, TrainingDivergedError, train_task, train_tasks
from clfd_bench.harness.protocol import TrainingJob, run_training, run_trainings
from clfd_bench.harness.run import TrainSpec
from clfd_bench.harness.worker import Job, lockstep_argv
from clfd_bench.leaderboard.grid import GridOptions, lockstep_batches, make_grid
from clfd_bench.learning import objective
from clfd_bench.learning.node import NodeSpec
from clfd_bench.methods import TaskData, get_method_class
from clfd_bench.runs import RunDir

torch.set_num_threads(1)

# widths of 32 and batches of >= 8 rows: shapes whose batched products this machine's BLAS
# computes bit for bit as the single ones (checked: the tests below stack where it does)
SPEC = NodeSpec(dim=2, hidden=(32, 32), time_input=True)
CFG = PartConfig(
    iterations=6, lr=1e-2, node_hidden=(32, 32), task_emb_dim=3, hnet_hidden=(6,), beta=0.5,
    hnet_reg="batched", chunk_emb_dim=2, chunk_dim=32, si_c=0.3, si_xi=0.3, mas_lambda=0.1,
    mas_points=20, batch="trajectories", points=8, solver="rk4",
    extras={"ewc_lambda": 10.0, "ewc_gamma": 1.0, "ewc_batches": 1, "agem_memory": 2,
            "agem_ref_tasks": 1, "packnet_prune": 0.5, "packnet_retrain": 0.25},
)
# per-sample times and batches whose rows differ from run to run (multiple shooting)
SEGMENTS = dataclasses.replace(CFG, points=12, segments=True, horizon_start=0.3,
                               horizon_ramp=0.9, iterations=8)
METHODS = ["sg", "ft", "rep", "si", "mas", "hn", "chn", "ewc", "agem", "packnet"]


def _data(task: int) -> TaskData:
    """Task ``task``'s demos: 8 + task of them (so REP's replayed batches differ in rows)."""
    g = torch.Generator().manual_seed(100 + task)
    demos = torch.cumsum(torch.randn(8 + task, 30, 2, generator=g) * 0.1, dim=1)
    return TaskData(demos, torch.linspace(0, 2, 30))


def _methods(name: str, cfg: PartConfig, seeds) -> list:
    out = []
    for seed in seeds:
        torch.manual_seed(seed)
        out.append(get_method_class(name)(SPEC, cfg))
    return out


def _unit(method, task: int, cfg: PartConfig, seed: int) -> TaskRun:
    """Task ``task`` added to ``method``, RNGs seeded as the protocol seeds them."""
    torch.manual_seed(1000 * seed + task)
    method.add_task()
    return TaskRun(method, task, _data(task), cfg, torch.Generator().manual_seed(seed + task),
                   rng_state=torch.get_rng_state())


def _state(method) -> dict[str, torch.Tensor]:
    return {k: v.clone() for k, v in method.state_dict().items()}


def _same(a: dict[str, torch.Tensor], b: dict[str, torch.Tensor]) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


@pytest.fixture
def stacked_calls(monkeypatch) -> list[int]:
    """Counts the stacked passes (``rk4_mlp_stacked``) the loss computations make."""
    calls = [0]
    original = objective.rk4_mlp_stacked

    def counting(*args, **kwargs):
        calls[0] += 1
        return original(*args, **kwargs)

    monkeypatch.setattr(objective, "rk4_mlp_stacked", counting)
    monkeypatch.setattr(objective, "_EXACT", {})  # this test's own exactness checks
    return calls


@pytest.mark.parametrize("cfg", [CFG, SEGMENTS], ids=["shared-times", "segments"])
@pytest.mark.parametrize("name", METHODS)
def test_every_method_in_lockstep_equals_each_run_alone(name, cfg, stacked_calls):
    seeds = [0, 1, 2]
    alone, together = _methods(name, cfg, seeds), _methods(name, cfg, seeds)
    for task in range(2):
        for seed, method in zip(seeds, alone, strict=True):
            unit = _unit(method, task, cfg, seed)
            torch.set_rng_state(unit.rng_state)
            train_task(method, task, unit.data, cfg, unit.generator)
        results = train_tasks([_unit(m, task, cfg, s) for s, m in zip(seeds, together,
                                                                      strict=True)])
        assert all(r.iterations == cfg.iterations for r in results)
    for a, b in zip(alone, together, strict=True):
        assert _same(_state(a), _state(b))
    # where this machine's batched products equal its single ones, the pass was stacked
    if any(objective._EXACT.values()):
        assert stacked_calls[0] > 0


def test_where_the_stacked_pass_is_not_exact_each_run_is_computed_alone(monkeypatch):
    """A stacked pass that differs from the runs' own in the last bit (here: made to) fails
    the exactness check, and every loss of that shape is computed alone: still bit for bit."""
    original = objective.rk4_mlp_stacked
    monkeypatch.setattr(objective, "rk4_mlp_stacked",
                        lambda *a, **k: original(*a, **k) * (1 + 2**-20))
    monkeypatch.setattr(objective, "_EXACT", {})
    seeds = [0, 1]
    alone, together = _methods("hn", SEGMENTS, seeds), _methods("hn", SEGMENTS, seeds)
    for seed, method in zip(seeds, alone, strict=True):
        unit = _unit(method, 0, SEGMENTS, seed)
        torch.set_rng_state(unit.rng_state)
        train_task(method, 0, unit.data, SEGMENTS, unit.generator)
    train_tasks([_unit(m, 0, SEGMENTS, s) for s, m in zip(seeds, together, strict=True)])
    assert objective._EXACT and not any(objective._EXACT.values())
    for a, b in zip(alone, together, strict=True):
        assert _same(_state(a), _state(b))


def test_a_run_that_diverges_stops_alone_and_the_others_are_unchanged():
    seeds = [0, 1, 2]
    alone, together = _methods("hn", CFG, seeds), _methods("hn", CFG, seeds)
    units = [_unit(m, 0, CFG, s) for s, m in zip(seeds, together, strict=True)]
    units[1].data = TaskData(units[1].data.demos.clone(), units[1].data.times)
    units[1].data.demos[0, 5:] = float("nan")  # its loss is NaN from the first iteration
    results = train_tasks(units)
    assert isinstance(results[1], TrainingDivergedError) and results[1].iteration == 0
    assert "the loss is nan" in str(results[1])
    for k in (0, 2):
        unit = _unit(alone[k], 0, CFG, seeds[k])
        torch.set_rng_state(unit.rng_state)
        stats = train_task(alone[k], 0, unit.data, CFG, unit.generator)
        assert results[k].iterations == stats.iterations
        assert _same(_state(alone[k]), _state(together[k]))


def test_each_run_keeps_its_own_stop_rule():
    cfg = dataclasses.replace(SEGMENTS, iterations=60, horizon_ramp=0.05, stop_window=4,
                              stop_rel=0.1, stop_decays=0)  # stops after 15..23 iterations
    seeds = [0, 1, 2, 3]
    alone, together = _methods("sg", cfg, seeds), _methods("sg", cfg, seeds)
    expected = []
    for seed, method in zip(seeds, alone, strict=True):
        unit = _unit(method, 0, cfg, seed)
        torch.set_rng_state(unit.rng_state)
        expected.append(train_task(method, 0, unit.data, cfg, unit.generator).iterations)
    got = train_tasks([_unit(m, 0, cfg, s) for s, m in zip(seeds, together, strict=True)])
    assert [r.iterations for r in got] == expected
    assert len(set(expected)) > 1 and max(expected) < cfg.iterations  # stopped, not together
    for a, b in zip(alone, together, strict=True):
        assert _same(_state(a), _state(b))


IGNORE = RUN_TIMING


def _smoke(method: str, seed: int, tasks: int = 2):
    return resolve_config(method, "helloworld", "smoke", seed=seed, tasks=tasks)


def _run_files(run_dir) -> tuple[dict, dict, dict]:
    run = RunDir(run_dir)
    preds = {p.name: dict(np.load(p)) for p in sorted(run.path.glob("predictions/*.npz"))}
    checkpoint = torch.load(run.checkpoint_path, weights_only=False)
    return comparable(run.load_results(), IGNORE), preds, checkpoint


def _assert_same_run(a, b) -> None:
    results_a, preds_a, ckpt_a = _run_files(a)
    results_b, preds_b, ckpt_b = _run_files(b)
    assert results_a == results_b
    assert preds_a.keys() == preds_b.keys()
    for name in preds_a:
        assert all(np.array_equal(preds_a[name][k], preds_b[name][k]) for k in preds_a[name])
    tensors_a = {k: v for k, v in ckpt_a.items() if isinstance(v, torch.Tensor)}
    tensors_b = {k: v for k, v in ckpt_b.items() if isinstance(v, torch.Tensor)}
    assert _same(tensors_a, tensors_b)


@pytest.mark.parametrize("method", ["hn", "rep"])
def test_protocol_runs_in_lockstep_equal_runs_alone_even_resumed_at_different_tasks(
        tmp_path, method):
    for seed in (0, 1):
        run_training(_smoke(method, seed), tmp_path / f"alone{seed}", threads=1, log=None)
    # seed 1 has learned its first task alone; seed 0 starts from nothing
    run_training(_smoke(method, 1, tasks=1), tmp_path / "lock1", threads=1, log=None)
    lines: list[str] = []
    outcomes = run_trainings([TrainingJob(_smoke(method, 0), tmp_path / "lock0", lines.append),
                              TrainingJob(_smoke(method, 1), tmp_path / "lock1", None)],
                             threads=1)
    assert all(o["tasks_done"] == 2 for o in outcomes)
    assert json.loads(RunDir(tmp_path / "lock0").results_path.read_text())[
        "provenance"]["lockstep_by_task"] == [1, 2]  # task 0 alone, task 1 with seed 1
    for seed in (0, 1):
        _assert_same_run(tmp_path / f"alone{seed}", tmp_path / f"lock{seed}")
    assert sum("task 1/2" in line or "task 2/2" in line for line in lines) == 2


def test_a_worker_reports_each_lockstep_run_on_its_own(tmp_path):
    jobs = [Job(TrainSpec("sg", "helloworld", "smoke", seed=s, tasks=1), str(tmp_path / f"s{s}"),
                sim=False) for s in (0, 1)]
    outcomes = tmp_path / "outcomes.json"
    with RunDir(tmp_path / "s1").lock("a test holding it"):
        proc = subprocess.run(lockstep_argv(jobs, str(outcomes)), capture_output=True,
                              text=True, timeout=600,
                              env={**os.environ, "CLFD_NO_PROGRESS": "1"})
    assert proc.returncode == 2, proc.stderr
    codes = json.loads(outcomes.read_text())
    assert codes == {str(tmp_path / "s0"): 0, str(tmp_path / "s1"): 2}
    assert RunDir(tmp_path / "s0").load_results()["tasks_done"] == 1
    log1 = RunDir(tmp_path / "s1").log_path.read_text()
    assert "clfd-bench worker: error:" in log1 and "a test holding it" in log1
    assert "done:" in RunDir(tmp_path / "s0").log_path.read_text()
    assert not RunDir(tmp_path / "s1").results_path.exists()


def test_the_grid_batches_seeds_and_orders_of_one_method_only():
    opts = GridOptions(tasks=2, sim=False)
    grid = make_grid("helloworld", ["hn", "sg"], "fast", [0, 1, 2, 3, 4], [0, 1], opts)
    batches = lockstep_batches(grid, workers=4)
    assert sorted(len(b) for b in batches) == [5, 5, 5, 5]  # ceil(20 / 4) runs per batch
    assert all(len({s.method for s in b}) == 1 for b in batches)
    assert sorted(s.name for b in batches for s in b) == sorted(s.name for s in grid)
    hn = make_grid("helloworld", ["hn"], "fast", [0, 1, 2, 3, 4], [0], opts)
    assert sorted(len(b) for b in lockstep_batches(hn, workers=2)) == [2, 3]
    assert [len(b) for b in lockstep_batches(hn, workers=5)] == [1] * 5
    assert [len(b) for b in lockstep_batches(hn, workers=1, enabled=False)] == [1] * 5
    many = make_grid("helloworld", ["hn"], "fast", list(range(20)), [0], opts)
    assert sorted(len(b) for b in lockstep_batches(many, workers=1)) == [6, 7, 7]  # <= 8
    # adaptive solvers (paper: dopri5) and stable NODEs gain nothing: one process each
    paper = make_grid("helloworld", ["hn"], "paper", [0, 1, 2], [0], opts)
    assert [len(b) for b in lockstep_batches(paper, workers=1)] == [1, 1, 1]
    snode = make_grid("lasa", ["hn"], "fast", [0, 1], [0],
                      GridOptions(node="s", tasks=1, sim=False))
    assert [len(b) for b in lockstep_batches(snode, workers=1)] == [1, 1]
