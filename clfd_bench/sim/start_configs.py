"""Start joint configurations from which each demonstration can be tracked.

From the `home` keyframe, IK tracking of some RoboTasks demos (openbox) drifts into a branch that
ends far off. All demos of a task end at one common pose, so (see docs/data.md, "Frames and start
configurations"): solve one goal configuration for that end pose, track each demo *backward*
from it, and use where the backward tracking ends as that demo's start configuration. Tracking
forward from there follows the demo.
"""

from __future__ import annotations

import numpy as np

from clfd_bench.sim.ik import PoseTracker
from clfd_bench.sim.robot import HOME_QPOS

#: Tracker settings of the offline procedure (docs/data.md: 8 iterations per sample, dt 0.01).
OFFLINE_ITERATIONS = 8
OFFLINE_DT = 0.01
OFFLINE_POSTURE_COST = 1e-3


def _check_shapes(positions: np.ndarray, quaternions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    positions = np.asarray(positions, dtype=float)
    quaternions = np.asarray(quaternions, dtype=float)
    if positions.ndim == 2:
        positions = positions[None]
    if quaternions.ndim == 2:
        quaternions = quaternions[None]
    if positions.ndim != 3 or positions.shape[-1] != 3:
        raise ValueError(f"positions must have shape [N, T, 3] (metres), got {positions.shape}")
    if quaternions.shape != positions.shape[:2] + (4,):
        raise ValueError(f"quaternions must have shape {positions.shape[:2] + (4,)} (w, x, y, z), "
                         f"got {quaternions.shape}")
    return positions, quaternions


def make_offline_tracker(model, frame: str = "hand", frame_type: str = "body") -> PoseTracker:
    """The tracker the offline procedures use (8 QP iterations per sample, dt 0.01 s)."""
    return PoseTracker(model, frame=frame, frame_type=frame_type,
                       posture_cost=OFFLINE_POSTURE_COST, iterations=OFFLINE_ITERATIONS,
                       dt=OFFLINE_DT)


def solve_configuration(model, position: np.ndarray, quaternion: np.ndarray,
                        initial_q: np.ndarray | None = None, frame: str = "hand",
                        frame_type: str = "body") -> tuple[np.ndarray, float, float]:
    """IK for one static pose, starting from `initial_q` [7] (default `home`).

    Returns:
        (q [7], position error m, rotation error rad).
    """
    tracker = make_offline_tracker(model, frame, frame_type)
    tracker.reset(HOME_QPOS if initial_q is None else initial_q)
    return tracker.solve(position, quaternion)


def backward_start_configs(model, positions: np.ndarray, quaternions: np.ndarray,
                           goal_q: np.ndarray | None = None, frame: str = "hand",
                           frame_type: str = "body") -> np.ndarray:
    """Start configurations by backward tracking from one goal configuration.

    Args:
        model: robot model (e.g. `clfd_bench.sim.robot.robot_model()`).
        positions: [N, T, 3] frame positions in metres (base frame).
        quaternions: [N, T, 4] frame orientations (w, x, y, z).
        goal_q: [7] configuration at the common end pose; default: solved by IK from `home`
            for demo 0's last pose.
        frame, frame_type: the frame the poses describe (default the `hand` body).

    Returns:
        [N, 7] arm configurations: where backward tracking of each demo ends (its t = 0 pose).
    """
    positions, quaternions = _check_shapes(positions, quaternions)
    if goal_q is None:
        goal_q, _, _ = solve_configuration(model, positions[0, -1], quaternions[0, -1],
                                           frame=frame, frame_type=frame_type)
    goal_q = np.asarray(goal_q, dtype=float)
    tracker = make_offline_tracker(model, frame, frame_type)
    starts = np.empty((positions.shape[0], 7))
    for n in range(positions.shape[0]):
        tracker.reset(goal_q)
        # Each demo's own end orientation may differ slightly from demo 0's: converge first.
        tracker.solve(positions[n, -1], quaternions[n, -1])
        for t in range(positions.shape[1] - 1, -1, -1):
            tracker.track(positions[n, t], quaternions[n, t])
        starts[n] = tracker.q
    return starts


def tracking_errors(model, start_q: np.ndarray, positions: np.ndarray, quaternions: np.ndarray,
                    tracker: PoseTracker | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Kinematic forward tracking of one demo from `start_q` [7] (no physics).

    Args:
        positions: [T, 3] m; quaternions: [T, 4] w, x, y, z.
        tracker: the tracker to use (default: the offline one).

    Returns:
        (position errors [T] m, rotation errors [T] rad) of the IK solution at each sample.
    """
    tracker = tracker or make_offline_tracker(model)
    tracker.reset(start_q)
    pos_err = np.empty(len(positions))
    rot_err = np.empty(len(positions))
    for t in range(len(positions)):
        _, pos_err[t], rot_err[t] = tracker.track(positions[t], quaternions[t])
    return pos_err, rot_err
