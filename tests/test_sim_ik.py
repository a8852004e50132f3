"""mink pose tracking: bad input, unreachable targets, tracking a HelloWorld demo."""

from __future__ import annotations

import numpy as np
import pytest

from clfd_bench.data import load_dataset
from clfd_bench.envs.writing import load_writing_spec
from clfd_bench.sim.ik import PoseTracker, quat_angle
from clfd_bench.sim.robot import HOME_QPOS, PEN_TIP_OFFSET, hand_pose, robot_model

DOWN = np.array([0.0, 0.7071068, 0.7071068, 0.0])


@pytest.fixture(scope="module")
def tracker():
    return PoseTracker(robot_model("pen"))


def test_nan_target_raises_naming_the_entries(tracker):
    tracker.reset(HOME_QPOS)
    with pytest.raises(ValueError, match=r"target position has non-finite .* indices \[1\]"):
        tracker.track(np.array([0.4, np.nan, 0.3]), DOWN)
    with pytest.raises(ValueError, match=r"target quaternion .* indices \[0, 3\]"):
        tracker.track(np.array([0.4, 0.0, 0.3]), np.array([np.inf, 0, 1, np.nan]))


def test_bad_frame_and_shapes_are_rejected():
    with pytest.raises(ValueError, match="no body named 'flange'"):
        PoseTracker(robot_model(), frame="flange")
    with pytest.raises(ValueError, match="shape"):
        PoseTracker(robot_model()).reset(np.zeros(3))


def test_unreachable_target_is_tracked_as_close_as_possible(tracker):
    tracker.reset(HOME_QPOS)
    target = np.array([2.0, 0.0, 0.5])  # 2 m away: far outside the workspace
    for _ in range(300):
        q, pos_err, rot_err = tracker.track(target, DOWN)
    assert np.all(np.isfinite(q))
    lo, hi = tracker.index.arm_range[:, 0], tracker.index.arm_range[:, 1]
    assert np.all(q >= lo - 1e-6) and np.all(q <= hi + 1e-6)
    hand, _ = hand_pose(robot_model("pen"), q)
    # The reported error is the true residual and the arm reached out towards the target.
    assert pos_err == pytest.approx(np.linalg.norm(hand - target), abs=1e-9)
    assert 1.0 < pos_err < 1.5 and hand[0] > 0.7


def test_tracks_a_helloworld_demo_within_tolerance(tracker):
    spec = load_writing_spec()
    demo = load_dataset("helloworld").tasks[0].demos[0]  # 'h', metres, base frame
    z = spec.surface_height + PEN_TIP_OFFSET
    targets = np.column_stack([demo, np.full(len(demo), z)])
    q0, err0, _ = tracker.solve(targets[0], DOWN)
    assert err0 < 1e-4
    tracker.reset(q0)
    errs = np.array([tracker.track(p, DOWN)[1:] for p in targets])
    assert errs[:, 0].max() < 5e-4  # 0.5 mm
    assert errs[:, 1].max() < 2e-3  # 0.1 degree


def test_quat_angle():
    assert quat_angle(DOWN, -DOWN) == pytest.approx(0.0, abs=1e-7)
    q90 = np.array([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])
    assert quat_angle(np.array([1.0, 0, 0, 0]), q90) == pytest.approx(np.pi / 2)


@pytest.mark.parametrize("tool", [None, "pen"])
def test_tracking_qp_is_minks_problem_to_the_last_bit(tool):
    """The tracker's preassembled QP equals `mink.build_ik`'s for its tasks and limits, at
    random configurations (inside and outside the joint range) and random targets."""
    import mink

    t = PoseTracker(robot_model(tool), posture_gain=0.1)
    assert t._qp is not None
    rng = np.random.default_rng(0)
    lo, hi = t.index.arm_range[:, 0], t.index.arm_range[:, 1]
    for k in range(25):
        q = rng.uniform(lo - 0.05, hi + 0.05)
        t.reset(np.clip(q, lo, hi), posture=rng.uniform(lo, hi))
        t.configuration.data.qpos[t.index.arm_qpos] = q  # also beyond a limit
        t.configuration.update()
        t.set_target(rng.uniform([0.2, -0.5, 0.0], [0.7, 0.5, 0.8]), rng.normal(size=4))
        dt = (1 / 60, 0.05)[k % 2]
        H, c, G, h = t._qp.problem(dt)
        ref = mink.build_ik(t.configuration, t.tasks, dt, 1e-12, t.limits)
        for ours, theirs in ((H, ref.P), (c, ref.q), (G, ref.G), (h, ref.h)):
            assert ours.shape == theirs.shape
            assert np.array_equal(ours, theirs)


def test_tracking_qp_solution_matches_mink_solve_ik():
    """Tracking a demo with the preassembled QP gives mink.solve_ik's joint trajectory."""
    ds = load_dataset("robotasks")
    demo = ds.tasks[0].demos[0][::10]
    fast = PoseTracker(robot_model(None))
    slow = PoseTracker(robot_model(None), solver="daqp")
    slow._qp = None  # the generic path: mink.solve_ik through qpsolvers
    for tr in (fast, slow):
        tr.solve(demo[0, :3], demo[0, 3:])
    for pose in demo:
        qa, _, _ = fast.track(pose[:3], pose[3:])
        qb, _, _ = slow.track(pose[:3], pose[3:])
        np.testing.assert_allclose(qa, qb, atol=1e-9)
