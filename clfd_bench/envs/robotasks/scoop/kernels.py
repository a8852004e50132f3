"""Compiled (numba) point-in-box tests of the Scoop scene's grain sweep.

The sweep runs every control step the bowl is in the beans, on a few hundred grain sites; as
numpy it was a dozen small array operations per step (each ~1-2 µs of overhead on [K, 3]).
Here it is one pass over the sites. Comparisons only, so the masks are exactly those of the
numpy expressions they replace (`tests/test_scoop.py` compares them); the sites' scoop-frame
coordinates are still computed by numpy (`@`), whose rounding (BLAS, fused multiply-adds) a
loop here would not reproduce.

A box is [2, 3]: its low and high corner; a point is in it when low <= p <= high on every axis
(the faces included).
"""

from __future__ import annotations

import numpy as np

from clfd_bench.compiled import njit


@njit(nogil=True)
def _within(x: float, y: float, z: float, box: np.ndarray) -> bool:
    """Whether the point (x, y, z) lies in `box` (branch-free: `&`, not `and`)."""
    return ((box[0, 0] <= x) & (x <= box[1, 0]) & (box[0, 1] <= y) & (y <= box[1, 1])
            & (box[0, 2] <= z) & (z <= box[1, 2]))


@njit(nogil=True)
def in_box(points: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Whether each point of `points` [K, 3] lies in `box` [2, 3]: bool [K]."""
    out = np.empty(points.shape[0], dtype=np.bool_)
    for k in range(points.shape[0]):
        out[k] = _within(points[k, 0], points[k, 1], points[k, 2], box)
    return out


@njit(nogil=True)
def classify(local: np.ndarray, outer: np.ndarray, cavity: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, int, int, int]:
    """The sites `local` [K, 3] (scoop frame) against the bowl's outside box `outer` [2, 3] and
    its cavity `cavity` [2, 3].

    Returns:
        (inside [K]: in the cavity, solid [K]: in the outside box but not the cavity, and the
         numbers of sites in the outside box, in the cavity, solid).
    """
    n = local.shape[0]
    inside = np.empty(n, dtype=np.bool_)
    solid = np.empty(n, dtype=np.bool_)
    n_outer = n_inside = n_solid = 0
    for k in range(n):
        x, y, z = local[k, 0], local[k, 1], local[k, 2]
        o = _within(x, y, z, outer)
        c = _within(x, y, z, cavity)
        s = o & (not c)
        inside[k] = c
        solid[k] = s
        n_outer += o
        n_inside += c
        n_solid += s
    return inside, solid, n_outer, n_inside, n_solid


@njit(nogil=True)
def entered(inside: np.ndarray, solid: np.ndarray, prev: np.ndarray, cavity: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The sites in the cavity now (`inside` [K]) that were not at the previous pose (`prev`
    [K, 3], scoop frame then), and those taken: `solid` [K] or entered.

    Returns:
        (entered [K], gone [K] = solid | entered, their numbers).
    """
    n = inside.shape[0]
    new = np.empty(n, dtype=np.bool_)
    gone = np.empty(n, dtype=np.bool_)
    n_new = n_gone = 0
    for k in range(n):
        e = inside[k] & (not _within(prev[k, 0], prev[k, 1], prev[k, 2], cavity))
        g = solid[k] | e
        new[k] = e
        gone[k] = g
        n_new += e
        n_gone += g
    return new, gone, n_new, n_gone
