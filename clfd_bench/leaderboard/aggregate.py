"""Aggregate finished runs into leaderboard rows: median and IQR over seeds and orders.

Input: the ``results.json`` of each run (schema of :mod:`clfd_bench.harness`). FS needs the
final model sizes of every compared method, so it is computed here, across the grid, and
CL_score / CL_stability are recomputed with it.

**exec CL_score** is CL_score with ACC and REM taken from executing the predictions in
simulation (``sim_cl_metrics``) instead of from the DTW threshold; MS, TE, FS and SSS are the
same. It ranks methods by what the robot achieved (e.g. a NODE^I letter that passes the
paper's DTW threshold without the loop the letter has fails the writing criterion).

A run scored from predictions made elsewhere (``clfd-bench score``) may not know its model
size, training time or stored samples (``results.json`` ``not_provided``): its MS, FS, TE, SSS
and CL_score are then empty, never estimated, and its row records them in ``not_provided``
(shown as "—"). FS is computed over the methods whose final size is known.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from clfd_bench.harness.evaluation import metric_part
from clfd_bench.leaderboard.grid import RunSpec
from clfd_bench.metrics.cl import CRITERIA, cl_score, cl_stability, final_model_size

__all__ = ["MethodRow", "RunRecord", "aggregate", "quartiles", "error_metric_for"]

EXEC_KEYS = ("ACC", "REM", "BWT")


@dataclass
class RunRecord:
    """A run of the grid and what it left: results (None if none), status, error."""

    spec: RunSpec
    status: str
    results: dict[str, Any] | None = None
    error: str | None = None


@dataclass
class MethodRow:
    """One leaderboard row: a method's metrics over its runs (value lists per key)."""

    method: str
    runs_ok: int = 0
    runs_failed: int = 0
    errors: list[str] = field(default_factory=list)
    values: dict[str, list[float]] = field(default_factory=lambda: defaultdict(list))
    #: execution failures by kind, summed over the runs that report them (None: no run does).
    failures: dict[str, int] | None = None
    #: the success checks behind the task failures, summed the same way (None: no run reports
    #: them; results.json ``sim.failed_check_counts``).
    failed_checks: dict[str, int] | None = None
    #: keys some run of the row left empty because it did not provide their inputs
    #: (``results.json`` ``not_provided``: predictions scored from elsewhere).
    not_provided: set[str] = field(default_factory=set)

    def median(self, key: str) -> float:
        vals = self.values.get(key, [])
        return float(np.median(vals)) if vals else float("nan")

    def iqr(self, key: str) -> tuple[float, float]:
        vals = self.values.get(key, [])
        if not vals:
            return float("nan"), float("nan")
        q1, q3 = np.percentile(vals, [25, 75])
        return float(q1), float(q3)


def quartiles(values: list[float] | np.ndarray) -> tuple[float, float, float]:
    """(q1, median, q3) of the finite values; NaNs if there are none."""
    arr = np.asarray(values, dtype=float)
    arr = arr[np.isfinite(arr)]
    if arr.size == 0:
        return float("nan"), float("nan"), float("nan")
    q1, med, q3 = np.percentile(arr, [25, 50, 75])
    return float(q1), float(med), float(q3)


def error_metric_for(results: dict[str, Any]) -> str:
    """The headline trajectory error of a run: DTW (position)."""
    return "dtw" if "dtw" in results.get("errors", {}) else next(iter(results["errors"]))


def _final_size(results: dict[str, Any]) -> float:
    """The final size of the model the run's CL criteria describe: for pose data the part of
    its primary metric (RoboTasks: the position model, as MS and TE and the paper's position
    table), else the whole model."""
    by_part = results.get("num_params_by_part") or {}
    primary = results.get("cl_metrics_primary")
    sizes = by_part.get(metric_part(primary, by_part)) if by_part and primary else None
    sizes = sizes or results.get("num_params") or []
    return float(sizes[-1]) if sizes and sizes[-1] is not None else float("nan")


def aggregate(records: list[RunRecord], methods: list[str]) -> list[MethodRow]:
    """One :class:`MethodRow` per method, in ``methods`` order.

    Keys in ``values``: the trajectory CL criteria and CL_score / CL_stability (with FS
    across the compared methods), ``BWT``, ``exec_ACC`` / ``exec_REM`` / ``exec_BWT`` (from
    simulation, when the run executed), ``train_time_s`` (total wall-clock), ``train_cpu_s``
    (total CPU seconds of the training process, when every task recorded it),
    ``final_params``; and
    ``failures``, the execution failures by kind summed over the runs; ``not_provided``, the
    keys a run could not fill (module docstring). ``exec_CL_score``: CL_score with ACC and REM
    from execution, for runs that executed and have all six criteria.
    """
    rows = {m: MethodRow(m) for m in methods}
    finished = [r for r in records if r.results is not None and r.status == "done"]
    # FS: the final model size of each method (median over its runs) against all methods
    # (those whose size is known: predictions scored from elsewhere may not give one).
    sizes: dict[str, float] = {}
    for method in methods:
        vals = [v for r in finished if r.spec.label == method
                if np.isfinite(v := _final_size(r.results))]
        if vals:
            sizes[method] = float(np.median(vals))
    unknown = {m for m in methods if m not in sizes
               and any(r.spec.label == m and _not_provided(r.results) for r in finished)}
    for record in records:
        row = rows[record.spec.label]
        if record.status != "done" or record.results is None:
            if record.status == "failed":
                row.runs_failed += 1
                row.errors.append(f"{record.spec.name}: {record.error}")
            continue
        row.runs_ok += 1
        res = record.results
        cl = dict(res.get("cl_metrics", {}))
        if len(sizes) + len(unknown) == len(methods) and record.spec.label in sizes:
            cl["FS"] = final_model_size(sizes, record.spec.label)
        row.not_provided |= _not_provided(res)
        for key in (*CRITERIA, "BWT"):
            if cl.get(key) is not None:
                row.values[key].append(float(cl[key]))
        criteria = {k: cl[k] for k in CRITERIA if cl.get(k) is not None}
        if len(criteria) == len(CRITERIA):
            row.values["CL_score"].append(cl_score(criteria))
            row.values["CL_stability"].append(cl_stability(criteria))
        sim_cl = res.get("sim_cl_metrics") or {}
        for key in EXEC_KEYS:
            if sim_cl.get(key) is not None:
                row.values[f"exec_{key}"].append(float(sim_cl[key]))
        if len(criteria) == len(CRITERIA) and all(sim_cl.get(k) is not None
                                                  for k in ("ACC", "REM")):
            executed = {**criteria, "ACC": float(sim_cl["ACC"]), "REM": float(sim_cl["REM"])}
            row.values["exec_CL_score"].append(cl_score(executed))
        counts = (res.get("sim") or {}).get("failure_counts")
        if counts:
            row.failures = row.failures or {}
            for kind, n in counts.items():
                row.failures[kind] = row.failures.get(kind, 0) + int(n)
        by_check = (res.get("sim") or {}).get("failed_check_counts")
        if by_check is not None:
            row.failed_checks = row.failed_checks or {}
            for name, n in by_check.items():
                row.failed_checks[name] = row.failed_checks.get(name, 0) + int(n)
        if res.get("train_time_s"):
            row.values["train_time_s"].append(float(sum(res["train_time_s"])))
        cpu = res.get("train_cpu_s") or []
        if cpu and len(cpu) == len(res.get("train_time_s") or []) and None not in cpu:
            row.values["train_cpu_s"].append(float(sum(cpu)))
        if np.isfinite(size := _final_size(res)):
            row.values["final_params"].append(size)
    return [rows[m] for m in methods]


def _not_provided(results: dict[str, Any]) -> set[str]:
    """The leaderboard keys a run leaves empty for want of inputs (``not_provided``)."""
    missing = set((results.get("not_provided") or {}).get("criteria") or ())
    if "CL_score" in missing:
        missing.add("exec_CL_score")
    fields = set((results.get("not_provided") or {}).get("fields") or ())
    if "num_params" in fields:
        missing.add("final_params")
    if "train_time_s" in fields:
        missing |= {"train_time_s", "train_cpu_s"}
    return missing
