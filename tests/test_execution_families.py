"""Every task's success criterion both ways: on every RoboTasks, HelloWorld and LASA env the
must-succeed families succeed and every must-fail family fails (one demo per family, the demo
rotating with the family so that the suite covers different demos; `clfd-bench replay --env
all --perturb all` runs every demo)."""

from __future__ import annotations

import gymnasium as gym
import pytest

import clfd_bench  # noqa: F401  (registers the envs)
from clfd_bench.envs.registration import env_specs
from clfd_bench.execution.perturb import FAMILIES
from clfd_bench.execution.replay import families_for, replay

SHAPE_ENVS = [i for i in env_specs() if not i.startswith("clfd/HelloWorld-v")]


@pytest.mark.parametrize("env_id", SHAPE_ENVS)
def test_families_on_every_env(env_id):
    env = gym.make(env_id, disable_env_checker=True)
    try:
        base = env.unwrapped
        wrong = []
        for k, family in enumerate(families_for(base)):
            demo = (k * 3 + len(env_id)) % base.num_demos
            (rec,) = replay(env_id, [demo], family, env=env)
            if rec.applicable and rec.success != (FAMILIES[family].expect == "succeed"):
                wrong.append((family, demo, rec.info.get("failure_reason"),
                              {k: v for k, v in rec.info.items() if k not in (
                                  "failure_reason", "failure", "objects")}))
        assert not wrong, wrong
    finally:
        env.close()


def test_a_shortcut_of_a_straight_line_is_no_wrong_trajectory():
    env = gym.make("clfd/LASA-Line-v3", disable_env_checker=True)
    try:
        (short,) = replay("clfd/LASA-Line-v3", [0], "shortcut", env=env)
        (rev,) = replay("clfd/LASA-Line-v3", [0], "reverse", env=env)
    finally:
        env.close()
    assert not short.applicable and rev.applicable and not rev.success


def test_families_on_the_text_env():
    env = gym.make("clfd/HelloWorld-v3", text="lo", disable_env_checker=True)
    try:
        for family in ("demo", "slower", "noise", "mirror", "rush-wait", "teleport"):
            (rec,) = replay("clfd/HelloWorld-v3", [2], family, env=env)
            assert rec.success == (FAMILIES[family].expect == "succeed"), (family, rec.info)
    finally:
        env.close()


def test_stop_early_of_a_demo_at_rest_by_half_time_is_no_wrong_trajectory():
    """MatFolding demo 0 has folded the mat by half time and rests (2.3 mm, 0.2 deg): its
    first half is the demo; of every other demo of every env, stopping at half time is wrong."""
    from clfd_bench.execution.perturb import perturb
    from clfd_bench.execution.replay import is_distinct

    at_rest = []
    for env_id in SHAPE_ENVS:
        env = gym.make(env_id, disable_env_checker=True)
        base = env.unwrapped
        for d in range(base.num_demos):
            half = perturb("stop-early", base.demo_trajectory(d))
            if not is_distinct(base, d, "stop-early", half):
                at_rest.append((env_id, d))
        env.close()
    assert at_rest == [("clfd/MatFolding-v3", 0)]


def test_valid_alternatives_of_outcome_judged_tasks_are_no_wrong_trajectories():
    """Team decisions (2026-12-05): a MatFolding shortcut that folds the mat is n/a (one whose
    edge slipped out still counts), every Scoop drift is n/a (nothing marks where a scoop
    ends); nothing else is."""
    from types import SimpleNamespace

    from clfd_bench.execution.replay import VALID_ALTERNATIVES, is_valid_alternative

    def info(**passed):
        return {"checks": [{"name": k, "passed": v} for k, v in passed.items()]}

    mat, scoop = SimpleNamespace(task_name="matfolding"), SimpleNamespace(task_name="scoop")
    folded = info(held_until_opened=True, far_half_height=True, turned_strips=True)
    slipped = info(held_until_opened=False, far_half_height=True, turned_strips=False)
    assert is_valid_alternative(mat, "shortcut", folded)
    assert not is_valid_alternative(mat, "shortcut", slipped)
    assert not is_valid_alternative(mat, "shortcut", {})  # no checks reported: counted
    assert not is_valid_alternative(mat, "drift", folded)
    assert is_valid_alternative(scoop, "drift", {})
    assert not is_valid_alternative(scoop, "shortcut", {})
    assert not is_valid_alternative(SimpleNamespace(task_name="pouring"), "drift", {})
    assert all(len(reason) > 80 for _, reason in VALID_ALTERNATIVES.values())  # written
