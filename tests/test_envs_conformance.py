"""Conformance of every registered clfd-bench env: Gymnasium's checker, same-seed determinism,
pickling (mid-episode, the limit monitor's state included). One loop over the registry (an id
whose entry point is missing fails here)."""

from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import clfd_bench  # noqa: F401 - registers the ids
from clfd_bench.envs.registration import env_specs, registered_env_ids

ENV_IDS = registered_env_ids()


def test_registry_holds_every_clfd_id():
    assert set(env_specs()) <= set(ENV_IDS)
    assert len(ENV_IDS) == 9 + 7 + 1 + 26


def _make(env_id: str) -> gym.Env:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gym.make(env_id).unwrapped


def _rollout(env: gym.Env, seed: int, steps: int) -> list[dict]:
    env.action_space.seed(seed)
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        out.append({**obs, "reward": reward, "terminated": terminated, "truncated": truncated,
                    "tracking_error": np.array(info["tracking_error"]),
                    "failure_reason": np.array(str(info["failure_reason"]))})
    return out


def _assert_same(a: list[dict], b: list[dict]) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x.keys() == y.keys()
        for k in x:
            np.testing.assert_array_equal(x[k], y[k], err_msg=k)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_env_conformance(env_id):
    env = _make(env_id)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # checker hints (e.g. unbounded obs) are not errors
            check_env(env, skip_render_check=True)
        # Same seed, same rollout (random actions drawn from the seeded action space).
        first = _rollout(env, seed=3, steps=6)
        second = _rollout(env, seed=3, steps=6)
        _assert_same(first, second)
        # Pickling mid-episode: the copy continues exactly like the original.
        env.reset(seed=5)
        env.action_space.seed(5)
        for _ in range(3):
            env.step(env.action_space.sample())
        clone = pickle.loads(pickle.dumps(env))
        actions = [env.action_space.sample() for _ in range(3)]
        for a in actions:
            o1, r1, *_ = env.step(a)
            o2, r2, *_ = clone.step(a)
            _assert_same([o1], [o2])
            assert r1 == r2
        clone.close()
        # Pickling in an episode that runs within the limits (demo 0's first actions): the
        # monitor's state comes along, and a jump refused by the original is refused alike.
        actions = env.trajectory_to_actions(env.demo_trajectory(0))
        env.reset(seed=5, options={"demo": 0})
        for a in actions[:4]:
            _, _, terminated, _, info = env.step(a)
            assert not terminated, info["failure_reason"]
        clone = pickle.loads(pickle.dumps(env))
        state, cstate = env.motion_monitor.state(), clone.motion_monitor.state()
        assert state.keys() == cstate.keys()
        for k in state:
            np.testing.assert_array_equal(state[k], cstate[k], err_msg=k)
        for a in [actions[4], env.action_space.high]:
            o1, r1, t1, _, i1 = env.step(a)
            o2, r2, t2, _, i2 = clone.step(a)
            _assert_same([o1], [o2])
            assert (r1, t1, i1["failure"]) == (r2, t2, i2["failure"])
        assert t1 and i1["failure"]["step"] == 5
        clone.close()
    finally:
        env.close()
