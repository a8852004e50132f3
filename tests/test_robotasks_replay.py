"""Replays through the RoboTasks envs: demonstrations succeed, wrong trajectories fail.

A subset of `clfd-bench replay --env robotasks --perturb all` (which runs all 9 demos of every
task with every perturbation): two demos per task, and for each task the perturbation whose
outcome is closest to its threshold (openbox demo 4 at half time is 2.8 deg short of the
lid's balance angle; pouring demo 1 has tipped the cup furthest at half time).
"""

from __future__ import annotations

import gymnasium as gym
import pytest

import clfd_bench  # noqa: F401 - registers the ids
from clfd_bench.execution.replay import replay

CASES = {
    "clfd/BoxOpening-v0": ((0, 4), "truncate", 4),
    "clfd/BottleShelving-v0": ((0, 4), "other-task", 4),
    "clfd/PlateStacking-v0": ((3, 7), "reverse", 3),
    "clfd/Pouring-v0": ((1, 5), "truncate", 1),
}


@pytest.mark.parametrize("env_id", sorted(CASES))
def test_demos_succeed_and_a_perturbed_demo_fails(env_id):
    demos, perturb, perturbed_demo = CASES[env_id]
    env = gym.make(env_id)
    try:
        for rec in replay(env_id, demos=demos, env=env):
            assert rec.success, (env_id, rec.demo, rec.info)
            assert rec.max_tracking_error_m < 0.02, (env_id, rec.demo)
            assert rec.info["release_reason"] != "slipped"
        (rec,) = replay(env_id, demos=[perturbed_demo], perturb=perturb, env=env)
        assert not rec.success, (env_id, perturb, rec.info)
    finally:
        env.close()
