"""Writing envs decide success by the ink: demos succeed, wrong trajectories fail (a subset of
`clfd-bench replay --env writing --perturb all`)."""

from __future__ import annotations

import argparse
import json

import gymnasium as gym
import pytest

import clfd_bench  # noqa: F401
from clfd_bench.cli import replay as replay_cli
from clfd_bench.execution.replay import PERTURBATIONS, replay

CASES = [("clfd/HelloWorld-e-v0", [0, 5]), ("clfd/HelloWorld-d-v0", [2, 7]),
         ("clfd/LASA-Sine-v0", [0]), ("clfd/LASA-GShape-v0", [3])]


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def case(request):
    env_id, demos = request.param
    env = gym.make(env_id)
    yield env_id, demos, env
    env.close()


def test_demos_succeed(case):
    env_id, demos, env = case
    for rec in replay(env_id, demos, None, env=env):
        assert rec.success, rec.info
        assert rec.info["ink_fraction"] > 0.99
        assert rec.max_tracking_error_m < 1e-3


@pytest.mark.parametrize("perturb", PERTURBATIONS)
def test_wrong_trajectories_fail(case, perturb):
    env_id, demos, env = case
    for rec in replay(env_id, demos, perturb, env=env):
        assert not rec.success, (perturb, rec.info)
        assert rec.info["dtw"] > rec.info["dtw_threshold"] or rec.info.get("goal_distance", 0) > 0


def test_text_env_writes_he_and_fails_reversed():
    env = gym.make("clfd/HelloWorld-v0", text="he")
    (ok,) = replay("clfd/HelloWorld-v0", [1], None, env=env)
    assert ok.success and ok.info["strokes"] == 2, ok.info
    assert max(ok.info["letter_dtw"]) < 1.0
    (bad,) = replay("clfd/HelloWorld-v0", [1], "reverse", env=env)
    assert not bad.success
    env.close()


def test_replay_cli_json(capsys):
    args = argparse.Namespace(env=["clfd/HelloWorld-l-v0"], demos="1", perturb="truncate",
                              settle=0.5, json=True)
    assert replay_cli._run(args) == 0
    out = json.loads(capsys.readouterr().out)
    (row,) = out["results"]
    assert row["demo"] == 1 and row["perturb"] == "truncate" and row["success"] is False
    assert out["summary"]["clfd/HelloWorld-l-v0 [truncate]"]["n"] == 1


def test_replay_rejects_bad_demo_index():
    with pytest.raises(ValueError, match="has demos 0..7"):
        replay("clfd/HelloWorld-h-v0", [8])


def test_unfinished_letter_fails_on_its_end_point():
    # 'l' cut at 50 %: its second half retraces the first, so the ink passes the paper's DTW
    # threshold; the letter is unfinished, which the end-point check catches.
    (rec,) = replay("clfd/HelloWorld-l-v0", [0], "truncate")
    assert rec.info["dtw"] <= rec.info["dtw_threshold"]
    assert rec.info["goal_distance"] > 0.01
    assert not rec.success
