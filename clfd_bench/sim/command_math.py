"""The arithmetic of the reflex checks (`clfd_bench.sim.limits.MotionMonitor`), written once for
one control step and for a whole command stream at once.

A command's channels are 13 numbers per step: the increment of the commanded position (3, m),
of the orientation (3, a rotation vector in the world frame, rad) and of the joint reference
(7, rad). They pass an input filter (cascaded first-order low-passes, libfranka's
`lowpassFilter` formula), then finite differences at the control rate give velocity,
acceleration and jerk, whose norms (translation, rotation) or absolute values (joints) are
compared with the limits.

Every function here uses elementwise numpy operations only (no matrix products, whose summation
order and fused multiply-adds depend on the BLAS build and the CPU), so the same formula gives
the same bits for one step (`MotionMonitor.check_command`) and for a stream of steps
(`MotionMonitor.check_stream`): the two paths agree to the last bit, on any machine.
"""

from __future__ import annotations

import mujoco
import numpy as np

#: Channels of a command increment: translation (3), rotation (3), joints (7).
CHANNELS = 13
#: Limit groups: translation norm, rotation norm, joints 1..7.
GROUPS = 9


def filter_step(stages: np.ndarray, x: np.ndarray, gain: np.ndarray,
                tmp: np.ndarray) -> np.ndarray:
    """Advances the cascaded low-passes by one sample, in place: each stage s += gain (x - s),
    x then the stage's output.

    Args:
        stages: [S, 13] each stage's output at the previous sample (updated).
        x: [13] this sample's input.
        gain: [13] libfranka's filter gain per channel (1: no filtering).
        tmp: [13] a work array.

    Returns:
        [13] the last stage's output (a view of `stages[-1]`).
    """
    for st in stages:
        np.subtract(x, st, out=tmp)
        np.multiply(gain, tmp, out=tmp)
        np.add(st, tmp, out=st)
        x = st
    return x


def filter_stream(x: np.ndarray, gain: np.ndarray, stages0: np.ndarray) -> np.ndarray:
    """`filter_step` over a stream: the stage outputs after every sample.

    Args:
        x: [T, 13] inputs.
        gain: [13].
        stages0: [S, 13] the stages before the first sample.

    Returns:
        [T, S, 13] the stages after each sample (the filtered signal is [:, -1]).
    """
    out = np.empty((len(x), len(stages0), x.shape[1]))
    stages = stages0.copy()
    tmp = np.empty(x.shape[1])
    for t in range(len(x)):
        filter_step(stages, x[t], gain, tmp)
        out[t] = stages
    return out


def velocity(x: np.ndarray, rate: float) -> np.ndarray:
    """Velocity [..., 13] of a filtered command from its increment `x` [..., 13]: r x."""
    return rate * x


def acceleration(x: np.ndarray, v_prev: np.ndarray, rate: float) -> np.ndarray:
    """Acceleration [..., 13] from the increment and the previous step's velocity:
    r (r x - v_prev), as r² x - r v_prev."""
    return (rate * rate) * x - rate * v_prev


def jerk(x: np.ndarray, v_prev: np.ndarray, a_prev: np.ndarray, rate: float) -> np.ndarray:
    """Jerk [..., 13] from the increment and the previous step's velocity and acceleration:
    r (a - a_prev), as r³ x - r² v_prev - r a_prev."""
    return (rate * rate * rate) * x - (rate * rate) * v_prev - rate * a_prev


def group_norms2(d: np.ndarray) -> np.ndarray:
    """Squared magnitudes per limit group: [..., 13] -> [..., 9] (translation |d[0:3]|²,
    rotation |d[3:6]|², joints d[6:13]²)."""
    s = d * d
    out = np.empty(d.shape[:-1] + (GROUPS,))
    out[..., 0] = s[..., 0] + s[..., 1] + s[..., 2]
    out[..., 1] = s[..., 3] + s[..., 4] + s[..., 5]
    out[..., 2:] = s[..., 6:]
    return out


def rotation_increment(out: np.ndarray, quat: np.ndarray, prev: np.ndarray,
                       scratch: np.ndarray) -> None:
    """The rotation from `prev` to `quat` (unit quaternions [4], w,x,y,z) as a rotation vector
    in the world frame, written into `out` [3] (MuJoCo's `mju_subQuat`, in `prev`'s frame,
    rotated by `prev`). `scratch` is a [3] work array."""
    mujoco.mju_subQuat(scratch, quat, prev)
    mujoco.mju_rotVecQuat(out, scratch, prev)


def stream_increments(pos: np.ndarray, quat: np.ndarray, q: np.ndarray, pos0: np.ndarray,
                      quat0: np.ndarray, q0: np.ndarray) -> np.ndarray:
    """Increments [T, 13] of a command stream from the pose and joints before it.

    Args:
        pos: [T, 3], quat: [T, 4] (unit), q: [T, 7] the commands.
        pos0, quat0, q0: the command (or the robot's pose) before the first.
    """
    n = len(pos)
    du = np.empty((n, CHANNELS))
    prev_pos = np.concatenate([pos0[None], pos[:-1]])
    np.subtract(pos, prev_pos, out=du[:, 0:3])
    prev_q = np.concatenate([q0[None], q[:-1]])
    np.subtract(q, prev_q, out=du[:, 6:13])
    scratch = np.empty(3)
    prev = quat0
    for t in range(n):
        rotation_increment(du[t, 3:6], quat[t], prev, scratch)
        prev = quat[t]
    return du
