"""The stop rule on the training loss (``stop_window``): hand-computed decisions on loss
sequences, and a real run that it ends early and records, while the default leaves every
run at its full iterations."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from clfd_bench.harness.config import resolve_config
from clfd_bench.harness.loop import stop_rule
from clfd_bench.harness.protocol import run_training
from clfd_bench.learning.part_config import ConfigError, PartConfig
from clfd_bench.learning.stop_rule import StopRule

SHARED = Path(__file__).resolve().parents[2] / "shared" / "datasets"


def _feed(rule: StopRule, losses: list[float]) -> int | None:
    for it, loss in enumerate(losses):
        if rule.update(it, loss):
            return it + 1
    return None


def test_a_plateau_stops_and_an_improving_loss_does_not():
    # windows of 2: means 1.0, 0.5, 0.25, 0.125 (halving: progress every window)
    improving = [1.0, 1.0, 0.5, 0.5, 0.25, 0.25, 0.125, 0.125]
    rule = StopRule(window=2, rel=0.1)
    assert _feed(rule, improving) is None and rule.stopped_at is None
    assert rule.best == 0.125
    # means 1.0, then 0.95: not 10 % below 1.0 -> plateau -> stop after iteration 4
    plateau = [1.0, 1.0, 0.96, 0.94, 0.5, 0.5]
    rule = StopRule(window=2, rel=0.1)
    assert _feed(rule, plateau) == 4 and rule.stopped_at == 4
    # the same losses with rel 0.04: 0.95 < 0.96 is progress, 0.5 too
    assert _feed(StopRule(window=2, rel=0.04), plateau) is None


def test_plateaus_first_lower_the_lr_then_stop():
    rule = StopRule(window=1, rel=0.0, decays=2)
    # 1.0 best; 1.0 plateau -> lr / 10; 0.5 progress; 0.7 plateau -> lr / 100; 0.7 stop
    decisions = [rule.update(i, x) for i, x in enumerate([1.0, 1.0, 0.5, 0.7, 0.7])]
    assert decisions == [False, False, False, False, True]
    assert rule.lr_scale == pytest.approx(0.01) and rule.stopped_at == 5


def test_losses_before_start_are_ignored():
    rule = StopRule(window=2, rel=0.5, start=3)
    # iterations 0-2 ignored (even a huge loss); windows [3, 4] mean 2, [5, 6] mean 1.5:
    # not 50 % below 2 -> stop after iteration 6
    assert _feed(rule, [100.0, 1.0, 1.0, 2.0, 2.0, 1.5, 1.5, 0.1]) == 7


def test_the_rule_starts_after_warmup_and_horizon_growth():
    cfg = PartConfig(iterations=1000, lr=1e-3, node_hidden=(8,), lr_warmup=0.1,
                     batch="trajectories", horizon_start=0.1, horizon_ramp=0.3,
                     segments=True, solver="rk4", stop_window=50)
    assert stop_rule(cfg).start == 300
    assert stop_rule(PartConfig(iterations=1000, lr=1e-3, node_hidden=(8,))) is None
    for bad in ({"stop_rel": 1.0}, {"stop_window": -1}, {"stop_decays": -1}):
        with pytest.raises(ConfigError, match=next(iter(bad))):
            PartConfig(iterations=10, lr=1e-3, node_hidden=(8,), **bad)
    assert "stop_window" not in PartConfig(iterations=10, lr=1e-3, node_hidden=(8,)).to_dict()


def test_a_run_stops_early_and_records_it(tmp_path):
    if "CLFD_DATA_DIR" not in os.environ and SHARED.is_dir():
        os.environ["CLFD_DATA_DIR"] = str(SHARED)
    base = ["iterations=200", "horizon_ramp=0.25", "lr_warmup=0.0"]
    # a window must be 90 % below the best earlier one: the second window after the
    # horizon's growth (iterations 50-74, 75-99) is a plateau -> 100 iterations
    cfg = resolve_config("hn", "helloworld", "smoke", tasks=1, overrides=[
        *base, "stop_window=25", "stop_rel=0.9"])
    stopped = run_training(cfg, tmp_path / "stop", threads=1, log=None)
    assert stopped["iterations_by_part"] == {"position": [100]}
    plain = resolve_config("hn", "helloworld", "smoke", tasks=1, overrides=base)
    full = run_training(plain, tmp_path / "plain", threads=1, log=None)
    assert full["iterations_by_part"] == {"position": [200]}


def test_packnet_refuses_a_stop_rule_that_would_skip_its_retraining():
    from clfd_bench.harness.learner import Learner

    cfg = resolve_config("packnet", "helloworld", "smoke", overrides=["stop_window=10"])
    with pytest.raises(ConfigError, match="packnet_retrain"):
        Learner.from_config(cfg, 2)
    ok = resolve_config("packnet", "helloworld", "smoke",
                        overrides=["stop_window=10", "packnet_retrain=0"])
    Learner.from_config(ok, 2)  # pruning after the last iteration: nothing to cut off
