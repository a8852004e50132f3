"""A rollout may stop once the writing criterion has decided a failure, and that must never
change a success decision: the early answer equals the full rollout's on every replay and
perturbation family, a decided failure is never followed by a success, and the must-fail shape
families are decided long before the horizon (so the stop saves time for real)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import clfd_bench  # noqa: F401
from clfd_bench.envs.writing import DECIDE_BATCH
from clfd_bench.execution.env_pool import get_env
from clfd_bench.execution.execute import execute
from clfd_bench.execution.replay import families_for, replay_trajectory
from clfd_bench.execution.rollout import rollout

ENVS = ("clfd/LASA-Angle-v3", "clfd/HelloWorld-h-v3")
#: Families whose ink leaves the tolerance tube: they must be decided before the horizon.
LEAVE_TUBE = ("shortcut", "rush-wait", "mirror", "drift")


@pytest.mark.parametrize("env_id", ENVS)
def test_early_and_full_rollouts_agree_on_every_family(env_id):
    env = get_env(env_id)
    base = env.unwrapped
    decided_early = {}
    for family in families_for(base):
        traj = replay_trajectory(base, 0, family)
        full = rollout(env, traj, demo=0)
        sticky = base.decided_failure()  # stays set to the end of the episode
        if sticky is not None:
            assert not full.success, (family, sticky)
            if full.info["failure_reason"] is None:  # judged at the end, not stopped by a limit
                assert sticky["check"] in full.info["failed"], (family, full.info["failed"])
                assert full.info["decided_failure"] == sticky
        early = rollout(env, traj, demo=0, stop_when_decided=True)
        assert early.success == full.success, family
        assert early.steps <= full.steps
        assert (early.stopped_early is None) == (sticky is None), family
        if early.stopped_early is not None:
            assert early.stopped_early == sticky  # the same decision, at the same step
            # noticed within one batch of inked steps, long before the horizon
            assert sticky["step"] < early.steps <= sticky["step"] + DECIDE_BATCH
            assert early.steps < full.steps
            assert early.info["stopped_early"]["stopped_at"] == early.steps
            horizon = len(base.trajectory_to_actions(traj)) + 60
            assert early.info["stopped_early"]["horizon"] == horizon
            decided_early[family] = early.steps / full.steps
        else:
            assert early.steps == full.steps
            assert early.info["is_success"] == full.info["is_success"]
    assert set(LEAVE_TUBE) <= set(decided_early), decided_early
    # rush-wait and mirror leave the tube within the first fifth of the episode
    assert decided_early["rush-wait"] < 0.2 and decided_early["mirror"] < 0.2, decided_early


def test_a_detour_is_decided_where_it_leaves_the_tube():
    env = get_env("clfd/HelloWorld-e-v3")
    base = env.unwrapped
    demo = base.demo_trajectory(2).copy()
    bound = base.tolerances.hausdorff
    # From step 400 on, the pen is pushed 3 tolerances sideways (a min-jerk ramp over 60 steps)
    ramp = np.clip((np.arange(len(demo)) - 400) / 60.0, 0.0, 1.0)[:, None]
    bad = demo + 3.0 * bound * ramp * np.array([0.0, 1.0])
    res = execute(env, bad, 2)
    assert not res.success and res.failure_kind == "task"
    assert res.failure_reason.startswith(f"task failed, decided after {res.steps} of 1060")
    step = res.info["stopped_early"]["step"]
    assert 400 < step < 460, step  # leaves the tube during the ramp ...
    assert step < res.steps <= step + DECIDE_BATCH  # ... and is noticed within a batch
    assert res.info["stopped_early"]["value"] > bound
    full = execute(env, bad, 2, stop_when_decided=False)
    assert not full.success and full.steps == 1060 and "hausdorff" in full.info["failed"]
    good = execute(env, demo, 2)
    assert good.success and good.steps == 1060 and "stopped_early" not in good.info


def test_pen_off_the_board_is_decided_once_the_ink_fraction_cannot_recover(monkeypatch):
    env = get_env("clfd/LASA-Angle-v3")
    base = env.unwrapped
    monkeypatch.setattr(base, "_inking", lambda: False)  # the pen never touches the board
    traj = base.demo_trajectory(1)
    res = rollout(env, traj, demo=1, stop_when_decided=True)
    horizon = len(traj) + 60
    # (horizon - off) / horizon < 0.9 first holds at off = floor(0.1 * horizon) + 1
    off = int(np.floor(0.1 * horizon)) + 1
    assert res.stopped_early["check"] == "ink_fraction"
    assert res.steps == off and res.stopped_early["step"] == off - 1
    assert not res.success
    full = rollout(env, traj, demo=1)
    assert not full.success and "ink_fraction" in full.info["failed"]


def test_recording_tracing_and_the_decision_state_keep_the_whole_episode():
    env = get_env("clfd/LASA-Angle-v3")
    base = env.unwrapped
    traj = replay_trajectory(base, 0, "rush-wait")
    traced = execute(env, traj, 0, trace=True)  # a trace shows the whole rollout
    assert traced.steps == 1060 and not traced.success
    # the decision survives pickling mid-episode
    env.reset(options={"demo": 0, "horizon": 1060})
    for action in base.trajectory_to_actions(traj)[:60]:
        env.step(action)
    decided = base.decided_failure()
    assert decided is not None and decided["check"] == "hausdorff"
    clone = pickle.loads(pickle.dumps(base))
    assert clone.decided_failure() == decided
    env.reset(options={"demo": 0})
    assert base.decided_failure() is None
