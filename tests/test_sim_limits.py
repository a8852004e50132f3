"""Executability checks (`clfd_bench.sim.limits`): hand-computed cases per limit kind, and the
env integration (a violation ends the episode as a failure; demos run without one; pickling
keeps the monitor)."""

from __future__ import annotations

import math
import pickle

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import clfd_bench  # noqa: F401 - registers the ids
from clfd_bench.execution.rollout import rollout
from clfd_bench.sim.limits import (
    CARTESIAN_VELOCITY,
    MAX_REACH,
    MotionLimits,
    MotionMonitor,
    Violation,
    filter_gain,
    panda_limits,
)

DT = 1.0 / 60.0
SHOULDER = np.array([0.0, 0.0, 0.333])
Q0 = np.array([0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853])
DOWN = np.array([0.0, 1.0, 0.0, 0.0])  # hand z axis pointing down


def _monitor(**overrides) -> MotionMonitor:
    m = MotionMonitor(panda_limits(**overrides), DT, SHOULDER, floor_height=0.0)
    m.reset(np.array([0.4, -0.25, 0.5]), DOWN, Q0)
    return m


def _ramp(v_max: float, accel: float, steps: int) -> np.ndarray:
    """Speeds [steps] of a ramp from rest: v_k = min(accel (k + 1) dt, v_max)."""
    return np.minimum(accel * DT * np.arange(1, steps + 1), v_max)


def _run_translation(m: MotionMonitor, speeds: np.ndarray) -> Violation | None:
    pos = np.array([0.4, -0.25, 0.5])
    for v in speeds:
        pos = pos + np.array([0.0, v * DT, 0.0])
        bad = m.check_command(pos, DOWN, Q0)
        if bad is not None:
            return bad
    return None


def test_published_limits_and_joint_ranges():
    lim = panda_limits()
    assert (lim.cartesian_velocity, lim.cartesian_acceleration, lim.cartesian_jerk) == (
        1.7, 13.0, 6500.0)
    assert (lim.rotation_velocity, lim.rotation_acceleration, lim.rotation_jerk) == (
        2.5, 25.0, 12500.0)
    assert lim.joint_velocity == (2.175,) * 4 + (2.61,) * 3
    assert lim.joint_acceleration == (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0)
    assert lim.joint_jerk == (7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0)
    assert lim.joint_position_low[3] == pytest.approx(-3.0718)  # Menagerie joint4 range
    assert lim.joint_position_high[5] == pytest.approx(3.7525)
    assert lim.max_reach == MAX_REACH == 0.855
    with pytest.raises(TypeError, match="unknown limits"):
        panda_limits(cartesian_speed=1.0)
    with pytest.raises(ValueError, match="joint_velocity must have 7 entries"):
        MotionLimits(joint_velocity=(1.0,))


def test_translation_ramp_2ms_fails_at_the_right_step():
    # 10 m/s² (under 13) up to 2 m/s: v_k = 10 (k + 1) / 60 first exceeds 1.7 at k = 10.
    bad = _run_translation(_monitor(), _ramp(2.0, 10.0, 40))
    assert bad is not None and bad.kind == "reflex" and bad.limit == "cartesian velocity"
    assert bad.step == 10
    assert bad.value == pytest.approx(11 * 10.0 / 60.0)
    assert bad.bound == CARTESIAN_VELOCITY
    assert bad.reason == "reflex: cartesian velocity 1.833 m/s > 1.7 m/s at step 10"
    assert bad.as_dict() == {"kind": "reflex", "limit": "cartesian velocity",
                             "value": bad.value, "bound": 1.7, "unit": "m/s", "step": 10}


def test_translation_ramp_1p5ms_passes():
    assert _run_translation(_monitor(), _ramp(1.5, 10.0, 25)) is None


def test_first_command_is_measured_from_rest():
    # 2 cm off the pose the robot is at: 1.2 m/s (fine) but 72 m/s² from rest.
    m = _monitor()
    bad = m.check_command(np.array([0.4, -0.23, 0.5]), DOWN, Q0)
    assert bad.limit == "cartesian acceleration" and bad.step == 0
    assert bad.value == pytest.approx(0.02 * 60 * 60)


def test_far_target_is_unreachable_at_step_0():
    m = _monitor()
    target = np.array([5.0, 0.0, 0.333])
    bad = m.check_command(target, DOWN, Q0)
    assert bad.kind == "unreachable" and bad.step == 0
    assert bad.value == pytest.approx(5.0)
    assert bad.reason == "unreachable: target 5 m from the shoulder > 0.855 m at step 0"
    bad = _monitor().check_command(np.array([0.4, -0.25, -0.1]), DOWN, Q0)
    assert bad.kind == "unreachable" and bad.limit == "floor"
    assert bad.reason == "unreachable: target height -0.1 m below the floor (0 m) at step 0"


def _rotate(m: MotionMonitor, speeds: np.ndarray) -> Violation | None:
    quat = DOWN.copy()
    pos = np.array([0.4, -0.25, 0.5])
    for w in speeds:
        mujoco.mju_quatIntegrate(quat, np.array([0.0, 0.0, w]), DT)  # about the hand's z
        bad = m.check_command(pos, quat, Q0)
        if bad is not None:
            return bad
    return None


def test_rotation_3rads_fails():
    # Raw command (no input filter): 20 rad/s² up to 3 rad/s exceeds 2.5 rad/s at k = 7.
    bad = _rotate(_monitor(rotation_filter_hz=None), _ramp(3.0, 20.0, 40))
    assert bad.limit == "rotation velocity" and bad.step == 7
    assert bad.value == pytest.approx(8 * 20.0 / 60.0)
    # Default limits (filtered rotation): the sustained 3 rad/s still breaks 2.5 rad/s.
    bad = _rotate(_monitor(), _ramp(3.0, 20.0, 120))
    assert bad.limit == "rotation velocity" and 2.5 < bad.value <= 3.0 + 1e-9
    assert _rotate(_monitor(), _ramp(2.3, 20.0, 120)) is None


def test_rotation_filter_accepts_sample_and_hold_but_not_jumps():
    # The RoboTasks orientation stream repeats samples: 0.6 rad/s turning, every other
    # sample held (0, 1.2, 0, 1.2 rad/s), is 72 rad/s² raw and passes through the filter.
    speeds = np.tile([0.0, 1.2], 60)
    bad = _rotate(_monitor(rotation_filter_hz=None), speeds)
    assert bad.limit == "rotation acceleration"
    assert _rotate(_monitor(), speeds) is None
    # A 1 rad jump of the commanded orientation is refused.
    bad = _rotate(_monitor(), np.array([60.0]))
    assert bad.kind == "reflex" and bad.limit.startswith("rotation") and bad.step == 0


def test_filter_gain_is_libfrankas_lowpass():
    f = 100.0
    assert filter_gain(f, 1e-3) == pytest.approx(1e-3 / (1e-3 + 1 / (2 * math.pi * f)))
    assert filter_gain(None, DT) == 1.0


def test_joint_range_and_tracking():
    m = _monitor()
    q = Q0.copy()
    q[3] = -0.05  # joint4's range ends at -0.0698
    bad = m.check_command(np.array([0.4, -0.25, 0.5]), DOWN, q)
    assert bad.reason == "reflex: joint4 position -0.05 rad > -0.0698 rad at step 0"
    m = _monitor()
    m.check_command(np.array([0.4, -0.25, 0.5]), DOWN, Q0)
    lim = m.limits
    assert m.check_tracking(0.5 * lim.tracking_position, 0.0) is None
    bad = m.check_tracking(0.05, 0.0)
    assert bad.kind == "tracking" and bad.step == 0 and bad.value == 0.05
    assert bad.reason.startswith("tracking: position error 0.05 m > ")
    assert m.check_tracking(0.0, 1.0).limit == "rotation error"


def test_violation_reason_of_a_collision():
    v = Violation("collision", "contact force", 85.0, 20.0, "N", 412, detail="link6 hit shelf")
    assert v.reason == "collision: link6 hit shelf with 85 N > 20 N at step 412"


def test_monitor_state_roundtrip():
    a, b = _monitor(), _monitor()
    speeds = _ramp(1.0, 10.0, 20)
    _run_translation(a, speeds)
    b.set_state(pickle.loads(pickle.dumps(a.state())))
    more = np.array([0.4, -0.25 + 0.5, 0.5])  # a jump: both refuse it the same way
    assert a.check_command(more, DOWN, Q0) == b.check_command(more, DOWN, Q0)


# ----------------------------------------------------------------------------- in the envs
def test_goal_pose_from_the_first_step_is_a_reflex():
    env = gym.make("clfd/BottleShelving-v3")
    base = env.unwrapped
    goal = base.trajectory_to_actions(base.demo_trajectory(0))[-1]
    obs, _ = env.reset(options={"demo": 0})
    q_start = obs["qpos"].copy()
    _, reward, terminated, truncated, info = env.step(goal)
    assert terminated and not truncated and reward == 0.0 and not info["is_success"]
    assert info["failure"]["kind"] == "reflex" and info["failure"]["step"] == 0
    assert info["failure"]["limit"] == "cartesian velocity"
    assert info["failure_reason"].startswith("reflex: cartesian velocity ")
    assert info["failure_reason"].endswith("> 1.7 m/s at step 0")
    # The robot stops: later commands are ignored, the arm holds where it was.
    for _ in range(30):
        obs, _, terminated, _, info = env.step(goal)
    assert terminated and info["failure"]["step"] == 0
    np.testing.assert_allclose(obs["qpos"], q_start, atol=2e-3)
    env.close()


@pytest.mark.parametrize("env_id", ["clfd/BottleShelving-v3", "clfd/HelloWorld-h-v3"])
def test_demo_replay_has_no_failure(env_id):
    env = gym.make(env_id)
    result = rollout(env, env.unwrapped.demo_trajectory(0), demo=0)
    assert result.info["failure"] is None and result.info["failure_reason"] is None
    env.close()


def test_collision_with_the_floor(pose_env_cls):
    env = pose_env_cls()
    obs, _ = env.reset(options={"demo": 0})
    pos, quat = obs["ee_pos"].copy(), obs["ee_quat"].copy()
    v = 0.0
    for _ in range(200):  # down at 0.2 m/s (2 m/s² to get there) to 1 cm above the floor
        v = min(v + 2.0 * DT, 0.2)
        pos[2] = max(pos[2] - v * DT, 0.01)
        _, _, terminated, _, info = env.step(np.concatenate([pos, quat, [1.0]]))
        if terminated:
            break
    assert info["failure"]["kind"] == "collision"
    assert info["failure_reason"].startswith("collision: ")
    assert " hit floor with " in info["failure_reason"]
    assert info["failure"]["value"] > info["failure"]["bound"] == 20.0
    env.close()


def test_limits_none_switches_the_checks_off(pose_env_cls):
    env = pose_env_cls(limits=None)
    env.reset(options={"demo": 0})
    for _ in range(10):
        _, _, terminated, _, info = env.step(np.array([0.5, 0.3, 0.5, 0.0, 1.0, 0.0, 0.0, 1.0]))
    assert not terminated and info["failure"] is None
    assert env.motion_monitor is None
    with pytest.raises(ValueError, match="limits must be 'panda', a MotionLimits or None"):
        pose_env_cls(limits="franka")
    env.close()


def test_pickling_mid_episode_keeps_the_monitor(pose_env_cls):
    env = pose_env_cls()
    actions = env.trajectory_to_actions(env.demo_trajectory(0))
    env.reset(options={"demo": 0})
    for a in actions[:40]:
        env.step(a)
    clone = pickle.loads(pickle.dumps(env))
    state, cstate = env.motion_monitor.state(), clone.motion_monitor.state()
    for k in state:
        np.testing.assert_array_equal(state[k], cstate[k], err_msg=k)
    jump = actions[40].copy()
    jump[:3] += [0.0, 0.0, 0.05]  # 5 cm up in one step
    r1 = env.step(jump)[-1]
    r2 = clone.step(jump)[-1]
    assert r1["failure"] is not None and r1["failure"] == r2["failure"]
    assert r1["failure"]["step"] == 40
    # ... and a failed episode pickles as failed.
    again = pickle.loads(pickle.dumps(env))
    assert again.step(actions[41])[2] and again._failure == env._failure
    env.close()
    clone.close()
    again.close()
