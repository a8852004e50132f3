"""Writing env geometry: pen down at the demo's start, ink only on the board, LASA placement,
text layout, env ids."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import clfd_bench  # noqa: F401
from clfd_bench.data import load_dataset
from clfd_bench.envs.registration import env_id_for, lasa_env_name
from clfd_bench.envs.writing import load_writing_spec


def test_reset_puts_the_pen_down_at_the_demo_start():
    env = gym.make("clfd/HelloWorld-w-v0").unwrapped
    obs, info = env.reset(seed=0, options={"demo": 4})
    assert info["demo"] == 4
    np.testing.assert_allclose(obs["pen_tip"][:2], env.demos[4, 0], atol=1e-3)
    spec = load_writing_spec()
    assert abs(obs["pen_tip"][2] - spec.surface_height) < 5e-4  # the spring takes the press
    obs, *_ = env.step(env.demos[4, 0])
    assert obs["pen_down"][0] == 1.0
    env.close()


def test_actions_are_clipped_to_the_board():
    env = gym.make("clfd/LASA-Line-v0").unwrapped
    env.reset(seed=0, options={"demo": 0})
    for _ in range(90):
        obs, *_ = env.step(np.array([5.0, 0.0]))  # far beyond the board edge x = 0.75
    np.testing.assert_allclose(obs["pen_tip"][:2], [0.75, 0.0], atol=3e-3)
    for _ in range(30):
        obs, *_ = env.step(np.array([0.7, 0.0]))
    assert obs["pen_down"][0] == 1.0
    env.close()


def test_lifted_pen_leaves_no_ink():
    env = gym.make("clfd/HelloWorld-v0", text="l").unwrapped
    env.reset(seed=0, options={"demo": 0})
    start = env.letter_to_surface(0, env.demo_letters(0)[0][0])
    for _ in range(30):
        obs, *_ = env.step(np.append(start, 1.0))
    assert obs["pen_down"][0] == 0.0 and obs["pen_tip"][2] > 0.12
    assert env.ink_trace().shape[0] < 10  # only while lifting off
    env.close()


def test_lasa_goal_is_centred_placement():
    env = gym.make("clfd/LASA-Angle-v0").unwrapped
    demos = env.demos
    xy = env.to_surface(demos)
    centre = (xy.min(axis=(0, 1)) + xy.max(axis=(0, 1))) / 2
    np.testing.assert_allclose(centre, load_writing_spec().lasa_center, atol=1e-9)
    np.testing.assert_allclose(env.to_data(env.to_surface(demos[0])), demos[0], atol=1e-9)
    assert env.sim_scale == load_dataset("lasa").tasks[0].sim_scale
    env.close()


def test_text_layout_places_letters_along_a_line():
    env = gym.make("clfd/HelloWorld-v0").unwrapped
    assert env.letters == list("helloworld")
    actions = env.trajectory_to_actions(env.demo_letters(0))
    assert actions.shape == (env._trajectory_steps(0), 3)
    lifted = actions[:, 2] > 0.05
    assert lifted.sum() == 9 * (2 * 12 + 24) - 9  # 9 transitions (last lowering step is down)
    with pytest.raises(ValueError, match="has 10 letters"):
        env.trajectory_to_actions(env.demo_letters(0)[:3])
    env.close()


def test_every_dataset_task_has_an_env_id():
    for name in ("helloworld", "lasa"):
        for task in load_dataset(name).task_names:
            assert env_id_for(name, task) in gym.registry
    for task in load_dataset("robotasks").task_names:
        assert env_id_for("robotasks", task) in gym.registry
    with pytest.raises(KeyError, match="tasks with an env"):
        env_id_for("robotasks9", "scoop")
    with pytest.raises(ValueError, match="only letters, digits"):
        lasa_env_name("Multi Models")
