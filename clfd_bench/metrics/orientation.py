"""Orientation error between two quaternion trajectories (the paper's E_q).

The paper (Sec. "Trajectory Metrics") defines, for a ground-truth trajectory ``q_t`` and a
prediction ``q̂_t`` of ``T`` unit quaternions,

    e_q(q_t, q̂_t) = 2 Log(q_t * conj(q̂_t))  in R^3,
    E_q = 1 / (3T) * sum_t || e_q(q_t, q̂_t) ||_1,

i.e. the mean absolute component of the rotation vector of the relative rotation
``q_t * conj(q̂_t)`` (world frame), averaged over the three axes; the 10 degree accuracy
threshold is on this value. (The authors' released code computes a different quantity, the
mean L2 norm of the half-angle vector; this module implements the paper's formula.)

Which ``Log``: the paper's ``Log(q) = arccos(w) u / |u|`` maps a quaternion with negative
scalar part ``w`` to the "long way round" (rotation angle ``2 arccos(w) > pi``), and jumps to 0
at exactly ``-1``; the paper assumes that case away. Here ``2 Log`` is MuJoCo's
``mju_subQuat`` (``mju_quat2Vel``), the shortest rotation vector (angle in ``[0, pi]``). The two
agree whenever the scalar part of ``q_t * conj(q̂_t)`` is >= 0, i.e. whenever the quaternions
lie in the same hemisphere; unlike the literal formula, this one is the same for ``q̂`` and
``-q̂`` (which describe the same orientation), so sign flips in a prediction cost nothing.

Quaternions are scalar first, ``(w, x, y, z)``. They need not be exactly unit: the rotation
vector depends only on the direction of ``q_t * conj(q̂_t)``.

Vectorisation: MuJoCo's quaternion functions take one quaternion per call, so the product
and log run in a Python loop over time steps (about 1.3 ms per 1000 steps); only the
conjugation (a sign flip) and the reduction are numpy array operations.
"""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["quaternion_error", "rotation_vectors"]

_CONJ = np.array([1.0, -1.0, -1.0, -1.0])


def _as_quats(q: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(q, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 4 or arr.shape[0] == 0:
        raise ValueError(f"{name} must have shape [T, 4] (w, x, y, z) with T >= 1, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf")
    if np.any(np.linalg.norm(arr, axis=1) < 1e-12):
        raise ValueError(f"{name} contains a zero quaternion; quaternions must be non-zero")
    return arr


def rotation_vectors(ref_q: np.ndarray, pred_q: np.ndarray) -> np.ndarray:
    """Per-step error vectors ``e_q(q_t, q̂_t) = 2 Log(q_t * conj(q̂_t))`` (shortest arc).

    Args:
        ref_q: ``[T, 4]`` ground-truth quaternions ``q_t`` (w, x, y, z).
        pred_q: ``[T, 4]`` predicted quaternions ``q̂_t``.

    Returns:
        ``[T, 3]`` rotation vectors in radians (norm = rotation angle in ``[0, pi]``).
    """
    ref = _as_quats(ref_q, "ref_q")
    pred = _as_quats(pred_q, "pred_q")
    if ref.shape != pred.shape:
        raise ValueError(
            f"ref_q and pred_q must have the same shape, got {ref.shape} and {pred.shape}"
        )
    # mju_subQuat(res, qa, qb) solves qb * quat(res) = qa, i.e. res = 2 Log(conj(qb) * qa).
    # With qa = conj(q̂_t) and qb = conj(q_t): conj(qb) * qa = q_t * conj(q̂_t).
    qa = pred * _CONJ
    qb = ref * _CONJ
    out = np.empty((ref.shape[0], 3))
    for res, a, b in zip(out, qa, qb, strict=True):
        mujoco.mju_subQuat(res, a, b)
    return out


def quaternion_error(pred_q: np.ndarray, ref_q: np.ndarray, degrees: bool = True) -> float:
    """The paper's orientation error ``E_q = 1/(3T) sum_t |2 Log(q_t * conj(q̂_t))|_1``.

    Args:
        pred_q: ``[T, 4]`` predicted quaternions ``q̂_t`` (w, x, y, z).
        ref_q: ``[T, 4]`` ground-truth quaternions ``q_t``.
        degrees: return degrees (the unit of the paper's 10 degree threshold) instead of
            radians.

    Returns:
        ``E_q``: the mean absolute rotation-vector component over steps and axes.
    """
    vecs = rotation_vectors(ref_q, pred_q)
    err = float(np.abs(vecs).sum() / (3 * vecs.shape[0]))
    return float(np.degrees(err)) if degrees else err
