"""Start configurations by backward tracking (docs/data.md, "Frames and start configurations")
and the hand frame convention."""

from __future__ import annotations

import numpy as np
import pytest

from clfd_bench.data import load_task
from clfd_bench.sim.ik import quat_angle
from clfd_bench.sim.robot import hand_pose, robot_model
from clfd_bench.sim.start_configs import backward_start_configs, tracking_errors


@pytest.fixture(scope="module")
def openbox():
    task = load_task("robotasks", "openbox")
    return task.positions, task.quaternions


@pytest.fixture(scope="module")
def start_q(openbox):
    pos, quat = openbox
    return backward_start_configs(robot_model(), pos[:1], quat[:1])[0]


def test_hand_frame_at_start_config_matches_first_pose(openbox, start_q):
    pos, quat = openbox
    p, q = hand_pose(robot_model(), start_q)
    assert np.linalg.norm(p - pos[0, 0]) < 1e-4
    assert quat_angle(q, quat[0, 0]) < 1e-3


def test_forward_tracking_from_backward_start_follows_openbox(openbox, start_q):
    pos, quat = openbox
    pos_err, rot_err = tracking_errors(robot_model(), start_q, pos[0], quat[0])
    assert pos_err.max() < 1e-3  # 1 mm
    assert np.degrees(rot_err.max()) < 0.5


def test_shapes_are_checked():
    with pytest.raises(ValueError, match=r"positions must have shape \[N, T, 3\]"):
        backward_start_configs(robot_model(), np.zeros((2, 5, 2)), np.zeros((2, 5, 4)))
    with pytest.raises(ValueError, match="quaternions must have shape"):
        backward_start_configs(robot_model(), np.zeros((2, 5, 3)), np.zeros((2, 4, 4)))
