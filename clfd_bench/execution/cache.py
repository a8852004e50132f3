"""Keys and summaries of the rollout cache (``sim_cache.json``, stored by
:class:`clfd_bench.runs.RunDir`): execution summaries
(:meth:`clfd_bench.execution.execute.ExecResult.summary`, with the env's final checks) keyed by
env id, demo, settling time and the prediction's bytes, valid for one simulator fingerprint
(:func:`clfd_bench.execution.fingerprint.sim_fingerprint`).

A rollout that stopped on a decided failure has checks of its partial episode only; the same
prediction run to its horizon (``stop_when_decided=False``, for the borderline gallery) is
cached under its own key (``to_horizon=True``). Its success is the same."""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np

__all__ = ["nonfinite_summary", "prediction_key"]


def prediction_key(env_id: str, demo: int, settle_s: float | None,
                   trajectory: np.ndarray, *, to_horizon: bool = False) -> str:
    """The cache key of executing ``trajectory`` [T, D] from demo ``demo``'s start
    (``to_horizon``: without stopping on a decided failure)."""
    digest = hashlib.sha256()
    mode = "|horizon" if to_horizon else ""
    digest.update(f"{env_id}|{demo}|{settle_s}|{trajectory.shape}{mode}|".encode())
    digest.update(np.ascontiguousarray(trajectory, dtype=np.float64).tobytes())
    return digest.hexdigest()[:32]


def nonfinite_summary(demo: int) -> dict[str, Any]:
    """The summary of a prediction that is not executed because it holds NaN/inf."""
    return {"demo": demo, "success": False, "mean_tracking_error": None,
            "max_tracking_error": None, "mean_rotation_error": None,
            "failure_reason": "prediction contains NaN/inf (diverged); not executed",
            "failure_kind": "diverged",
            "steps": 0, "stopped_early": False, "checks": None}
