"""Orientation trajectories in the tangent space of the goal orientation.

The paper (Sec. "Learning Orientation Trajectories", after Ude et al. 2014) learns unit
quaternion trajectories as Euclidean trajectories of tangent vectors relative to the final
orientation ``q_g`` and maps predictions back:

    r_t = Log(conj(q_g) * q_t)          q_t = q_g * Exp(r_t)

with the quaternion logarithm ``Log(q) = arccos(w) u/|u|`` (half the rotation angle) and
``Exp(r) = [cos|r|, sin|r| r/|r|]``. (The paper's Eq. for ``r_t`` writes the product the
other way round, ``conj(q_t) * q_g``; that is ``-r_t`` for ``Log`` and does not invert with
its ``Exp`` equation. The form here is the one that round-trips and is what the original
code computes.) ``Log`` takes the shortest arc, so ``q`` and ``-q`` map to the same vector.

The group operations are mink's :class:`mink.SO3` (MuJoCo's ``mju_*`` underneath): its
``log`` returns the rotation vector (the full angle), so ``Log = SO3.log / 2`` and
``Exp(r) = SO3.exp(2 r)``.
"""

from __future__ import annotations

import numpy as np
from mink import SO3

__all__ = ["quat_exp_relative", "quat_log_relative"]


def _broadcast_goals(goal: np.ndarray, lead: tuple[int, ...]) -> np.ndarray:
    goal = np.asarray(goal, dtype=np.float64)
    if goal.shape[-1] != 4:
        raise ValueError(f"goal quaternions must end in 4 (w, x, y, z), got {goal.shape}")
    if goal.ndim == 1:
        return np.broadcast_to(goal, (*lead, 4))
    # one goal per trajectory: [N, 4] for data [N, T, ...]
    extra = len(lead) - (goal.ndim - 1)
    if extra < 0 or goal.shape[:-1] != lead[: goal.ndim - 1]:
        raise ValueError(f"goals of shape {goal.shape} do not match data of shape {lead}")
    return np.broadcast_to(goal.reshape(*goal.shape[:-1], *([1] * extra), 4), (*lead, 4))


def quat_log_relative(quats: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Tangent vectors ``r = Log(conj(q_g) * q)``.

    Args:
        quats: ``[..., 4]`` unit quaternions (w, x, y, z), e.g. ``[N, T, 4]``.
        goal: ``[4]`` one goal for all, or ``[N, 4]`` one goal per trajectory.

    Returns:
        ``[..., 3]`` tangent vectors (half-angle units, ``|r| <= pi/2``).
    """
    q = np.asarray(quats, dtype=np.float64)
    if q.shape[-1] != 4:
        raise ValueError(f"quaternions must end in 4 (w, x, y, z), got shape {q.shape}")
    goals = _broadcast_goals(goal, q.shape[:-1]).reshape(-1, 4)
    flat = q.reshape(-1, 4)
    out = np.empty((flat.shape[0], 3))
    cache: dict[bytes, SO3] = {}
    for k in range(flat.shape[0]):
        key = goals[k].tobytes()
        inv = cache.get(key)
        if inv is None:
            inv = cache[key] = SO3(wxyz=np.array(goals[k])).normalize().inverse()
        out[k] = 0.5 * (inv @ SO3(wxyz=np.array(flat[k])).normalize()).log()
    return out.reshape(*q.shape[:-1], 3)


def quat_exp_relative(tangent: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Quaternions ``q = q_g * Exp(r)`` from tangent vectors.

    Args:
        tangent: ``[..., 3]`` tangent vectors, e.g. ``[N, T, 3]``.
        goal: ``[4]`` or ``[N, 4]`` goal quaternions (w, x, y, z).

    Returns:
        ``[..., 4]`` unit quaternions (w, x, y, z).
    """
    r = np.asarray(tangent, dtype=np.float64)
    if r.shape[-1] != 3:
        raise ValueError(f"tangent vectors must end in 3, got shape {r.shape}")
    goals = _broadcast_goals(goal, r.shape[:-1]).reshape(-1, 4)
    flat = r.reshape(-1, 3)
    out = np.empty((flat.shape[0], 4))
    cache: dict[bytes, SO3] = {}
    for k in range(flat.shape[0]):
        key = goals[k].tobytes()
        g = cache.get(key)
        if g is None:
            g = cache[key] = SO3(wxyz=np.array(goals[k])).normalize()
        out[k] = (g @ SO3.exp(2.0 * flat[k])).wxyz
    return out.reshape(*r.shape[:-1], 4)
