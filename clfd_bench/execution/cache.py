"""The rollout cache of a run directory (``sim_cache.json``): execution summaries keyed by
env id, demo, settling time and the prediction's bytes, valid for one simulator fingerprint
(:func:`clfd_bench.execution.fingerprint.sim_fingerprint`)."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.io import atomic_write_json

__all__ = ["CACHE_FILE", "load_cache", "nonfinite_summary", "prediction_key", "save_cache"]

CACHE_FILE = "sim_cache.json"
"""Name of the execution cache in a run directory."""
_CACHE_SCHEMA = 2  # 2: summaries carry failure_kind


def prediction_key(env_id: str, demo: int, settle_s: float | None,
                    trajectory: np.ndarray) -> str:
    digest = hashlib.sha256()
    digest.update(f"{env_id}|{demo}|{settle_s}|{trajectory.shape}|".encode())
    digest.update(np.ascontiguousarray(trajectory, dtype=np.float64).tobytes())
    return digest.hexdigest()[:32]


def load_cache(path: Path, fingerprint: str) -> dict[str, dict[str, Any]]:
    if not path.is_file():
        return {}
    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)
    except (OSError, json.JSONDecodeError):
        return {}  # unreadable: start over (it is only a cache)
    if doc.get("schema") != _CACHE_SCHEMA or doc.get("fingerprint") != fingerprint:
        return {}
    return dict(doc.get("entries") or {})


def save_cache(path: Path, fingerprint: str, entries: Mapping[str, Any]) -> None:
    atomic_write_json(path, {"schema": _CACHE_SCHEMA, "fingerprint": fingerprint,
                             "entries": dict(entries)}, indent=None)


def nonfinite_summary(demo: int) -> dict[str, Any]:
    return {"demo": demo, "success": False, "mean_tracking_error": None,
            "max_tracking_error": None, "mean_rotation_error": None,
            "failure_reason": "prediction contains NaN/inf (diverged); not executed",
            "failure_kind": "diverged",
            "steps": 0}
