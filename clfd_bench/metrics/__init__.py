"""The paper's metrics: trajectory errors, orientation error, accuracy thresholds, CL metrics.

* :mod:`~clfd_bench.metrics.trajectory`: DTW, discrete Fréchet, swept area (and batched forms).
* :mod:`~clfd_bench.metrics.orientation`: the quaternion error ``E_q``.
* :mod:`~clfd_bench.metrics.thresholds`: the paper's accuracy thresholds, in any units.
* :mod:`~clfd_bench.metrics.cl`: ACC, BWT, REM, MS, SSS, TE, FS, CL_score, CL_stability.
* :mod:`~clfd_bench.metrics.paper_numbers`: the paper's published values of these metrics
  (its CL tables, training and inference times), read from ``baselines/paper_results.toml``.
"""

from clfd_bench.metrics.orientation import quaternion_error
from clfd_bench.metrics.thresholds import THRESHOLD_SOURCES, demo_spread_threshold, threshold
from clfd_bench.metrics.trajectory import (
    TRAJECTORY_METRICS,
    dtw,
    dtw_batch,
    frechet,
    frechet_batch,
    swept_area,
    swept_area_batch,
    trajectory_errors,
)

__all__ = [
    "THRESHOLD_SOURCES",
    "TRAJECTORY_METRICS",
    "demo_spread_threshold",
    "dtw",
    "dtw_batch",
    "frechet",
    "frechet_batch",
    "quaternion_error",
    "swept_area",
    "swept_area_batch",
    "threshold",
    "trajectory_errors",
]
