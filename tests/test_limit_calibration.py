"""The measurement behind `clfd_bench.sim.limits` (`clfd_bench.execution.limit_calibration`,
`limit_derivation`): a quick run on demo 0 of two small envs, hand-computed filtered peaks of
synthetic command streams and the cutoff choice they imply, and an injected jump of the command."""

from __future__ import annotations

import math

import numpy as np
import pytest

import clfd_bench  # noqa: F401 - registers the ids
from clfd_bench.execution.limit_calibration import (
    CommandStream,
    calibration_env,
    calibration_env_ids,
    grid_peaks,
    measure,
    measure_rollout,
    stream_peaks,
)
from clfd_bench.execution.limit_derivation import (
    Calibration,
    RolloutMeasurement,
    choose_cutoff,
    compare,
    differences,
)
from clfd_bench.execution.replay import replay_trajectory
from clfd_bench.execution.rollout import rollout
from clfd_bench.sim import limits as L
from clfd_bench.sim.limits import filter_gain

DT = 1.0 / 60.0
LETTER = "clfd/HelloWorld-l-v3"


def _stream(pos: np.ndarray, quat: np.ndarray, q: np.ndarray) -> CommandStream:
    """A stream of T commands ([T, 3], [T, 4], [T, 7]) starting at rest at the first one's
    predecessor: identity orientation, origin + (0.4, 0, 0.5), joints 0."""
    return CommandStream(np.array([0.4, 0.0, 0.5]), np.array([1.0, 0.0, 0.0, 0.0]),
                         np.zeros(7), pos, quat, q, DT)


def _rest(T: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return (np.tile([0.4, 0.0, 0.5], (T, 1)), np.tile([1.0, 0.0, 0.0, 0.0], (T, 1)),
            np.zeros((T, 7)))


def _synthetic_record(stream: CommandStream) -> RolloutMeasurement:
    rot, joints = grid_peaks(stream)
    return RolloutMeasurement(
        env_id="synthetic", demo=0, family="demo", success=True, failure_reason=None,
        steps=len(stream), trajectory_steps=len(stream), tracking_position=0.001,
        tracking_position_step=0, tracking_rotation=0.001, tracking_rotation_step=0,
        collision_force=0.0, collision_detail="", collision_step=None,
        raw_peaks=stream_peaks(stream), rotation_peaks=rot, joint_peaks=joints,
        peak_reach=0.5, lowest_height=0.5, floor_height=0.0, wall_s=0.0)


def test_env_list_is_the_822_replays():
    ids = calibration_env_ids()
    assert len(ids) == 4 + 7 + 26  # RoboTasks, HelloWorld letters, LASA shapes
    assert "clfd/HelloWorld-v3" not in ids and LETTER in ids
    later = ("clfd/WineGlass-", "clfd/PanToStove-", "clfd/ObstacleRotate-",
             "clfd/MatFolding-", "clfd/Scoop-")  # added since
    assert not any(i.startswith(later) for i in ids)


def test_rotation_jump_filtered_acceleration_and_cutoff_choice():
    # At rest, then the orientation jumps by theta about z and holds. Two cascaded stages of
    # y += g (x - y) on the per-step increment: the filtered increment at the jump is g^2 theta
    # (from 0 before), so the peak acceleration is g^2 theta / dt^2 (later steps change by
    # g^2 (1 - g)^(n-1) |1 - (n+1) g| theta < g^2 theta).
    theta = 125.0 * DT ** 2  # 0.0347 rad: g^2 theta / dt^2 = 125 g^2 rad/s^2
    pos, quat, q = _rest(40)
    quat[:] = [math.cos(theta / 2), 0.0, 0.0, math.sin(theta / 2)]
    stream = _stream(pos, quat, q)
    rot, joints = grid_peaks(stream)
    for i, f in enumerate(L.ROTATION_FILTER_GRID):
        assert rot[i, 1] == pytest.approx(filter_gain(f, DT) ** 2 * 125.0, rel=1e-9)
    assert not joints.any()
    # Raw: the whole jump in one step, theta / dt^2 = 125 rad/s^2, 5 x the limit.
    assert stream_peaks(stream)[1, 1] == pytest.approx(125.0, rel=1e-9)
    # vs 2/3 of 25 rad/s^2: 8 Hz 0.208 x 125 / 25 = 1.04, 6 Hz 0.744, 5 Hz 0.590 -> 5 Hz.
    ratios = rot[:, 1] / L.ROTATION_ACCELERATION
    assert ratios[1] > 2 / 3 > ratios[2]
    assert choose_cutoff(L.ROTATION_FILTER_GRID, ratios) == 5.0
    assert choose_cutoff((8.0, 6.0), ratios[:2]) is None
    # The same through the procedure: the rotation cutoff is 5 Hz; no joint moves, so the
    # highest joint cutoff passes; the translation stays raw.
    derived = Calibration([_synthetic_record(stream)]).derive()
    assert derived.rotation_filter_hz == 5.0 and derived.joint_filter_hz == 3.0
    assert derived.rotation_worst[2].quantity == "rotation acceleration"
    assert derived.rotation_worst[2].ratio == pytest.approx(ratios[2])
    assert derived.translation_raw_passes


def test_held_joint_sample_filtered_acceleration():
    # Joint 2 ramps up slowly (300 steps) to a per-step increment a, runs steadily, and one
    # sample repeats the previous one (held), the next catches up (increment 2a). Against the
    # steady filtered increment a, the held sample is an increment of -a then +a: the filtered
    # increment drops by g^2 a, so the acceleration peaks at g^2 a / dt^2 (the slow ramp's is
    # far below).
    a = 0.2 * DT  # 0.2 rad/s
    T, hold = 700, 600
    inc = np.minimum(np.arange(1, T + 1) / 300.0, 1.0) * a
    inc[hold], inc[hold + 1] = 0.0, 2 * a
    pos, quat, q = _rest(T)
    q[:, 1] = np.cumsum(inc)
    stream = _stream(pos, quat, q)
    _, joints = grid_peaks(stream)
    for j, f in enumerate(L.JOINT_FILTER_GRID):
        g = filter_gain(f, DT)
        assert joints[j, 1, 1] == pytest.approx(g ** 2 * a / DT ** 2, rel=1e-3)
        assert 0.2 <= joints[j, 0, 1] < 0.205  # the steady speed (+ a small overshoot)
    assert np.all(np.diff(joints[:, 1, 1]) < 0)  # lower cutoff, smaller acceleration
    # Unfiltered: -a then +2a per step: a / dt^2 twice over.
    assert stream_peaks(stream)[1, 3] == pytest.approx(2 * a / DT ** 2, rel=1e-9)


def test_raw_translation_jump_exceeds_the_limit():
    # A 4 mm jump of the commanded position: raw acceleration 0.004 / dt^2 = 14.4 m/s^2 > 13.
    pos, quat, q = _rest(10)
    pos[3:, 1] += 0.004
    peaks = stream_peaks(_stream(pos, quat, q))
    assert peaks[1, 0] == pytest.approx(14.4, rel=1e-9) and peaks[1, 0] > L.CARTESIAN_ACCELERATION


@pytest.fixture(scope="module")
def letter_env():
    env = calibration_env(LETTER)
    yield env
    env.close()


def test_measure_two_demos():
    cal = measure([LETTER, "clfd/BoxOpening-v3"], families=("demo",), demos=[0],
                  progress=False)
    assert [(r.env_id, r.demo, r.family) for r in cal.records] == [
        (LETTER, 0, "demo"), ("clfd/BoxOpening-v3", 0, "demo")]
    for r in cal.records:
        assert r.success and r.failure_reason is None
        assert r.steps == r.trajectory_steps + 60  # 1 s of settling at 60 Hz
        # The hand lags the command a little, far below the worst replay and the bound.
        assert 0 < r.tracking_position < L.TRACKING_MEASURED_POSITION < L.TRACKING_POSITION
        assert 0 < r.tracking_rotation < L.TRACKING_MEASURED_ROTATION < L.TRACKING_ROTATION
        assert r.collision_force == 0.0  # the pen and the lid touch the scene, the robot not
        assert r.raw_peaks.shape == (3, 9) and (r.raw_peaks[:, 0] < 0.5 * np.array(
            [L.CARTESIAN_VELOCITY, L.CARTESIAN_ACCELERATION, L.CARTESIAN_JERK])).all()
        assert r.rotation_peaks.shape == (5, 3) and r.joint_peaks.shape == (5, 3, 7)
        assert r.floor_height == 0.0 and r.lowest_height > 0.0
    box = cal.records[1]
    # BoxOpening's recorded orientation is sample-and-hold: raw, its acceleration is over the
    # limit; the input filter brings it down, the more the lower the cutoff.
    assert box.raw_peaks[1, 1] > L.ROTATION_ACCELERATION
    assert np.all(np.diff(box.rotation_peaks[:, 1]) < 0)
    assert box.rotation_peaks[-1, 1] < L.ROTATION_ACCELERATION
    d = cal.derive()
    assert d.tracking_position_measured.env_id == "clfd/BoxOpening-v3"
    assert d.tracking_position == L.TRACKING_FLOOR_POSITION  # 2 x ~1 mm < the 10 mm floor
    assert d.n_rollouts == d.n_successes == 2
    rows = {c.name: c for c in compare(cal)}
    assert rows["COLLISION_MEASURED_FORCE"].ok and rows["TRANSLATION_FILTER_HZ"].ok
    # Two easy demos do not reach the worst replay of the 822.
    assert not rows["TRACKING_MEASURED_POSITION"].ok
    assert {c.name for c in differences(cal)} <= set(rows)
    again = Calibration.from_json(cal.to_json())
    assert compare(again) == compare(cal)


def test_recorded_stream_replays_to_the_online_peaks(letter_env):
    traj = replay_trajectory(letter_env.unwrapped, 0, "demo")
    rec = measure_rollout(letter_env, traj, 0, LETTER, "demo")
    stream = letter_env.unwrapped.motion_monitor.stream()
    assert len(stream) == rec.steps
    # The monitor's own filter run offline over the recorded commands reproduces the env's
    # (raw) peaks and, at the grids' cutoffs, the rollout's filtered ones.
    np.testing.assert_allclose(stream_peaks(stream), rec.raw_peaks, rtol=1e-12)
    np.testing.assert_allclose(
        stream_peaks(stream, None, L.ROTATION_FILTER_GRID[2], L.JOINT_FILTER_GRID[1])[1, 1:],
        [rec.rotation_peaks[2, 1], *rec.joint_peaks[1, 1]], rtol=1e-12)


def test_injected_jump_breaks_the_raw_translation_limit(letter_env):
    base = letter_env.unwrapped
    traj = np.array(replay_trajectory(base, 0, "demo"))
    jumped = traj.copy()
    jumped[len(traj) // 2:, 0] += 0.01  # 1 cm (the letter's units are metres)
    rec = measure_rollout(letter_env, jumped, 0, LETTER, "jump")
    # One step moves the pen 1 cm: 0.6 m/s, 36 m/s^2 (the first difference of 0.01 / dt).
    assert rec.raw_peaks[1, 0] == pytest.approx(0.01 / DT ** 2, rel=0.05)
    assert rec.raw_peaks[1, 0] > L.CARTESIAN_ACCELERATION
    d = Calibration([rec]).derive()
    assert not d.translation_raw_passes
    assert d.translation_raw[1].ratio > 1.0
    assert not {c.name: c for c in compare(d)}["TRANSLATION_FILTER_HZ"].ok
    # The env with the Panda's limits refuses that command at the jump.
    import gymnasium as gym

    env = gym.make(LETTER)
    try:
        out = rollout(env, jumped, demo=0, settle_s=0.0)
    finally:
        env.close()
    assert not out.success
    assert out.info["failure"]["limit"] == "cartesian acceleration"
    assert out.info["failure"]["step"] == len(traj) // 2
