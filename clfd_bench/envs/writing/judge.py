"""How the writing envs judge the ink, as an observer would: `judge_shape`, a pure function of
the ink, the pen's path, the target and the task's tolerances (the paper's summed DTW, plus the
shape, the end point and the timing)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from clfd_bench.envs.checks import Check, failed_checks
from clfd_bench.envs.writing.spec import ShapeTolerances


def ink_strokes(pen_down: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the runs of True in `pen_down` [T]."""
    d = np.diff(np.concatenate([[0], pen_down.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(),
                    strict=True))


def dwell_fraction(path: np.ndarray, radius: float) -> float:
    """Fraction of the pen positions `path` [N, 2] within `radius` of the last one."""
    if len(path) == 0:
        return 0.0
    d = path - path[-1]
    return float(np.mean(np.einsum("ij,ij->i", d, d) <= radius * radius))


#: Names of the checks `judge_shape` makes, in order.
SHAPE_CHECKS = ("dtw", "hausdorff", "coverage", "goal", "dwell")


def judge_shape(ink: np.ndarray, pen_path: np.ndarray, target: np.ndarray, goal: np.ndarray,
                tol: ShapeTolerances, dtw_threshold: float, metres_per_unit: float = 1.0
                ) -> dict[str, Any]:
    """Decides whether `ink` draws `target`, all in one unit (the task's data units).

    The verdict is a list of `Check`s (`SHAPE_CHECKS`, in this order); the letter fails when
    any of them fails:

    - `dtw`: summed DTW of ink vs target <= `dtw_threshold` (the paper's);
    - `hausdorff`: symmetric Hausdorff distance <= `tol.hausdorff` (the shape, both ways);
    - `coverage`: the ink passes within `tol.coverage_radius` along >= `tol.min_coverage` of
      the target's arc length (value: that fraction, unitless);
    - `goal`: the last ink point within `tol.goal_tolerance` of `goal` (the letter was
      finished);
    - `dwell`: the pen spent <= `tol.max_dwell` of the steps within `tol.dwell_radius` of its
      last position (it wrote, rather than rushed to the end and waited; unitless).

    With fewer than 2 ink points dtw, hausdorff, coverage and goal are not measured (value
    None) and fail.

    Args:
        ink: [K, 2] pen tip points of the steps the pen was on the board.
        pen_path: [N, 2] pen tip points of every step of the episode (or the letter).
        target: [T, 2] the target demo.
        goal: [2] the task's end point.
        tol: the task's tolerances (data units).
        dtw_threshold: the paper's DTW threshold in these units.
        metres_per_unit: metres on the board per data unit: the checks report lengths in
            metres on the board (HelloWorld letters 1, LASA 0.003, a letter of the text 0.3);
            the other returned values stay in data units.

    Returns:
        {dtw, hausdorff, coverage, goal_distance, dwell (the measured values, data units; inf /
        0 when not measured), checks: list of the `Check`s, failed: the failed checks' names,
        is_success}.
    """
    from clfd_bench.metrics.trajectory import coverage, dtw, nearest_distances

    out: dict[str, Any] = {"dtw": math.inf, "hausdorff": math.inf, "coverage": 0.0,
                           "goal_distance": math.inf,
                           "dwell": dwell_fraction(pen_path, tol.dwell_radius)}
    measured = len(ink) >= 2
    if measured:
        d_ink, d_target = nearest_distances(ink, target)  # both ways: Hausdorff and coverage
        out.update(dtw=dtw(ink, target), hausdorff=float(max(d_ink.max(), d_target.max())),
                   coverage=coverage(target, ink, tol.coverage_radius, ref_distances=d_target),
                   goal_distance=float(np.linalg.norm(ink[-1] - goal)))
    k = float(metres_per_unit)

    def length(name: str, key: str, bound: float, note: str) -> Check:
        return Check(name, out[key] * k if measured else None, bound * k, "<=", "m", note)

    checks = [
        length("dtw", "dtw", dtw_threshold, "summed DTW of ink vs target (the paper's "
               "threshold)"),
        length("hausdorff", "hausdorff", tol.hausdorff, "largest two-sided deviation of the "
               "ink from the target"),
        Check("coverage", out["coverage"] if measured else None, tol.min_coverage, ">=", "",
              f"fraction of the target's arc length the ink passes within "
              f"{tol.coverage_radius * k:.4g} m of"),
        length("goal", "goal_distance", tol.goal_tolerance, "last ink point to the task's end "
               "point"),
        Check("dwell", out["dwell"], tol.max_dwell, "<=", "",
              f"fraction of the steps the pen spent within {tol.dwell_radius * k:.4g} m of its "
              "last position"),
    ]
    out["checks"] = checks
    out["failed"] = failed_checks(checks)
    out["is_success"] = not out["failed"]
    return out
