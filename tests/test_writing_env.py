"""Writing env geometry (pen down at the demo's start, ink only on the board, LASA placement,
text layout, cameras, env ids), the shape metrics and criterion on synthetic ink, and the
per-task tolerances against their derivation from the demos. No rollouts of whole demos here
(tests/test_writing_replay.py has those)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import clfd_bench  # noqa: F401
from clfd_bench.data import load_dataset
from clfd_bench.envs.registration import env_id_for, lasa_env_name
from clfd_bench.envs.writing import (
    ShapeTolerances,
    judge_shape,
    load_tolerances,
    load_writing_spec,
    min_jerk,
)
from clfd_bench.metrics.trajectory import coverage, hausdorff


def test_reset_puts_the_pen_down_at_the_demo_start():
    env = gym.make("clfd/HelloWorld-w-v2").unwrapped
    obs, info = env.reset(seed=0, options={"demo": 4})
    assert info["demo"] == 4
    np.testing.assert_allclose(obs["pen_tip"][:2], env.demos[4, 0], atol=1e-3)
    spec = load_writing_spec()
    assert abs(obs["pen_tip"][2] - spec.surface_height) < 5e-4  # the spring takes the press
    obs, *_ = env.step(env.demos[4, 0])
    assert obs["pen_down"][0] == 1.0
    env.close()


def test_actions_are_clipped_to_the_board():
    # A jump to the board's edge breaks the Panda's motion limits (a reflex); switched off here,
    # where only the clipping is tested.
    env = gym.make("clfd/LASA-Line-v2", limits=None).unwrapped
    env.reset(seed=0, options={"demo": 0})
    for _ in range(90):
        obs, *_ = env.step(np.array([5.0, 0.0]))  # far beyond the board edge x = 0.75
    np.testing.assert_allclose(obs["pen_tip"][:2], [0.75, 0.0], atol=3e-3)
    for _ in range(30):
        obs, *_ = env.step(np.array([0.7, 0.0]))
    assert obs["pen_down"][0] == 1.0
    env.close()


def test_lifted_pen_leaves_no_ink():
    env = gym.make("clfd/HelloWorld-v2", text="l").unwrapped
    env.reset(seed=0, options={"demo": 0})
    start = env.letter_to_surface(0, env.demo_letters(0)[0][0])
    for lift in np.concatenate([min_jerk(24), np.ones(30)]):
        obs, _, terminated, *_ = env.step(np.append(start, lift))
        assert not terminated
    assert obs["pen_down"][0] == 0.0 and obs["pen_tip"][2] > 0.12
    assert env.ink_trace().shape[0] < 10  # only while lifting off
    env.close()


def test_lasa_goal_is_centred_placement():
    env = gym.make("clfd/LASA-Angle-v2").unwrapped
    demos = env.demos
    xy = env.to_surface(demos)
    centre = (xy.min(axis=(0, 1)) + xy.max(axis=(0, 1))) / 2
    np.testing.assert_allclose(centre, load_writing_spec().lasa_center, atol=1e-9)
    np.testing.assert_allclose(env.to_data(env.to_surface(demos[0])), demos[0], atol=1e-9)
    assert env.sim_scale == load_dataset("lasa").tasks[0].sim_scale
    env.close()


def test_text_layout_places_letters_along_a_line():
    env = gym.make("clfd/HelloWorld-v2").unwrapped
    assert env.letters == list("helloworld")
    actions = env.trajectory_to_actions(env.demo_letters(0))
    assert actions.shape == (env._trajectory_steps(0), 3)
    spec = load_writing_spec()
    lifted = actions[:, 2] > 0.05
    lift = min_jerk(spec.text_lift_steps)
    per_move = int(np.sum(lift > 0.05) + np.sum(1 - lift > 0.05)) + spec.text_travel_steps
    assert lifted.sum() == 9 * per_move  # 9 transitions between 10 letters
    # Lift, travel, lower in turn: the pen moves sideways only at full height.
    moving = np.linalg.norm(np.diff(actions[:, :2], axis=0), axis=1) > 1e-12
    steps = np.flatnonzero(moving & (actions[1:, 2] > 0))
    assert np.all(actions[1:, 2][steps] == 1.0)
    # Smooth from rest to rest: accelerations of the pen-up moves far below 13 m/s^2.
    up = np.flatnonzero(lifted)
    pos = np.column_stack([actions[:, :2], actions[:, 2] * spec.lift_height])
    acc = np.diff(pos, n=2, axis=0) * 60.0 ** 2
    assert np.linalg.norm(acc[up[up < len(acc)] - 1], axis=1).max() < 2.0
    with pytest.raises(ValueError, match="has 10 letters"):
        env.trajectory_to_actions(env.demo_letters(0)[:3])
    env.close()


def test_every_dataset_task_has_an_env_id():
    for name in ("helloworld", "lasa"):
        for task in load_dataset(name).task_names:
            assert env_id_for(name, task) in gym.registry
    for name in ("robotasks", "robotasks9"):  # every RoboTasks9 task has a scene now
        for task in load_dataset(name).task_names:
            assert env_id_for(name, task) in gym.registry
    with pytest.raises(KeyError, match="tasks with an env"):
        env_id_for("robotasks9", "juggling")
    with pytest.raises(ValueError, match="only letters, digits"):
        lasa_env_name("Multi Models")


def test_hausdorff_and_coverage_by_hand():
    line = np.column_stack([np.linspace(0, 1, 101), np.zeros(101)])
    bump = line.copy()
    bump[50, 1] = 0.3  # one point 0.3 off the line
    assert hausdorff(line, bump) == pytest.approx(0.3)
    assert hausdorff(line, line[::-1]) == 0.0  # order-free
    half = line[:51]
    assert hausdorff(half, line) == pytest.approx(0.5)
    assert coverage(line, half, 0.01) == pytest.approx(0.5)  # by arc length
    assert coverage(line, half, 0.01, by="points") == pytest.approx(51 / 101)
    assert coverage(line, line + [0.0, 0.02], 0.01) == 0.0


def _judge(path: np.ndarray, target: np.ndarray, tol: ShapeTolerances) -> dict:
    return judge_shape(path, path, target, target[-1], tol, dtw_threshold=18.21,
                       goal_tolerance=0.01)


def test_judge_shape_on_synthetic_letters():
    # A 'u' of 10 cm (metres, HelloWorld units), 600 samples.
    s = np.linspace(0, np.pi, 600)
    u = np.column_stack([0.05 * (1 - np.cos(s)), -0.1 * np.sin(s)])
    tol = ShapeTolerances(hausdorff=0.015, coverage_radius=0.01, min_coverage=0.9,
                          max_dwell=0.5)
    assert _judge(u, u, tol)["is_success"]
    slow = np.repeat(u, 2, axis=0)
    assert _judge(slow, u, tol)["is_success"]
    straight = np.linspace(u[0], u[-1], 600)
    assert set(_judge(straight, u, tol)["failed"]) >= {"hausdorff", "coverage"}
    rush = np.concatenate([u[::10], np.repeat(u[-1:], 540, axis=0)])  # right shape, then waits
    assert _judge(rush, u, tol)["failed"] == ["dwell"]
    half = u[:300]
    assert "goal" in _judge(half, u, tol)["failed"]


def test_tolerances_equal_their_derivation():
    """tasks/writing_tolerances.toml is what the written procedure gives on the demos."""
    from clfd_bench.envs.writing_derive import derive_tolerances

    derived = derive_tolerances()
    assert set(derived["helloworld"]) == set("helloworld") - {" "}
    assert len(derived["lasa"]) == 26
    for dataset, tasks in derived.items():
        for task, vals in tasks.items():
            tol = load_tolerances(dataset, task)
            for key in ("hausdorff", "coverage_radius", "min_coverage", "max_dwell"):
                assert getattr(tol, key) == pytest.approx(vals[key], rel=1e-5), (dataset, task,
                                                                                 key)


def test_tolerances_follow_the_demo_spread():
    spec = load_writing_spec()
    proc = spec.tolerance_procedure
    for name in ("helloworld", "lasa"):
        ds = load_dataset(name)
        for task in ds.tasks:
            tol = load_tolerances(name, task.name)
            floor = proc["hausdorff_floor"] / task.sim_scale
            assert tol.hausdorff >= floor - 1e-12
            assert tol.min_coverage == proc["coverage_fraction"]
            assert 0 < tol.max_dwell <= proc["dwell_cap"]


def _project(cam, points: np.ndarray, aspect: float = 4 / 3) -> np.ndarray:
    """Image coordinates in [-1, 1] (x right, y up) of world points [K, 3] seen by a MuJoCo free
    camera with a 45° vertical field of view."""
    import math

    az, el = math.radians(cam.azimuth), math.radians(cam.elevation)
    fwd = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    pos = np.array(cam.lookat) - cam.distance * fwd
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    rel = points - pos
    depth = rel @ fwd
    t = math.tan(math.radians(22.5))
    return np.column_stack([rel @ right / depth / (t * aspect), rel @ up / depth / t])


def test_cameras_frame_the_shape():
    """The shape is in view and spans a good part of the 640 x 480 frame, reading the right way
    round (HelloWorld: the writing direction -x to the right; LASA: +x to the right)."""
    for env_id, right in (("clfd/HelloWorld-l-v2", -1), ("clfd/HelloWorld-h-v2", -1),
                          ("clfd/LASA-Worm-v2", 1), ("clfd/LASA-Line-v2", 1),
                          ("clfd/HelloWorld-v2", -1)):
        env = gym.make(env_id).unwrapped
        pts = env._framed_points()
        uv = _project(env.camera(), np.column_stack([pts, np.full(len(pts), 0.1)]))
        assert np.abs(uv).max() < 0.95, env_id  # all in view
        span = (uv.max(axis=0) - uv.min(axis=0)) / 2  # fraction of width, height
        assert span.max() > 0.4, (env_id, span)
        a, b = np.array([[0.4, 0.0, 0.1], [0.45, 0.0, 0.1]]) @ np.eye(3)
        ua, ub = _project(env.camera(), np.array([a, b]))
        assert np.sign(ub[0] - ua[0]) == right, env_id
        env.close()
