"""`clfd-bench evaluate` on a tiny saved run (trained here with the smoke profile): success
arrays of the right shapes, the trajectory metrics untouched, the cache reused, the CLI."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from clfd_bench.execution.evaluate import evaluate_run
from clfd_bench.runs import RunDir
from clfd_bench.viz.rerun_log import rrd_entity_paths

SIM_KEYS = ("success", "sim_accuracy", "sim_cl_metrics", "sim")


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """SG on HelloWorld's first two letters, smoke profile (the library function behind
    `clfd-bench train --method sg --dataset helloworld --profile smoke --tasks 2`)."""
    from clfd_bench.harness.config import resolve_config
    from clfd_bench.harness.protocol import run_training

    out = tmp_path_factory.mktemp("run") / "sg_smoke"
    config = resolve_config("sg", "helloworld", "smoke", seed=0, tasks=2)
    run_training(config, out, threads=1, log=None)
    return out


def _read(run_dir):
    with open(run_dir / "results.json", encoding="utf-8") as fh:
        return json.load(fh)


def test_evaluate_run_writes_success_and_keeps_everything_else(tiny_run, tmp_path):
    before = _read(tiny_run)
    rrd = tmp_path / "eval.rrd"
    from clfd_bench.viz.rerun_log import RolloutLogger

    with RolloutLogger(rrd, recording_name="test") as logger:
        fields = evaluate_run(tiny_run, observer=logger)
    after = _read(tiny_run)

    # Everything training wrote is unchanged; only the execution keys were added.
    assert {k: v for k, v in after.items() if k not in SIM_KEYS} == before
    m, n = 2, 8  # tasks learned, demos per HelloWorld letter
    success = after["success"]
    assert len(success) == m and all(len(row) == m for row in success)
    assert success[0][1] is None
    for i in range(m):
        for j in range(i + 1):
            assert len(success[i][j]) == n
            assert all(isinstance(s, bool) for s in success[i][j])
            assert after["sim_accuracy"][i][j] == pytest.approx(np.mean(success[i][j]))
    assert after["sim_accuracy"][0][1] is None
    assert set(after["sim_cl_metrics"]) == {"ACC", "REM", "BWT"}
    sim = after["sim"]
    assert sim["env_ids"] == {"h": "clfd/HelloWorld-h-v3", "e": "clfd/HelloWorld-e-v3"}
    assert sim["mujoco"] and sim["mink"] and sim["fingerprint"]
    assert sim["rollouts"] == 3 * n
    # SG keeps task 0's model: its prediction after task 1 is the same, executed once.
    assert sim["rollouts_executed"] == 2 * n and sim["rollouts_cached"] == n
    assert success[1][0] == success[0][0]
    assert fields["success"] == success
    # Every failed execution has a kind, every success none; the counts tally them.
    kinds = sim["failure_kind"]
    tally = {}
    for i in range(m):
        for j in range(i + 1):
            for ok, kind, reason in zip(success[i][j], kinds[i][j], sim["failure_reason"][i][j],
                                        strict=True):
                assert (kind is None) == ok and (reason is None) == ok
                if kind:
                    tally[kind] = tally.get(kind, 0) + 1
    assert {k: n for k, n in sim["failure_counts"].items() if n} == tally
    assert list(sim["failure_counts"])[:4] == ["reflex", "tracking", "unreachable", "collision"]

    counts = rrd_entity_paths(rrd)
    assert "/after_task_1/e/demo_7/tool" in counts
    assert "/after_task_1/h/demo_0/prediction" in counts


def test_evaluate_again_uses_the_cache_and_resumes(tiny_run):
    first = _read(tiny_run)
    again = evaluate_run(tiny_run)
    assert again["sim"]["rollouts_executed"] == 0
    assert again["success"] == first["success"]

    # An interrupted evaluation: drop one cached rollout; only that one runs again.
    cache_path = RunDir(tiny_run).cache_path
    cache = json.loads(cache_path.read_text())
    cache["entries"].pop(next(iter(cache["entries"])))
    cache_path.write_text(json.dumps(cache))
    resumed = evaluate_run(tiny_run)
    assert resumed["sim"]["rollouts_executed"] == 1
    assert resumed["success"] == first["success"]


def test_evaluate_cli(tiny_run, capsys):
    from clfd_bench.cli import evaluate

    parser = argparse.ArgumentParser()
    evaluate.register(parser.add_subparsers())
    args = parser.parse_args(["evaluate", str(tiny_run)])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "execution success R[i][j]" in out and "ACC" in out
    assert "execution failures: " in out

    args = parser.parse_args(["evaluate", str(tiny_run / "missing")])
    assert args.func(args) == 2
    assert "results.json not found" in capsys.readouterr().err
