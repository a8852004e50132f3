"""``refine_gap``: a task whose stop rule ends it with a solver gap above the bound trains on
with twice the solver steps per interval, until the gap is within it (or the steps or the
iterations run out). Where the gap is within the bound from the start the run is bit for bit
the run without the option, so turning it on changes only the tasks it refines."""

from __future__ import annotations

import numpy as np
import pytest

import clfd_bench.harness.loop as loop
from clfd_bench.harness.config import ConfigError, resolve_config
from clfd_bench.harness.learner import PartLearner
from clfd_bench.harness.protocol import run_training
from clfd_bench.harness.run import TrainSpec
from clfd_bench.learning.part_config import REFINE_MAX_SUBSTEPS
from clfd_bench.runs import RunDir

STOP_EARLY = ("stop_window=3", "stop_rel=0.3", "stop_decays=1", "horizon_ramp=0",
              "horizon_start=1", "iterations=300")
"""A stop rule that ends smoke tasks after a few windows, well before the cap."""


def _config(*overrides: str, method: str = "sg", dataset: str = "helloworld", tasks: int = 2):
    return TrainSpec(method, dataset, "smoke", seed=0, tasks=tasks,
                     overrides=STOP_EARLY + overrides).config()


def _train(tmp_path, name: str, *overrides: str, **kw) -> tuple[dict, dict]:
    out = tmp_path / name
    config = _config(*overrides, **kw)
    run_training(config, out, log=None)
    run = RunDir(out)
    return run.load_results(), run.load_predictions(config.tasks - 1)


@pytest.fixture
def halving_gap(monkeypatch):
    """A solver gap of 1 cm at one step per interval that halves with each doubling of the
    steps (what RK4 steps on a field they under-resolve do, roughly), whatever the weights."""
    def gap(self, index, task, goals=None, fine=None, substeps=None):
        return 0.01 / (substeps or self.cfg.substeps)
    monkeypatch.setattr(PartLearner, "solver_gap", gap)


def test_a_gap_above_the_bound_is_refined_until_within_it(tmp_path, halving_gap):
    off, _ = _train(tmp_path, "off")
    on, _ = _train(tmp_path, "on", "refine_gap=0.003")
    for i in range(2):
        # 1 cm, 0.5 cm, 0.25 cm: within 0.3 cm after two doublings
        assert on["refine_gaps_by_part"]["position"][i] == [0.01, 0.005, 0.0025]
        assert on["substeps_by_part"]["position"][i] == 4
        # the recorded solver gap is the one of the steps the task ended with
        assert on["solver_gap_by_part"]["position"][i] == 0.0025
        # each refinement trained on under a fresh stop rule: more iterations than without
        assert on["iterations_by_part"]["position"][i] > off["iterations_by_part"]["position"][i]
    assert off["substeps_by_part"]["position"] == [1, 1]
    assert off["refine_gaps_by_part"]["position"] == [[], []]


def test_a_refined_phase_goes_on_at_the_lr_its_task_ended_with(tmp_path, halving_gap,
                                                                monkeypatch):
    """Refining fine-tunes a learned task: at a constant lr the rate never rises again, and
    each phase's own stop rule lowers it once more (one decay per phase: base, base/10 in the
    first phase, /100 and /1000 in the two refined ones)."""
    lrs: list[float] = []
    original = loop._adam

    def recording_adam(params, lr):
        optimizer = original(params, lr)
        optimizer.register_step_pre_hook(
            lambda opt, args, kwargs: lrs.append(opt.param_groups[0]["lr"]))
        return optimizer

    monkeypatch.setattr(loop, "_adam", recording_adam)
    on, _ = _train(tmp_path, "on", "refine_gap=0.003", "lr_schedule=constant", "lr_warmup=0",
                   tasks=1)
    assert on["substeps_by_part"]["position"] == [4]
    assert all(b <= a for a, b in zip(lrs[:-1], lrs[1:], strict=True)), "the lr rose again"
    levels = sorted({round(lrs[0] / lr) for lr in lrs})
    assert levels == [1, 10, 100, 1000]


def test_refining_stops_at_the_most_steps(tmp_path, halving_gap):
    on, _ = _train(tmp_path, "on", "refine_gap=0.0001")  # never reached by 1 cm / 8
    gaps = on["refine_gaps_by_part"]["position"][0]
    assert on["substeps_by_part"]["position"][0] == REFINE_MAX_SUBSTEPS
    assert gaps == [0.01 / s for s in (1, 2, 4, 8)]


def test_a_gap_within_the_bound_leaves_the_run_bit_for_bit(tmp_path):
    """The real gap of a smoke run is far below 1 m: the option measures it once per task and
    changes nothing else (predictions and iterations identical to the option off)."""
    off, pred_off = _train(tmp_path, "off")
    on, pred_on = _train(tmp_path, "on", "refine_gap=1")
    assert all(np.array_equal(pred_off[j], pred_on[j]) for j in pred_off)
    assert on["iterations_by_part"] == off["iterations_by_part"]
    assert [len(g) for g in on["refine_gaps_by_part"]["position"]] == [1, 1]
    assert on["substeps_by_part"]["position"] == [1, 1]


def test_real_refinement_trains_with_the_finer_steps(tmp_path):
    """A bound no gap meets refines every task to the most steps, and the run's recorded gap
    is measured with them (so at most the last gap the refinement saw)."""
    on, _ = _train(tmp_path, "on", "refine_gap=1e-12", method="hn")
    for i in range(2):
        gaps = on["refine_gaps_by_part"]["position"][i]
        steps = on["substeps_by_part"]["position"][i]
        assert steps == 2 ** (len(gaps) - 1) and steps > 1
        assert on["solver_gap_by_part"]["position"][i] == pytest.approx(gaps[-1], rel=1e-6)


@pytest.mark.parametrize("bad", [("stop_window=0",), ("batch=windows",),
                                 ("solver=dopri5", "segments=false")])
def test_refine_gap_needs_a_stop_rule_and_fixed_steps_on_trajectories(bad):
    with pytest.raises(ConfigError, match="refine_gap"):
        resolve_config("sg", "helloworld", "smoke", overrides=[*STOP_EARLY, "refine_gap=0.01",
                                                                *bad])
