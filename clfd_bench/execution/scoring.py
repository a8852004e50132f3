"""Execution outcomes -> the success matrix and its continual-learning metrics, and failure
counts by kind (what ``results.json`` stores)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from clfd_bench.execution.execute import FAILURE_KINDS, _finite_or_none

__all__ = ["failure_counts", "sim_fields"]


def sim_fields(success: Sequence[Sequence[Sequence[bool] | None]],
               scored: Sequence[bool] | None = None) -> dict[str, Any]:
    """``success``, ``sim_accuracy`` and ``sim_cl_metrics`` of a run from its execution
    outcomes (what the training protocol and :func:`evaluate_run` write).

    Args:
        success: ``[M][<=M][N_j]``: ``success[i][j]`` the outcome of each demo of task ``j``
            after learning task ``i`` (``j <= i``; rows may be ragged or padded with None).
        scored: ``[M]`` whether task ``j`` was executed (False for tasks without an env); by
            default every task.

    Returns:
        ``{"success": [M][M] (lists of bools, None for j > i or unscored tasks),
        "sim_accuracy": [M][M] fraction of successful demos (None above the diagonal),
        "sim_cl_metrics": {"ACC", "REM", "BWT"} (:mod:`clfd_bench.metrics.cl`; None when
        undefined, e.g. BWT/REM with one task)}``. With unscored tasks the same formulas run
        over the scored tasks' columns ``j`` (every row ``i >= j``).
    """
    from clfd_bench.metrics.cl import acc, bwt, rem

    m = len(success)
    scored = [True] * m if scored is None else [bool(s) for s in scored]
    if len(scored) != m:
        raise ValueError(f"scored needs one flag per task ({m}), got {len(scored)}")
    out_success: list[list[list[bool] | None]] = []
    r = np.full((m, m), np.nan)
    for i in range(m):
        row: list[list[bool] | None] = []
        for j in range(m):
            cell = success[i][j] if (j <= i and j < len(success[i])) else None
            if cell is None or not scored[j]:
                row.append(None)
                continue
            flags = [bool(s) for s in cell]
            if not flags:
                raise ValueError(f"success[{i}][{j}] is empty: every executed task needs at "
                                 "least one demo")
            row.append(flags)
            r[i, j] = float(np.mean(flags))
        out_success.append(row)
    for i in range(m):
        for j in range(i + 1):
            if scored[j] and math.isnan(r[i, j]):
                raise ValueError(f"success[{i}][{j}] is missing: every scored task j <= i needs "
                                 "its outcomes")
    metrics: dict[str, float | None] = {"ACC": None, "REM": None, "BWT": None}
    if all(scored):
        metrics = {"ACC": acc(r), "REM": rem(r), "BWT": bwt(r)}
    elif any(scored):
        # The same formulas over the scored columns only (rows after unscored tasks count).
        low = [(i, j) for i in range(m) for j in range(i + 1) if scored[j]]
        back = [r[i, j] - r[j, j] for i, j in low if i > j]
        b = float(np.mean(back)) if back else math.nan
        metrics = {"ACC": float(np.mean([r[i, j] for i, j in low])),
                   "REM": math.nan if math.isnan(b) else 1.0 - abs(min(b, 0.0)), "BWT": b}
    accuracy = [[None if (j > i or math.isnan(r[i, j])) else float(r[i, j]) for j in range(m)]
                for i in range(m)]
    return {
        "success": out_success,
        "sim_accuracy": accuracy,
        "sim_cl_metrics": {k: _finite_or_none(v) if v is not None else None
                           for k, v in metrics.items()},
    }



def failure_counts(kinds: Sequence[Sequence[Sequence[str | None] | None]]) -> dict[str, int]:
    """Failures by kind over every evaluation point.

    Args:
        kinds: ``[M][M][N_j]`` failure kind of each executed point (None = success or not
            executed), as ``results.json``'s ``sim.failure_kind``.

    Returns:
        ``{kind: count}`` for every kind of :data:`FAILURE_KINDS` (zeros included), in that
        order.
    """
    counts = dict.fromkeys(FAILURE_KINDS, 0)
    for row in kinds:
        for cell in row:
            for kind in cell or ():
                if kind is not None:
                    if kind not in counts:
                        raise ValueError(f"unknown failure kind {kind!r}; valid: {FAILURE_KINDS}")
                    counts[kind] += 1
    return counts


def failed_check_counts(
    checks: Sequence[Sequence[Sequence[Sequence[str] | None] | None]],
) -> dict[str, int]:
    """How often each success check failed over every evaluation point, most frequent first
    (ties by name): the checks behind the ``task`` failures.

    Args:
        checks: ``[M][M][N_j]`` names of the failed checks of each executed point (None or
            empty: it succeeded, failed otherwise, or its env reports no checks), as
            ``results.json``'s ``sim.failed_checks``. An execution that fails two checks
            counts for both.
    """
    counts: dict[str, int] = {}
    for row in checks:
        for cell in row:
            for names in cell or ():
                for name in names or ():
                    counts[name] = counts.get(name, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))

