"""RoboTasks scenes: the geometry they are derived from, the specs, the grasp model and the
physical success predicates on hand-made states."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from clfd_bench.data import load_dataset
from clfd_bench.envs.robotask_scenes import set_free_pose
from clfd_bench.envs.robotask_specs import TASKS, dumps_task_spec, load_task_spec
from clfd_bench.envs.robotasks import RoboTaskEnv
from clfd_bench.sim.robot import hand_pose, robot_model
from clfd_bench.sim.scene_fit import fit_hinge, grasp_points, hinge_angles


@pytest.fixture(scope="module")
def robotasks():
    return load_dataset("robotasks")


@pytest.fixture(scope="module")
def envs():
    made = {task: RoboTaskEnv(task) for task in TASKS}
    yield made
    for env in made.values():
        env.close()


def _body(env, name):
    return mujoco.mj_name2id(env.model, mujoco.mjtObj.mjOBJ_BODY, name)


def _quat_about(axis, angle):
    q = np.empty(4)
    mujoco.mju_axisAngle2Quat(q, np.asarray(axis, dtype=float), angle)
    return q


# ---------------------------------------------------------------- scene geometry
def test_fit_hinge_recovers_a_known_axis_from_noisy_arcs():
    rng = np.random.default_rng(0)
    point = np.array([0.42, -0.55, 0.19])
    yaw = np.radians(-10.0)
    axis = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    front = np.cross([0.0, 0.0, 1.0], axis)
    up = np.cross(axis, front)
    arcs = []
    for radius, axial in [(0.23, -0.01), (0.26, 0.02), (0.25, 0.0), (0.24, 0.01)]:
        ang = np.linspace(0.0, np.radians(rng.uniform(85, 115)), 200)
        pts = (point + axial * axis + radius * (np.cos(ang)[:, None] * front
                                                + np.sin(ang)[:, None] * up))
        arcs.append(pts + rng.normal(0.0, 0.001, pts.shape))
    fit = fit_hinge(np.stack(arcs))
    assert abs(float(fit.axis @ axis)) > np.cos(np.radians(0.5))
    assert fit.axis @ axis > 0  # oriented so that the lid opens by a positive angle
    # The fitted point lies on the true axis.
    off = fit.point - point
    assert np.linalg.norm(off - (off @ axis) * axis) < 2e-3
    np.testing.assert_allclose(np.sort(fit.radii), [0.23, 0.24, 0.25, 0.26], atol=2e-3)
    assert np.all(hinge_angles(np.stack(arcs), fit)[:, -1] > np.radians(80))


def test_openbox_hinge_fits_the_demonstrated_arcs(robotasks):
    task = robotasks.tasks[robotasks.task_names.index("openbox")]
    g = grasp_points(task.positions, task.quaternions)
    fit = fit_hinge(g)
    # The demos' grasp points stay within the lid handle's slide ranges (tasks/openbox.xml).
    assert np.all(fit.radii - 0.25 > -0.055) and np.all(fit.radii + fit.radial_residual
                                                        - 0.25 < 0.045)
    ang = np.degrees(hinge_angles(g, fit))
    spec = load_task_spec("openbox")
    np.testing.assert_allclose(spec["scene"]["hinge_pos"], fit.point, atol=1e-6)
    np.testing.assert_allclose(spec["derived"]["grasp_angle_end_deg"], ang[:, -1], atol=1e-6)
    np.testing.assert_allclose(spec["derived"]["grasp_angle_half_deg"], ang[:, ang.shape[1] // 2],
                               atol=1e-6)


def test_the_lid_balances_between_the_demos_half_time_and_end_angles(envs):
    """The lid (with its handle) falls open past its balance angle and shut below it: every
    demo must end past it and none be past it at half time, with a margin."""
    spec = load_task_spec("openbox")
    half = max(spec["derived"]["grasp_angle_half_deg"])
    end = min(spec["derived"]["grasp_angle_end_deg"])
    env = envs["openbox"]
    env.reset(options={"demo": 0})
    d, m = env.data, env.model
    d.qpos[env.scene.qadr["lid_hinge"]] = 0.0
    mujoco.mj_forward(m, d)
    lid = _body(env, "lid")
    rot = d.xmat[lid].reshape(3, 3)
    com = rot.T @ (d.subtree_com[lid] - d.xpos[lid])  # lid frame: y to the front, z up
    balance = 90.0 + np.degrees(np.arctan2(-com[2], com[1]))
    assert half + 2.0 < balance < end - 2.0, (half, balance, end)


@pytest.mark.parametrize("task_name", TASKS)
def test_start_configurations_put_the_hand_at_each_demos_first_pose(robotasks, task_name):
    task = robotasks.tasks[robotasks.task_names.index(task_name)]
    qpos = np.asarray(load_task_spec(task_name)["start"]["qpos"])
    assert qpos.shape == (task.positions.shape[0], 7)
    model = robot_model()
    for j, q in enumerate(qpos):
        pos, quat = hand_pose(model, q)
        assert np.linalg.norm(pos - task.positions[j, 0]) < 1e-3, (task_name, j)
        angle = 2 * np.arccos(min(1.0, abs(float(quat @ task.quaternions[j, 0]))))
        assert np.degrees(angle) < 0.1, (task_name, j)


def test_task_spec_errors_name_the_problem():
    with pytest.raises(KeyError, match="valid"):
        load_task_spec("washdishes")
    doc = load_task_spec("openbox")
    bad = {k: dict(v) for k, v in doc.items() if k != "success"}
    with pytest.raises(ValueError, match=r"missing table \[success\]"):
        RoboTaskEnv("openbox", spec=bad)


def test_dumps_task_spec_round_trips():
    import tomllib

    doc = {"task": {"name": "x", "flag": False}, "scene": {"v": np.array([0.1, 2.0]),
                                                           "m": [[1.0, 2.0], [3.0, 4.0]]}}
    back = tomllib.loads(dumps_task_spec(doc, "header line"))
    assert back == {"task": {"name": "x", "flag": False},
                    "scene": {"v": [0.1, 2.0], "m": [[1.0, 2.0], [3.0, 4.0]]}}


# ---------------------------------------------------------------- grasp model
def test_reset_attaches_the_prop_at_the_grasp_point(envs):
    for task, env in envs.items():
        env.reset(options={"demo": 1})
        assert env.grasp.held(env.data), task
        dist, angle = env.grasp.separation(env.data)
        assert dist < 1e-9 and angle < 1e-6, task


def test_opening_the_gripper_releases_and_the_prop_falls(envs):
    env = envs["bottle2shelf"]
    env.reset(options={"demo": 0})
    bottle = _body(env, "bottle")
    z0 = env.data.xpos[bottle, 2]
    hold = env.trajectory_to_actions(env.demo_trajectory(0)[:1])[0]
    for _ in range(3):
        env.step(hold)
    assert env.grasp.held(env.data)
    release = hold.copy()
    release[7] = 0.0
    _, _, _, _, info = env.step(release)
    assert not info["held"] and info["release_reason"] == "opened"
    env.step(release)  # a released prop is not grasped again while the command stays open
    hold_again = hold.copy()
    for _ in range(10):
        _, _, _, _, info = env.step(hold_again)
    assert not info["held"]
    assert env.data.xpos[bottle, 2] < z0 - 0.001  # it fell onto the table


def test_a_prop_pulled_out_of_the_grasp_slips(envs):
    env = envs["platestandingtolying"]
    env.reset(options={"demo": 0})
    plate = _body(env, "plate")
    adr = env.model.jnt_qposadr[env.model.body_jntadr[plate]]
    env.data.qpos[adr:adr + 3] += [0.0, 0.0, 0.05]  # 5 cm away from where the hand holds it
    mujoco.mj_kinematics(env.model, env.data)
    env.grasp.update(env.data)
    assert not env.grasp.held(env.data) and env.grasp.release_reason == "slipped"


# ---------------------------------------------------------------- success predicates
def test_openbox_success_is_the_lid_angle(envs):
    env = envs["openbox"]
    env.reset(options={"demo": 0})
    hinge = env.scene.qadr["lid_hinge"]
    threshold = load_task_spec("openbox")["success"]["min_lid_angle_deg"]
    for angle, expected in [(0.0, False), (60.0, False), (threshold - 1.0, False),
                            (120.0, True)]:
        env.data.qpos[hinge] = np.radians(angle)
        mujoco.mj_forward(env.model, env.data)
        ok, info = env.scene.success(env.data, env.grasp)
        assert ok is expected, angle
        assert info["lid_angle_deg"] == pytest.approx(angle)


def _release(env):
    env.grasp.release(env.data)


def test_bottle_success_needs_it_lying_on_the_shelf(envs):
    env = envs["bottle2shelf"]
    env.reset(options={"demo": 0})
    _release(env)
    bottle = _body(env, "bottle")
    top = np.asarray(env.spec_doc["scene"]["shelf_top"])
    lying = _quat_about([1.0, 0.0, 0.0], np.pi / 2)  # bottle axis (its z) along -y
    cases = [
        ("lying on the shelf", top + [0.0, 0.05, 0.032], lying, True),
        ("standing on the shelf", top + [0.0, 0.0, 0.035], np.array([0.0, 1.0, 0.0, 0.0]),
         False),
        ("lying on the floor", np.array([0.2, 0.3, 0.032]), lying, False),
        ("lying beside the shelf", top + [0.0, 0.3, 0.032], lying, False),
    ]
    for name, pos, quat, expected in cases:
        set_free_pose(env.model, env.data, bottle, pos, quat)
        mujoco.mj_forward(env.model, env.data)
        ok, _ = env.scene.success(env.data, env.grasp)
        assert ok is expected, name
    # Lying on the shelf but still held: not placed.
    set_free_pose(env.model, env.data, bottle, top + [0.0, 0.05, 0.032], lying)
    env.data.eq_active[env.grasp.eq_id] = 1
    mujoco.mj_forward(env.model, env.data)
    assert env.scene.success(env.data, env.grasp)[0] is False


def test_plate_success_needs_it_lying_on_the_platform_and_the_blocks_in_place(envs):
    env = envs["platestandingtolying"]
    env.reset(options={"demo": 0})
    _release(env)
    plate = _body(env, "plate")
    top = np.asarray(env.spec_doc["scene"]["platform_top"])
    # Plate normal (its y axis) up: turn -90 deg about x; the disc centre is 0.06 m along the
    # plate frame's z, which then points along world y.
    lying = _quat_about([1.0, 0.0, 0.0], -np.pi / 2)
    on_platform = top + [0.0, -0.06, 0.005]
    cases = [("lying on the platform", on_platform, lying, True),
             ("standing on the platform", top + [0.0, 0.0, 0.0], np.array([1.0, 0, 0, 0]),
              False),
             ("lying on the floor", np.array([0.3, 0.3, env.scene.table_z + 0.005]), lying,
              False)]
    for name, pos, quat, expected in cases:
        set_free_pose(env.model, env.data, plate, pos, quat)
        mujoco.mj_forward(env.model, env.data)
        ok, info = env.scene.success(env.data, env.grasp)
        assert ok is expected, (name, info)
    set_free_pose(env.model, env.data, plate, on_platform, lying)
    block = env.scene.block_ids[2]
    set_free_pose(env.model, env.data, block, env.scene.block_start[2] + [0.05, 0.0, 0.0],
                  np.array([1.0, 0, 0, 0]))
    mujoco.mj_forward(env.model, env.data)
    ok, info = env.scene.success(env.data, env.grasp)
    assert ok is False and info["blocks_in_place"] is False


def test_pouring_success_counts_beans_in_the_container(envs):
    env = envs["pouring"]
    env.reset(options={"demo": 0})
    floor = np.asarray(env.spec_doc["scene"]["container_floor"])
    half = env.spec_doc["scene"]["container_half_size"]
    r = env.scene.bean_radius
    n = env.scene.n_beans
    need = int(np.ceil(load_task_spec("pouring")["success"]["min_fraction"] * n))
    xs = np.linspace(-half + r, half - r, n)
    for inside, expected in [(n, True), (need, True), (need - 1, False), (0, False)]:
        for i, b in enumerate(env.scene.bean_ids):
            where = (floor + [xs[i], 0.0, r]) if i < inside else np.array([0.6, 0.3 + 0.03 * i, r])
            set_free_pose(env.model, env.data, b, where, np.array([1.0, 0, 0, 0]))
        mujoco.mj_forward(env.model, env.data)
        ok, info = env.scene.success(env.data, env.grasp)
        assert ok is expected, inside
        assert info["bean_fraction"] == pytest.approx(inside / n)


@pytest.mark.parametrize("task_name", ["bottle2shelf", "platestandingtolying"])
def test_task_specs_are_up_to_date_with_their_derivation(task_name):
    """The committed scene numbers are what `eval/make_task_specs.py` derives from the data."""
    from clfd_bench.envs.robotask_derive import derive_spec

    derived = derive_spec(task_name, with_starts=False)["scene"]
    stored = load_task_spec(task_name)["scene"]
    assert derived.keys() == stored.keys()
    for key, value in derived.items():
        np.testing.assert_allclose(np.asarray(stored[key], dtype=float),
                                   np.asarray(value, dtype=float), atol=1e-6, err_msg=key)


def test_a_pickled_env_keeps_holding_its_prop_like_the_original():
    import pickle

    env = RoboTaskEnv("platestandingtolying")
    actions = env.trajectory_to_actions(env.demo_trajectory(2)[:30])
    env.reset(options={"demo": 2})
    for a in actions[:10]:
        env.step(a)
    clone = pickle.loads(pickle.dumps(env))
    for a in actions[10:]:
        o1, *_, i1 = env.step(a)
        o2, *_, i2 = clone.step(a)
        np.testing.assert_array_equal(o1["objects"], o2["objects"])
        assert i1["held"] and i2["held"]
    env.close()
    clone.close()
