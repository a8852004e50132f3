"""Orientation tangent map: Log relative to the goal and back with Exp."""

from __future__ import annotations

import numpy as np
import pytest

from clfd_bench.learning.normalize import Normalizer
from clfd_bench.learning.tangent import quat_exp_relative, quat_log_relative


def _random_quats(n: int, seed: int = 0) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _same_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(np.abs(np.sum(a * b, axis=-1)) - 1.0)


def test_round_trip_per_demo_goals():
    quats = _random_quats(3 * 50).reshape(3, 50, 4)
    goals = quats[:, -1]
    r = quat_log_relative(quats, goals)
    assert r.shape == (3, 50, 3)
    assert np.allclose(r[:, -1], 0.0, atol=1e-12)  # the goal itself maps to 0
    back = quat_exp_relative(r, goals)
    assert _same_rotation(back, quats).max() < 1e-12


def test_round_trip_single_goal_and_double_cover():
    quats = _random_quats(40, seed=1)
    goal = _random_quats(1, seed=2)[0]
    r = quat_log_relative(quats, goal)
    assert np.allclose(r, quat_log_relative(-quats, goal))  # q and -q: same rotation
    assert np.all(np.linalg.norm(r, axis=-1) <= np.pi / 2 + 1e-12)  # shortest arc
    assert _same_rotation(quat_exp_relative(r, goal), quats).max() < 1e-12


def test_log_is_half_the_rotation_angle_about_the_axis():
    """Paper: Log(q) = arccos(w) u/|u| -- half the rotation angle."""
    angle, axis = 0.8, np.array([0.0, 0.6, 0.8])
    goal = np.array([1.0, 0.0, 0.0, 0.0])
    q = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])
    assert np.allclose(quat_log_relative(q[None], goal)[0], angle / 2 * axis)
    # relative to a rotated goal: Log(conj(g) * (g * q)) recovers the same vector
    g = _random_quats(1, seed=3)[0]
    gq = quat_exp_relative((angle / 2 * axis)[None], g)
    assert np.allclose(quat_log_relative(gq, g)[0], angle / 2 * axis)


def test_goal_shape_is_checked():
    with pytest.raises(ValueError, match="do not match"):
        quat_log_relative(_random_quats(6).reshape(2, 3, 4), _random_quats(3))


def test_normalizer_round_trip():
    demos = np.random.default_rng(0).normal(size=(4, 30, 3)) * [1.0, 5.0, 0.1] + [2.0, -1.0, 0.0]
    norm = Normalizer.fit(demos)
    z = norm.apply(demos)
    assert np.allclose(z.reshape(-1, 3).mean(0), 0.0) and np.allclose(z.reshape(-1, 3).std(0), 1)
    assert np.allclose(norm.invert(z), demos)
    assert np.allclose(Normalizer.from_list(norm.to_list()).apply(demos), z)
