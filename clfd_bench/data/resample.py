"""Time operations on trajectories in data units: resampling (positions linearly, the
quaternions of 7-D poses by slerp) and the minimum-jerk profile. Used by the envs (the text's
pen moves, the RoboTasks derivations) and the execution layer (perturbation families)."""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["min_jerk_profile", "resample", "slerp"]


def min_jerk_profile(s: np.ndarray) -> np.ndarray:
    """The minimum-jerk profile 10s³ − 15s⁴ + 6s⁵ at phases `s` [n] in [0, 1] (0 → 0, 1 → 1,
    zero velocity and acceleration at both ends). Returns [n]."""
    s = np.asarray(s, dtype=float)
    return s ** 3 * (10 - 15 * s + 6 * s * s)


def slerp(q0: np.ndarray, q1: np.ndarray, a: float) -> np.ndarray:
    """Unit quaternion `a` of the way from `q0` [4] to `q1` [4] (w, x, y, z), along the
    rotation MuJoCo's quaternion maps give (`mju_subQuat`, then `mju_quatIntegrate`)."""
    v = np.empty(3)
    mujoco.mju_subQuat(v, q1, q0)  # rotation q0 -> q1 as a 3-vector in q0's frame
    q = np.array(q0, dtype=float)
    mujoco.mju_quatIntegrate(q, v, float(a))
    return q / np.linalg.norm(q)


def resample(traj: np.ndarray, n: int) -> np.ndarray:
    """`traj` [T, D] resampled to `n` samples at evenly spaced times (positions linearly,
    quaternions of 7-D poses by slerp). Returns [n, D]."""
    traj = np.asarray(traj, dtype=float)
    T = len(traj)
    s = np.linspace(0.0, T - 1.0, int(n))
    i0 = np.clip(np.floor(s).astype(int), 0, T - 1)
    i1 = np.minimum(i0 + 1, T - 1)
    a = s - i0
    out = traj[i0] + a[:, None] * (traj[i1] - traj[i0])
    if traj.shape[1] == 7:
        out[:, 3:] = [slerp(traj[k0, 3:], traj[k1, 3:], w)
                      for k0, k1, w in zip(i0, i1, a, strict=True)]
    return out
