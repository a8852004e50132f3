"""The dynamic programme of DTW and the discrete Fréchet distance, compiled (numba).

``D[i, j] = combine(c[i, j], min(D[i-1, j], D[i, j-1], D[i-1, j-1]))`` with
``c[i, j] = |pred[i] - ref[j]|`` (Euclidean), ``D[0, 0] = c[0, 0]``, cells outside the matrix
``inf``; ``combine`` is ``+`` (DTW) or ``max`` (Fréchet). Row by row, in two rows of ``m + 1``
values. Every cell is the textbook loop's arithmetic: the squared differences summed in
coordinate order from 0, one square root, one exact minimum, one ``+`` or ``max``, so the result
equals the plain Python loop's to the bit, whatever order the cells are visited in (minimum and
maximum are exact; ``tests/test_metrics_trajectory.py``). Compiled without fast-math, so no
reassociation or fused multiply-add changes a rounding.

Compiled on first use and cached on disk (:mod:`clfd_bench.compiled`). Imported lazily by
:mod:`clfd_bench.metrics.trajectory`, so importing the package does not import numba.
"""

from __future__ import annotations

import math

import numpy as np

from clfd_bench.compiled import njit


@njit(nogil=True)
def _pair(pred: np.ndarray, ref: np.ndarray, frechet: bool, prev: np.ndarray,
          cur: np.ndarray) -> float:
    """``D[n-1, m-1]`` of one pair: ``pred`` [n, D], ``ref`` [m, D]; ``prev``, ``cur`` [m + 1]
    scratch rows (index ``j + 1`` holds column ``j``; index 0 is the ``j = -1`` border)."""
    n, dim = pred.shape
    m = ref.shape[0]
    # Row i = -1: inf, except a 0 at its border so that D[0, 0] = combine(c, 0) = c exactly
    # (c + 0 = c and max(c, 0) = c for c >= 0); from row 0 on, the border is inf.
    prev[0] = 0.0
    prev[1:] = np.inf
    cur[0] = np.inf
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for k in range(dim):
                t = ref[j, k] - pred[i, k]
                acc += t * t
            c = math.sqrt(acc)
            best = min(prev[j + 1], prev[j], cur[j])
            cur[j + 1] = max(c, best) if frechet else c + best
        prev, cur = cur, prev
        cur[0] = np.inf
    return prev[m]


@njit(nogil=True)
def warping_batch(pred: np.ndarray, ref: np.ndarray, frechet: bool) -> np.ndarray:
    """DTW (``frechet=False``) or discrete Fréchet distance of each pair.

    Args:
        pred: ``[B, n, D]`` float64, finite.
        ref: ``[B, m, D]`` float64, finite.
        frechet: False for DTW, True for Fréchet.

    Returns:
        ``[B]`` float64 ``D[n-1, m-1]`` per pair.
    """
    b = pred.shape[0]
    m = ref.shape[1]
    out = np.empty(b)
    prev = np.empty(m + 1)
    cur = np.empty(m + 1)
    for k in range(b):
        out[k] = _pair(pred[k], ref[k], frechet, prev, cur)
    return out
