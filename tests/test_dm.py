"""`clfd_bench.dm`: every task as a `dm_env.Environment`.

dm_env's own conformance tests (`dm_env.test_utils.EnvironmentTestMixin`) run on
`clfd_bench.dm.load(id)` for every registered id, with an action sequence that ends episodes
both ways (a time limit and a refused command) so the mixin checks the end-of-episode contract.
Then what the adapter must keep: the Gymnasium env's observations and rewards step for step,
demo replays that succeed and a wrong trajectory that fails, a Physics that is the env's state,
pickling, the error for an unknown name and for a missing extra.
"""

from __future__ import annotations

import importlib
import pickle
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("dm_control", reason="the optional extra: pip install 'clfd-bench[dm]'")

import dm_env  # noqa: E402
from absl.testing import absltest  # noqa: E402
from dm_env import test_utils  # noqa: E402

from clfd_bench import dm  # noqa: E402
from clfd_bench.envs.registration import registered_env_ids  # noqa: E402
from clfd_bench.execution.perturb import perturb  # noqa: E402
from clfd_bench.execution.rollout import rollout  # noqa: E402

ENV_IDS = registered_env_ids()
#: Episode length in the conformance tests: short, so the action sequence reaches a time limit.
HORIZON = 5


def _demo_actions(env: dm.DmEnv, demo: int = 0) -> np.ndarray:
    gym_env = env.gym_env
    return gym_env.trajectory_to_actions(gym_env.demo_trajectory(demo))


def _conformance_actions(env: dm.DmEnv) -> list[np.ndarray]:
    """Actions that run: HORIZON steps of demo 0 (LAST by the time limit), one ignored action
    (FIRST), two demo steps (MID), the action space's upper corner (refused by the Panda's
    limits: LAST by termination), one ignored action (FIRST) and the spec's test value."""
    a = _demo_actions(env)
    high = env.action_spec().maximum
    return [*a[:HORIZON], a[0], a[0], a[1], high, a[0], env.action_spec().generate_value()]


class _Conformance(test_utils.EnvironmentTestMixin):
    env_id: str

    def make_object_under_test(self):
        return dm.load(self.env_id, seed=0, options={"demo": 0, "horizon": HORIZON})

    def make_action_sequence(self):
        yield from _conformance_actions(self.environment)


# One absltest class per registered id (pytest cannot parametrize a unittest.TestCase).
for _env_id in ENV_IDS:
    _name = "TestDmConformance_" + _env_id.split("/", 1)[1].replace("-", "_")
    globals()[_name] = type(_name, (_Conformance, absltest.TestCase), {"env_id": _env_id})
del _env_id, _name


def test_every_id_has_a_conformance_class():
    classes = [v for k, v in globals().items() if k.startswith("TestDmConformance_")]
    assert sorted(c.env_id for c in classes) == ENV_IDS
    assert len(ENV_IDS) == 43
    assert dm.names() == [i.split("/", 1)[1] for i in ENV_IDS]


@pytest.mark.parametrize("env_id", ["clfd/PlateStacking-v3", "clfd/LASA-Angle-v3"])
def test_step_types_and_discounts(env_id):
    """Time limit: LAST with discount 1.0; a refused command: LAST with discount 0.0; the
    step after LAST starts an episode."""
    env = dm.load(env_id, seed=0, options={"demo": 0, "horizon": HORIZON})
    assert env.reset().step_type is dm_env.StepType.FIRST
    got, infos = [], []
    for a in _conformance_actions(env):
        ts = env.step(a)
        got.append((ts.step_type, ts.discount))
        infos.append(env.last_info)
    first, mid, last = dm_env.StepType.FIRST, dm_env.StepType.MID, dm_env.StepType.LAST
    assert got[:10] == [*[(mid, 1.0)] * (HORIZON - 1), (last, 1.0),  # the time limit
                        (first, None), (mid, 1.0), (mid, 1.0),
                        (last, 0.0),  # the upper corner: refused, the episode fails
                        (first, None)]
    failure = infos[8]["failure"]
    assert failure["step"] == 2 and failure["kind"] in ("reflex", "unreachable")
    assert infos[9]["failure"] is None and infos[9]["step"] == 0  # the new episode's reset
    env.close()


def _gym(env_id: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gym.make(env_id).unwrapped


@pytest.mark.parametrize("env_id", ["clfd/BottleShelving-v3", "clfd/HelloWorld-e-v3"])
def test_same_observations_and_rewards_as_gymnasium(env_id):
    """Same seed (the demo is drawn with it), same actions: the same observations, rewards and
    ends as the Gymnasium env, bit for bit (one implementation)."""
    gym_env = _gym(env_id)
    env = dm.load(env_id, seed=11)
    obs, _ = gym_env.reset(seed=11)
    ts = env.reset()
    assert env.gym_env.demo == gym_env.demo
    actions = _demo_actions(env, gym_env.demo)[:40]
    rng = np.random.default_rng(0)
    actions = [*(a + rng.normal(0, 1e-4, a.shape) for a in actions), gym_env.action_space.high]
    assert env.observation_spec().keys() == obs.keys()
    for k in obs:
        np.testing.assert_array_equal(ts.observation[k], obs[k], err_msg=k)
    for a in actions:
        obs, reward, terminated, truncated, info = gym_env.step(a)
        ts = env.step(a)
        for k in obs:
            np.testing.assert_array_equal(ts.observation[k], obs[k], err_msg=k)
        assert ts.reward == reward
        assert ts.last() == (terminated or truncated)
        assert env.last_info["failure_reason"] == info["failure_reason"]
    assert terminated and ts.discount == 0.0
    gym_env.close()
    env.close()


def _replay(env_id: str, trajectory: np.ndarray, demo: int
            ) -> tuple[dm_env.TimeStep, int, dict]:
    """Runs a trajectory and its settle actions through the dm env as `rollout` does."""
    env = dm.load(env_id)
    gym_env = env.gym_env
    actions = gym_env.trajectory_to_actions(trajectory)
    actions = np.concatenate([actions, gym_env.settle_actions(actions[-1], 60)])
    env.reset_options = {"demo": demo, "horizon": len(actions)}
    ts = env.reset()
    steps = 0
    for a in actions:
        ts = env.step(a)
        steps += 1
        if ts.last():
            break
    info = env.last_info
    env.close()
    return ts, steps, info


@pytest.mark.parametrize(("env_id", "demo"), [("clfd/PlateStacking-v3", 2),
                                              ("clfd/HelloWorld-h-v3", 1)])
def test_demo_replay_succeeds_and_a_shortcut_fails(env_id, demo):
    gym_env = _gym(env_id)
    trajectory = gym_env.demo_trajectory(demo)
    ts, steps, info = _replay(env_id, trajectory, demo)
    assert steps == len(trajectory) + 60  # ran to the time limit
    assert (ts.step_type, ts.discount, ts.reward) == (dm_env.StepType.LAST, 1.0, 1.0)
    assert info["is_success"] and info["failure_reason"] is None
    # The straight min-jerk move from the demo's start to its end (a must-fail family).
    shortcut = perturb("shortcut", trajectory)
    ts, _, info = _replay(env_id, shortcut, demo)
    assert ts.last() and ts.reward == 0.0 and not info["is_success"]
    # The Gymnasium rollout of the same trajectory decides alike.
    assert not rollout(gym_env, shortcut, demo=demo).success
    gym_env.close()


def test_physics_is_the_env_state():
    env = dm.load("PlateStacking-v3", options={"demo": 0})
    gym_env, physics = env.gym_env, env.physics
    assert physics.model.ptr is gym_env.model and physics.data.ptr is gym_env.data
    env.reset()
    for a in _demo_actions(env)[:10]:
        env.step(a)
    np.testing.assert_array_equal(physics.data.qpos, gym_env.data.qpos)
    assert physics.data.time == pytest.approx(10 * gym_env.control_dt)
    hand = gym_env.robot.hand_body
    np.testing.assert_array_equal(physics.data.xpos[hand], env.step(_demo_actions(env)[10])
                                  .observation["ee_pos"])
    # Named access (dm-control's indexers) reads the same arrays.
    np.testing.assert_array_equal(physics.named.data.qpos[physics.model.id2name(0, "joint")],
                                  gym_env.data.qpos[physics.model.jnt_qposadr[0]])
    env.close()


def test_pickles_mid_episode():
    env = dm.load("PlateStacking-v3", seed=3, options={"demo": 1})
    actions = _demo_actions(env, 1)
    env.reset()
    for a in actions[:5]:
        env.step(a)
    clone = pickle.loads(pickle.dumps(env))
    assert clone.physics.data.ptr is clone.gym_env.data
    assert clone.physics.data.ptr is not env.physics.data.ptr
    for a in actions[5:10]:
        t1, t2 = env.step(a), clone.step(a)
        assert (t1.step_type, t1.reward, t1.discount) == (t2.step_type, t2.reward, t2.discount)
        for k in t1.observation:
            np.testing.assert_array_equal(t1.observation[k], t2.observation[k], err_msg=k)
    np.testing.assert_array_equal(clone.physics.data.qpos, env.physics.data.qpos)
    env.close()
    clone.close()


def test_unknown_name_lists_the_valid_names():
    with pytest.raises(dm.UnknownEnvError) as err:
        dm.load("PlateStackin-v2")
    msg = str(err.value)
    assert msg.startswith("no clfd-bench env 'PlateStackin-v2' (Environment `PlateStackin` "
                          "doesn't exist in namespace clfd. Did you mean: `PlateStacking`?); "
                          "valid names (with or without 'clfd/'): BottleShelving-v3, ")
    assert all(n in msg for n in dm.names())
    # An old version: the registry's message names the current one.
    with pytest.raises(dm.UnknownEnvError, match=r"Please use `clfd/PlateStacking-v3`"):
        dm.load("PlateStacking-v0")
    # Not an id at all, or another namespace: the same error.
    with pytest.raises(dm.UnknownEnvError, match=r"Malformed environment ID"):
        dm.load("plate stacking")
    with pytest.raises(dm.UnknownEnvError, match=r"in the namespace 'clfd', not 'gym'"):
        dm.load("gym/PlateStacking-v3")
    # With or without the namespace, without a version: the current version.
    assert type(dm.load("clfd/PlateStacking-v3").gym_env).__name__ == "RoboTaskEnv"
    assert dm.load("LASA-Angle").gym_env.task_name == "Angle"


def test_missing_extra_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "dm_control", None)  # as if not installed
    monkeypatch.delitem(sys.modules, "clfd_bench.dm")
    with pytest.raises(ImportError, match=r"pip install 'clfd-bench\[dm\]'"):
        importlib.import_module("clfd_bench.dm")
