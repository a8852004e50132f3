"""Continual-learning metrics (paper Sec. "Continual Learning Metrics", after Díaz-Rodríguez
et al. 2018, "Don't forget, there is more than forgetting").

``R[i, j]`` is the accuracy on task ``j`` after learning task ``i`` (``j <= i``), the fraction
of task ``j``'s demonstrations whose prediction has an error <= the threshold. With ``M``
tasks:

* ACC = mean of ``R[i, j]`` over ``i >= j``.
* BWT = mean over ``i > j`` of ``R[i, j] - R[j, j]``;  REM = 1 - |min(BWT, 0)|.
* MS  = min(1, mean_i Mem(theta_0) / Mem(theta_i))  (model size after task ``i``).
* SSS = 1 - min(1, mean_i stored_i / total)  (samples kept after task ``i``; all tasks' data).
* TE  = min(1, T_0 / M * sum_i 1 / T_i)  (``T_i``: time to learn task ``i``).
* FS  = 1 - Mem(theta_{M-1}) / (largest final size among the compared methods).
* CL_score = mean of the six criteria; CL_stability = 1 - their sample standard deviation.

All criteria lie in [0, 1], 1 best.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

__all__ = [
    "CRITERIA",
    "accuracy_matrix",
    "acc",
    "bwt",
    "rem",
    "model_size_efficiency",
    "sss",
    "time_efficiency",
    "final_model_size",
    "cl_score",
    "cl_stability",
    "cl_metrics",
]

CRITERIA: tuple[str, ...] = ("ACC", "REM", "MS", "TE", "FS", "SSS")
"""The six criteria CL_score and CL_stability combine (the paper's set C)."""


def accuracy_matrix(errors: Sequence | np.ndarray, thr: float) -> np.ndarray:
    """Accuracy matrix ``R`` from per-demonstration errors.

    Args:
        errors: ``[M][M][N_j]`` nested sequence (or ``[M, M, N]`` array): ``errors[i][j]``
            holds the errors of task ``j``'s predictions after learning task ``i``. Entries
            with ``j > i`` are ignored and may be ``None``, NaN-filled or absent (rows may be
            ragged, of length ``i + 1``). A NaN error with ``j <= i`` (e.g. a diverged
            prediction) counts as inaccurate.
        thr: threshold; an error <= ``thr`` is accurate.

    Returns:
        ``[M, M]`` float64 ``R`` with NaN above the diagonal.
    """
    m = len(errors)
    if m == 0:
        raise ValueError("errors is empty: need errors[i][j] for at least one task")
    r = np.full((m, m), np.nan)
    for i in range(m):
        row = errors[i]
        if row is None or len(row) < i + 1:
            raise ValueError(
                f"errors[{i}] must hold the errors of tasks 0..{i} (after learning task {i}), "
                f"got {0 if row is None else len(row)} entries"
            )
        for j in range(i + 1):
            if row[j] is None:
                raise ValueError(
                    f"errors[{i}][{j}] is missing: task {j} must be evaluated after task {i}"
                )
            e = np.asarray(row[j], dtype=np.float64).ravel()
            if e.size == 0:
                raise ValueError(f"errors[{i}][{j}] is empty: need one error per demonstration")
            r[i, j] = np.mean(e <= thr)  # NaN <= thr is False: counts as inaccurate
    return r


def _check_r(r: np.ndarray) -> np.ndarray:
    r = np.asarray(r, dtype=np.float64)
    if r.ndim != 2 or r.shape[0] != r.shape[1] or r.shape[0] == 0:
        raise ValueError(f"R must be a square [M, M] matrix with M >= 1, got shape {r.shape}")
    low = r[np.tril_indices(r.shape[0])]
    if np.any(~np.isfinite(low)) or np.any((low < 0) | (low > 1)):
        raise ValueError("R must hold accuracies in [0, 1] on and below the diagonal")
    return r


def acc(r: np.ndarray) -> float:
    """ACC: mean accuracy over all ``R[i, j]`` with ``i >= j``.

    Args:
        r: ``[M, M]`` accuracy matrix (values above the diagonal are ignored).
    """
    r = _check_r(r)
    return float(r[np.tril_indices(r.shape[0])].mean())


def bwt(r: np.ndarray) -> float:
    """Backward transfer: mean over ``i > j`` of ``R[i, j] - R[j, j]`` (negative = forgetting).

    Args:
        r: ``[M, M]`` accuracy matrix.

    Returns:
        BWT in [-1, 1]; NaN for a single task (no earlier task to forget).
    """
    r = _check_r(r)
    i, j = np.tril_indices(r.shape[0], k=-1)
    if i.size == 0:
        return math.nan
    return float(np.mean(r[i, j] - r[j, j]))


def rem(r: np.ndarray) -> float:
    """Remembering: ``1 - |min(BWT, 0)|``; NaN for a single task.

    Args:
        r: ``[M, M]`` accuracy matrix.
    """
    b = bwt(r)
    return math.nan if math.isnan(b) else 1.0 - abs(min(b, 0.0))


def _positive(values: Sequence[float], name: str) -> np.ndarray:
    arr = np.asarray(values, dtype=np.float64).ravel()
    if arr.size == 0:
        raise ValueError(f"{name} needs one value per learned task, got none")
    if np.any(~np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name} must be finite and > 0, got {arr.tolist()}")
    return arr


def model_size_efficiency(num_params_per_task: Sequence[float]) -> float:
    """MS = ``min(1, mean_i Mem(theta_0) / Mem(theta_i))``.

    Args:
        num_params_per_task: ``[M]`` model size (e.g. parameter count) after learning each task.
    """
    sizes = _positive(num_params_per_task, "num_params_per_task")
    return float(min(1.0, np.mean(sizes[0] / sizes)))


def sss(stored_per_task: Sequence[float], total_samples: float) -> float:
    """Sample storage size efficiency: ``1 - min(1, mean_i stored_i / total)``.

    Args:
        stored_per_task: ``[M]`` number of training samples kept in memory after learning
            task ``i`` (including the current task's data if the method keeps it for later
            tasks; 0 for methods that store none).
        total_samples: number of training samples of all ``M`` tasks together.

    A replay method that keeps every task's data scores ``1 - (M + 1) / (2M)`` with equal
    tasks: 0.48, 0.43 and 0.38 for 26, 7 and 4 tasks.
    """
    stored = np.asarray(stored_per_task, dtype=np.float64).ravel()
    if stored.size == 0 or np.any(~np.isfinite(stored)) or np.any(stored < 0):
        raise ValueError(f"stored_per_task must be one count >= 0 per task, got {stored.tolist()}")
    if not total_samples > 0:
        raise ValueError(f"total_samples must be > 0, got {total_samples}")
    return float(1.0 - min(1.0, np.mean(stored / total_samples)))


def time_efficiency(train_time_per_task: Sequence[float]) -> float:
    """TE = ``min(1, T_0 / M * sum_i 1 / T_i)`` (the paper's Eq. for TE).

    Args:
        train_time_per_task: ``[M]`` wall-clock seconds spent learning each task.
    """
    times = _positive(train_time_per_task, "train_time_per_task")
    return float(min(1.0, times[0] / times.size * np.sum(1.0 / times)))


def final_model_size(sizes: Mapping[str, float], method: str) -> float:
    """FS = ``1 - Mem(theta_{M-1}) / max over compared methods of their final size``.

    Args:
        sizes: final model size (after the last task) of every compared method.
        method: the method to score; must be a key of ``sizes``.
    """
    if method not in sizes:
        raise ValueError(f"method {method!r} is not among the compared sizes {sorted(sizes)}")
    values = _positive(list(sizes.values()), "sizes")
    return float(1.0 - float(sizes[method]) / values.max())


def _criteria_values(criteria: Mapping[str, float]) -> np.ndarray:
    unknown = sorted(set(criteria) - set(CRITERIA))
    if unknown:
        raise ValueError(f"unknown CL criteria {unknown}; valid: {list(CRITERIA)}")
    if not criteria:
        raise ValueError(f"no CL criteria given; valid: {list(CRITERIA)}")
    return np.array([float(criteria[k]) for k in CRITERIA if k in criteria])


def cl_score(criteria: Mapping[str, float]) -> float:
    """CL_score: the mean of the given criteria (normally all six of :data:`CRITERIA`).

    The paper writes a sum, but its tables print the mean (values in [0, 1]); Díaz-Rodríguez
    et al. weight the criteria, here equally. A subset may be passed (the paper's
    hyperparameter study leaves out SSS).

    Args:
        criteria: ``{name: value}`` with names from :data:`CRITERIA`.
    """
    return float(np.mean(_criteria_values(criteria)))


def cl_stability(criteria: Mapping[str, float]) -> float:
    """CL_stability: ``1 -`` the sample standard deviation (ddof = 1) of the criteria.

    The sample (not population) deviation reproduces the paper's tables.

    Args:
        criteria: ``{name: value}`` with at least two names from :data:`CRITERIA`.
    """
    values = _criteria_values(criteria)
    if values.size < 2:
        raise ValueError("CL_stability needs at least two criteria")
    return float(1.0 - np.std(values, ddof=1))


def cl_metrics(
    r: np.ndarray,
    num_params: Sequence[float] | None,
    stored: Sequence[float] | None,
    total: float,
    train_times: Sequence[float] | None,
    fs: float | None = None,
) -> dict[str, float | None]:
    """All CL metrics of one run.

    Args:
        r: ``[M, M]`` accuracy matrix (:func:`accuracy_matrix`).
        num_params: ``[M]`` model size after each task (None: not known).
        stored: ``[M]`` training samples kept after each task (None: not known).
        total: training samples of all tasks together.
        train_times: ``[M]`` seconds spent learning each task (None: not known).
        fs: FS, which needs every compared method's final size (:func:`final_model_size`);
            without it FS, CL_score and CL_stability are left out.

    Returns:
        ``{"ACC", "REM", "BWT", "MS", "SSS", "TE"}`` plus ``"FS"``, ``"CL_score"`` and
        ``"CL_stability"`` when ``fs`` is given. A criterion whose input is None (e.g.
        predictions scored from elsewhere without a model size,
        :mod:`clfd_bench.harness.external`) is None, never estimated; CL_score and
        CL_stability are then left out.
    """
    r = _check_r(r)
    m = r.shape[0]
    for name, seq in (("num_params", num_params), ("stored", stored), ("train_times", train_times)):
        if seq is not None and len(seq) != m:
            raise ValueError(f"{name} needs one value per task ({m}), got {len(seq)}")
    out: dict[str, float | None] = {
        "ACC": acc(r),
        "REM": rem(r),
        "BWT": bwt(r),
        "MS": None if num_params is None else model_size_efficiency(num_params),
        "SSS": None if stored is None else sss(stored, total),
        "TE": None if train_times is None else time_efficiency(train_times),
    }
    if fs is not None:
        out["FS"] = float(fs)
        if all(out[k] is not None for k in CRITERIA):
            criteria = {k: out[k] for k in CRITERIA}
            out["CL_score"] = cl_score(criteria)
            out["CL_stability"] = cl_stability(criteria)
    return out
