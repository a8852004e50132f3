"""The shared PandaEnv loop: bad actions, physics blow-ups, tracking through physics, rendering,
rollout."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import clfd_bench  # noqa: F401
from clfd_bench.execution.rollout import rollout
from clfd_bench.sim.robot import robot_model


@pytest.fixture(scope="module")
def pose_env(pose_env_cls):
    env = pose_env_cls()
    yield env
    env.close()


def test_nan_action_raises_naming_entries(pose_env):
    pose_env.reset(seed=0)
    action = np.array([0.4, 0.0, 0.4, np.nan, 0.0, 1.0, np.inf, 1.0])
    with pytest.raises(ValueError, match=r"non-finite entries at indices \[3, 6\]"):
        pose_env.step(action)
    with pytest.raises(ValueError, match=r"action must have shape \(8,\)"):
        pose_env.step(np.zeros(3))


def test_writing_env_nan_action_raises():
    env = gym.make("clfd/HelloWorld-l-v3").unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"indices \[1\]"):
        env.step(np.array([0.4, np.nan]))
    env.close()


def test_demo_is_tracked_through_physics(pose_env):
    demo = pose_env.demo_trajectory(0)
    result = rollout(pose_env, demo, demo=0, settle_s=0.2)
    assert result.info["failure_reason"] is None and result.info["failure"] is None
    assert np.nanmax(result.tracking_error_pos) < 2e-3  # servo + IK, whole demo
    assert np.nanmean(result.tracking_error_pos) < 3e-4
    np.testing.assert_allclose(result.ee_path[-1], demo[-1, :3], atol=1e-3)


def test_unreachable_action_fails_as_unreachable(pose_env):
    pose_env.reset(seed=0, options={"demo": 0})
    obs, reward, terminated, truncated, info = pose_env.step(
        np.array([0.95, 0.0, 1.2, 1.0, 0.0, 0.0, 0.0, 1.0]))
    assert terminated and not truncated and reward == 0.0
    assert info["failure"]["kind"] == "unreachable" and info["failure"]["step"] == 0
    assert info["failure_reason"] == ("unreachable: target 1.286 m from the shoulder > 0.855 m "
                                      "at step 0")
    assert np.all(np.isfinite(obs["qpos"]))


def test_unreachable_action_without_limits_reports_error_without_crash(pose_env_cls):
    env = pose_env_cls(limits=None)
    env.reset(seed=0, options={"demo": 0})
    for _ in range(30):
        obs, _, terminated, _, info = env.step(
            np.array([0.95, 0.0, 1.2, 1.0, 0.0, 0.0, 0.0, 1.0]))
    assert not terminated and info["failure_reason"] is None and info["failure"] is None
    assert info["tracking_error"][0] > 0.2
    assert np.all(np.isfinite(obs["qpos"]))
    env.close()


def test_physics_blowup_ends_episode_as_failure(pose_env, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo logs its warning to MUJOCO_LOG.TXT in the cwd
    pose_env.reset(seed=0, options={"demo": 0})
    pose_env.data.qvel[:7] = 1e12  # an exploding state
    _, reward, terminated, truncated, info = pose_env.step(pose_env.trajectory_to_actions(
        pose_env.demo_trajectory(0)[:1])[0])
    assert terminated and not truncated and reward == 0.0
    assert not info["is_success"]
    assert "physics blow-up at step 0" in info["failure_reason"]
    assert info["failure"]["kind"] == "blowup" and info["failure"]["step"] == 0


def test_reset_options_are_validated(pose_env):
    with pytest.raises(ValueError, match=r"demo must be in \[0, 1\)"):
        pose_env.reset(options={"demo": 3})
    with pytest.raises(ValueError, match="unknown reset options"):
        pose_env.reset(options={"demos": 0})


def test_render_rgb_array():
    env = gym.make("clfd/HelloWorld-o-v3", render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.std() > 5  # not a blank image
    env.close()


def test_env_ik_posture_gain(pose_env):
    from clfd_bench.envs.base import IK_POSTURE_GAIN
    from clfd_bench.sim.ik import PoseTracker

    assert pose_env.tracker.posture_task.gain == IK_POSTURE_GAIN == 0.1
    with pytest.raises(ValueError, match=r"posture_gain must be in \(0, 1\], got 0"):
        PoseTracker(robot_model(), posture_gain=0.0)
