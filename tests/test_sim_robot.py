"""The composed Panda model: Menagerie + assets/panda additions."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from clfd_bench.sim.robot import (
    ARM_JOINTS,
    GRASP_OFFSET,
    HOME_QPOS,
    PEN_TIP_OFFSET,
    RobotIndex,
    hand_pose,
    panda_spec,
    robot_model,
)


def _site_in_hand(model, data, site):
    hand = data.body("hand")
    rel = data.site(site).xpos - hand.xpos
    return hand.xmat.reshape(3, 3).T @ rel


def test_grasp_site_and_pen_tip_along_hand_z():
    model = robot_model("pen")
    data = mujoco.MjData(model)
    data.qpos[RobotIndex(model).arm_qpos] = HOME_QPOS
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(_site_in_hand(model, data, "grasp"), [0, 0, GRASP_OFFSET],
                               atol=1e-9)
    np.testing.assert_allclose(_site_in_hand(model, data, "pen_tip"), [0, 0, PEN_TIP_OFFSET],
                               atol=1e-9)


def test_robot_model_without_tool_has_no_pen_and_all_names():
    model = robot_model()
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "pen_tip") == -1
    for name in ARM_JOINTS:
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) >= 0
    assert model.body("hand").id > 0 and model.geom("floor").id >= 0


def test_unknown_tool_is_rejected_with_valid_names():
    with pytest.raises(ValueError, match="valid tools"):
        panda_spec("brush")


def test_gravity_compensation_holds_the_arm_at_home():
    model = robot_model()
    data = mujoco.MjData(model)
    idx = RobotIndex(model)
    data.qpos[idx.arm_qpos] = HOME_QPOS
    data.ctrl[idx.arm_act] = HOME_QPOS
    mujoco.mj_step(model, data, nstep=500)
    assert np.abs(data.qpos[idx.arm_qpos] - HOME_QPOS).max() < 1e-4


def test_robot_does_not_collide_with_itself_but_with_the_world():
    model = robot_model()
    robot_geoms = [g for g in range(model.ngeom)
                   if model.geom_bodyid[g] > 0 and (model.geom_contype[g] or
                                                    model.geom_conaffinity[g])]
    assert robot_geoms
    for g in robot_geoms:
        assert (model.geom_contype[g] & model.geom_conaffinity[g]) == 0  # not with each other
        assert model.geom_conaffinity[g] & 1  # with default (contype 1) objects


def test_hand_pose_at_home_points_down():
    pos, quat = hand_pose(robot_model(), HOME_QPOS)
    z_axis = np.empty(9)
    mujoco.mju_quat2Mat(z_axis, quat)
    np.testing.assert_allclose(z_axis.reshape(3, 3)[:, 2], [0, 0, -1], atol=1e-3)
    assert 0.5 < pos[0] < 0.6 and pos[2] > 0.5
