"""Trajectory error metrics: DTW, discrete Fréchet distance and swept area.

All three compare a predicted trajectory with a reference (demonstration) trajectory in
whatever length unit the arrays are given in; nothing is normalised. DTW and Fréchet scale
linearly with the length unit, the swept area quadratically (see
:mod:`clfd_bench.metrics.thresholds`).

DTW and Fréchet are dynamic programmes over the ``[T, T2]`` matrix of Euclidean point
distances, compiled with numba (:mod:`clfd_bench.metrics.warping`); the recursion is the
textbook one and its arithmetic is the cell-by-cell loop's, so the result equals that loop's to
the bit (tests).

Point-set metrics, which ignore the time order (:func:`hausdorff`, :func:`coverage`,
:func:`nearest_distances`), compare the shapes two trajectories draw; the writing envs use them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from clfd_bench.metrics.orientation import quaternion_error

__all__ = [
    "TRAJECTORY_METRICS",
    "coverage",
    "dtw",
    "dtw_batch",
    "frechet",
    "frechet_batch",
    "hausdorff",
    "nearest_distances",
    "self_crossings",
    "swept_area",
    "swept_area_batch",
    "trajectory_errors",
]

def _as_batch(a: np.ndarray, name: str) -> np.ndarray:
    """Check a batch of trajectories ``[B, T, D]`` and return it as float64."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[1] == 0 or arr.shape[2] == 0:
        raise ValueError(f"{name} must have shape [N, T, D] with T, D >= 1, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(
            f"{name} contains NaN or inf; a diverged prediction has no finite error, "
            "mark it as failed before computing metrics"
        )
    return arr


def _as_traj(a: np.ndarray, name: str) -> np.ndarray:
    """Check one trajectory ``[T, D]`` and return it as float64."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim != 2:
        raise ValueError(f"{name} must have shape [T, D], got shape {arr.shape}")
    return arr


def _check_pair(pred: np.ndarray, ref: np.ndarray) -> None:
    if pred.shape[0] != ref.shape[0] or pred.shape[2] != ref.shape[2]:
        raise ValueError(
            "pred and ref must hold the same number of trajectories N and the same point "
            f"dimension D, got pred {pred.shape} and ref {ref.shape}"
        )


def _warping(pred: np.ndarray, ref: np.ndarray, frechet: bool) -> np.ndarray:
    """:func:`clfd_bench.metrics.warping.warping_batch` on checked batches [B, n, D], [B, m, D]."""
    from clfd_bench.metrics.warping import warping_batch  # numba: imported on first use

    _check_pair(pred, ref)
    return warping_batch(np.ascontiguousarray(pred), np.ascontiguousarray(ref), frechet)


def dtw_batch(pred: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """DTW distance of each pair ``(pred[k], ref[k])``.

    Args:
        pred: ``[N, T, D]`` trajectories.
        ref: ``[N, T2, D]`` trajectories (``T2`` may differ from ``T``).

    Returns:
        ``[N]`` float64: see :func:`dtw`.
    """
    return _warping(_as_batch(pred, "pred"), _as_batch(ref, "ref"), False)


def frechet_batch(pred: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Discrete Fréchet distance of each pair ``(pred[k], ref[k])``.

    Args:
        pred: ``[N, T, D]`` trajectories.
        ref: ``[N, T2, D]`` trajectories.

    Returns:
        ``[N]`` float64: see :func:`frechet`.
    """
    return _warping(_as_batch(pred, "pred"), _as_batch(ref, "ref"), True)


def dtw(pred: np.ndarray, ref: np.ndarray) -> float:
    """Dynamic time warping distance between two trajectories.

    The sum of the Euclidean distances between matched points along the optimal warping
    path (steps ``(1, 0)``, ``(0, 1)``, ``(1, 1)``, from the first points to the last),
    un-normalised: it grows with trajectory length and linearly with the length unit.
    Symmetric in its arguments.

    Args:
        pred: ``[T, D]`` predicted trajectory.
        ref: ``[T2, D]`` reference trajectory.

    Returns:
        The DTW distance (0 for identical trajectories).
    """
    return float(dtw_batch(_as_traj(pred, "pred")[None], _as_traj(ref, "ref")[None])[0])


def frechet(pred: np.ndarray, ref: np.ndarray) -> float:
    """Discrete Fréchet distance between two trajectories.

    The smallest, over monotone couplings of the two point sequences (same steps as DTW),
    of the largest Euclidean distance between coupled points.

    Args:
        pred: ``[T, D]`` predicted trajectory.
        ref: ``[T2, D]`` reference trajectory.

    Returns:
        The discrete Fréchet distance (0 for identical trajectories).
    """
    return float(frechet_batch(_as_traj(pred, "pred")[None], _as_traj(ref, "ref")[None])[0])


def swept_area_batch(pred: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Swept area of each pair ``(pred[k], ref[k])``; see :func:`swept_area`.

    Args:
        pred: ``[N, T, D]`` with ``D`` 2 or 3.
        ref: ``[N, T, D]``, the same shape.

    Returns:
        ``[N]`` float64 areas.
    """
    p = _as_batch(pred, "pred")
    r = _as_batch(ref, "ref")
    if p.shape != r.shape:
        raise ValueError(
            "swept area pairs points by time step: pred and ref need the same shape, "
            f"got {p.shape} and {r.shape}"
        )
    if p.shape[2] not in (2, 3):
        raise ValueError(f"swept area needs 2-D or 3-D points, got D = {p.shape[2]}")
    # Quadrilateral (p_t, p_t+1, r_t+1, r_t): its vector area is half the cross product of
    # its diagonals, (r_t+1 - p_t) x (r_t - p_t+1).
    d1 = r[:, 1:] - p[:, :-1]
    d2 = r[:, :-1] - p[:, 1:]
    if p.shape[2] == 2:
        cross = np.abs(d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0])
    else:
        cross = np.linalg.norm(np.cross(d1, d2), axis=-1)
    return 0.5 * cross.sum(axis=1)


def swept_area(pred: np.ndarray, ref: np.ndarray) -> float:
    """Swept area error: the area between two trajectories of equal length.

    The sum over ``t = 0 .. T-2`` of the area of the quadrilateral
    ``(pred[t], pred[t+1], ref[t+1], ref[t])``. Each area is half the magnitude of the cross
    product of the quadrilateral's diagonals, which in 2-D is exactly the shoelace formula
    of the paper's released code (for a self-intersecting "bow tie" quadrilateral that is
    the difference of its two triangles, as there).

    3-D points: the magnitude of the quadrilateral's vector area. For a planar
    quadrilateral that is its area; for a non-planar one it is the largest area of its
    projection onto any plane, and it reduces to the 2-D formula when all points share a
    plane. (The released code would silently use x and y only.)

    Args:
        pred: ``[T, D]`` predicted trajectory, ``D`` 2 or 3.
        ref: ``[T, D]`` reference trajectory of the same shape.

    Returns:
        The swept area in squared length units.
    """
    return float(swept_area_batch(_as_traj(pred, "pred")[None], _as_traj(ref, "ref")[None])[0])


def nearest_distances(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance from every point of one point set to the nearest point of the other.

    Order-free (the points' time order plays no part); a k-d tree (``scipy.spatial``) keeps it
    ``O((N + M) log(N + M))``.

    Args:
        a: ``[N, D]`` points.
        b: ``[M, D]`` points.

    Returns:
        ``(d_ab [N], d_ba [M])``: ``d_ab[i] = min_j |a[i] - b[j]|`` and
        ``d_ba[j] = min_i |a[i] - b[j]|``.
    """
    from scipy.spatial import cKDTree

    pa = _as_traj(a, "a")
    pb = _as_traj(b, "b")
    if len(pa) == 0 or len(pb) == 0 or pa.shape[1] != pb.shape[1]:
        raise ValueError(f"need two non-empty point sets of the same dimension, got shapes "
                         f"{pa.shape} and {pb.shape}")
    d_ab = cKDTree(pb).query(pa, k=1)[0]
    d_ba = cKDTree(pa).query(pb, k=1)[0]
    return np.asarray(d_ab, dtype=float), np.asarray(d_ba, dtype=float)


def hausdorff(pred: np.ndarray, ref: np.ndarray) -> float:
    """Symmetric Hausdorff distance between the point sets of two trajectories.

    The largest distance from a point of either trajectory to the nearest point of the other:
    the worst two-sided deviation of the drawn shape, whatever the timing. Symmetric.

    Args:
        pred: ``[T, D]`` points.
        ref: ``[T2, D]`` points.

    Returns:
        The distance, in the arrays' length unit (0 for the same point set).
    """
    d_pr, d_rp = nearest_distances(pred, ref)
    return float(max(d_pr.max(), d_rp.max()))


def coverage(ref: np.ndarray, pred: np.ndarray, radius: float, by: str = "length",
             ref_distances: np.ndarray | None = None) -> float:
    """How much of a reference trajectory another one passes within ``radius`` of.

    Order-free, like :func:`hausdorff`. ``by="length"`` weighs the reference by arc length: the
    fraction of its polyline length whose segments have both end points within ``radius`` of
    some point of ``pred`` (time-sampled points would over-weigh where the reference is slow,
    e.g. a pen resting at its end point); a reference without length falls back to points.
    ``by="points"``: the fraction of the reference's points within ``radius``.

    Args:
        ref: ``[T, D]`` the trajectory to cover (e.g. the target).
        pred: ``[T2, D]`` the covering points (e.g. the ink).
        radius: in the arrays' length unit.
        by: ``"length"`` or ``"points"``.
        ref_distances: ``[T]`` the distances of ``ref``'s points to ``pred`` if already known
            (the second result of :func:`nearest_distances` ``(pred, ref)``); saves the search.

    Returns:
        A fraction in [0, 1].
    """
    if by not in ("length", "points"):
        raise ValueError(f"by must be 'length' or 'points', got {by!r}")
    r = _as_traj(ref, "ref")
    d_ref = nearest_distances(pred, r)[1] if ref_distances is None else ref_distances
    inside = d_ref <= radius
    if by == "length" and len(r) >= 2:
        seg = np.linalg.norm(np.diff(r, axis=0), axis=1)
        total = float(seg.sum())
        if total > 0:
            return float(seg[inside[1:] & inside[:-1]].sum() / total)
    return float(np.mean(inside))


def self_crossings(traj: np.ndarray, min_step: float = 0.0) -> int:
    """How often a planar trajectory crosses itself: the loops it draws.

    A time-invariant planar vector field (NODE^I on a 2-D dataset) cannot draw a crossing:
    two solution curves, or one curve and itself, never meet. A letter written with a loop
    ('e', 'd') crosses itself where the loop closes; a prediction that follows it without a
    time input can only come close. Counts proper crossings of two non-adjacent segments of
    the polyline (touching end points and collinear overlap do not count).

    Args:
        traj: ``[T, 2]`` points.
        min_step: points closer than this to the last kept point are dropped first, so that
            the jitter of a trajectory resting at its end does not count (arrays' length unit).

    Returns:
        The number of crossings.
    """
    p = _as_traj(traj, "traj")
    if p.shape[1] != 2:
        raise ValueError(f"self_crossings needs planar points [T, 2], got shape {p.shape}")
    if min_step < 0:
        raise ValueError(f"min_step must be >= 0, got {min_step}")
    keep = [0]
    for i in range(1, len(p)):
        if np.linalg.norm(p[i] - p[keep[-1]]) > min_step:
            keep.append(i)
    p = p[keep]
    if len(p) < 4:
        return 0
    a, b = p[:-1], p[1:]
    d = b - a

    def side(origin: np.ndarray, direction: np.ndarray, q: np.ndarray) -> np.ndarray:
        rel = q[None, :, :] - origin[:, None, :]
        return direction[:, None, 0] * rel[..., 1] - direction[:, None, 1] * rel[..., 0]

    # [n, n]: where segment j's end points lie relative to segment i's line, and back.
    s_a, s_b = side(a, d, a), side(a, d, b)
    crosses = (s_a * s_b < 0) & (s_a.T * s_b.T < 0)
    return int(np.triu(crosses, k=2).sum())


def _quaternion_batch(pred: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.array([quaternion_error(p, r, degrees=True) for p, r in zip(pred, ref, strict=True)])


TRAJECTORY_METRICS: dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]] = {
    "dtw": dtw_batch,
    "frechet": frechet_batch,
    "swept_area": swept_area_batch,
    "quaternion": _quaternion_batch,
}
"""Batched metric functions ``f(pred [N, T, D], ref [N, T, D]) -> [N]`` by name.
``quaternion`` takes ``D = 4`` (w, x, y, z) and returns degrees."""


def trajectory_errors(
    pred: np.ndarray,
    ref: np.ndarray,
    metrics: Sequence[str] = ("dtw", "frechet", "swept_area"),
) -> dict[str, np.ndarray]:
    """Several metrics for a batch of (prediction, demonstration) pairs.

    Args:
        pred: ``[N, T, D]`` predicted trajectories.
        ref: ``[N, T, D]`` reference trajectories, paired with ``pred`` by index.
        metrics: names from :data:`TRAJECTORY_METRICS`.

    Returns:
        ``{name: [N] float64 errors}`` in the order of ``metrics``.
    """
    if isinstance(metrics, str):
        metrics = (metrics,)
    unknown = [m for m in metrics if m not in TRAJECTORY_METRICS]
    if unknown:
        raise ValueError(
            f"unknown trajectory metric(s) {unknown}; valid: {sorted(TRAJECTORY_METRICS)}"
        )
    p = _as_batch(pred, "pred")
    r = _as_batch(ref, "ref")
    _check_pair(p, r)
    return {name: TRAJECTORY_METRICS[name](p, r) for name in metrics}
