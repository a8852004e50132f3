"""Predictions made elsewhere, scored like a run trained here (``clfd-bench score``).

:func:`score_predictions` reads and checks them with
:func:`~clfd_bench.harness.external_format.read_predictions` (the format, the optional fields
and every check are in :mod:`clfd_bench.harness.external_format` and ``docs/predictions.md``)
and turns them into a normal run directory (:class:`clfd_bench.runs.RunDir`) with the same code
as a training run: errors from :func:`~clfd_bench.harness.evaluation.task_errors`, accuracy
matrices and CL metrics from :func:`~clfd_bench.harness.evaluation.results_document`, and run by
the function that runs a training run (:func:`clfd_bench.harness.run.run`: the run directory's
lock, execution in simulation), with a source that trains nothing. A CL criterion whose
optional field is missing (:data:`CRITERIA_NEEDING`) is left empty, never estimated.
"""

from __future__ import annotations

import datetime
import os
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from clfd_bench.data.types import Dataset
from clfd_bench.harness.external_format import (
    ExternalPredictions,
    PredictionsError,
    read_predictions,
)
from clfd_bench.harness.validate import check_run_out_dir
from clfd_bench.runs import CACHE_FILE, LOCK_FILE, PREDICTIONS_DIR, RunDir, RunFileError

__all__ = [
    "CRITERIA_NEEDING",
    "score_predictions",
]

CRITERIA_NEEDING: dict[str, tuple[str, ...]] = {
    "num_params": ("MS", "FS"),
    "train_time_s": ("TE",),
    "stored_samples": ("SSS",),
}
"""The CL criteria left empty when a field (or its ``_by_part`` form) is not given."""

_LABEL = re.compile(r"[A-Za-z0-9_.+-]+")


# ---------------------------------------------------------------------------- scoring
def _load_dataset(name: str, order: int, node: str) -> Dataset:
    """The dataset in ``order``, after the run-level checks every command shares."""
    from clfd_bench.data import DATASETS, load_dataset
    from clfd_bench.harness.config import ConfigError
    from clfd_bench.harness.run_config import check_run_values

    if name not in DATASETS:
        raise PredictionsError(f"--dataset {name!r}: unknown dataset; valid: "
                               f"{', '.join(DATASETS)}")
    try:
        check_run_values({"order": order, "node": node}, name)
    except ConfigError as exc:
        raise PredictionsError(str(exc)) from None
    return load_dataset(name, order=order)


def _per_part(fields: Mapping[str, Any], name: str) -> tuple[list[float] | None,
                                                             dict[str, list[float]] | None]:
    """``(total [M], {part: [M]})`` of ``num_params`` or ``train_time_s`` (None: not given):
    the total is the sum of the parts when only those are given, and the parts are
    ``{"position": total}`` (one model for every metric) when only the total is."""
    total, parts = fields.get(name), fields.get(f"{name}_by_part")
    if parts and total is None:
        total = [float(sum(v)) for v in zip(*parts.values(), strict=True)]
    if total is not None and not parts:
        parts = {"position": list(total)}
    return total, parts


def _not_provided(fields: Mapping[str, Any]) -> dict[str, list[str]]:
    missing = [name for name in CRITERIA_NEEDING
               if name not in fields and f"{name}_by_part" not in fields]
    criteria = [c for name in missing for c in CRITERIA_NEEDING[name]]
    if criteria:
        criteria += ["CL_score", "CL_stability"]
    return {"fields": missing, "criteria": criteria}


def _check_out(run: RunDir, config: Mapping[str, Any], files: Mapping[str, str]) -> None:
    """``--out`` may be new, hold only what a killed scoring leaves, or the same scoring."""
    try:
        existing = run.read_results()
    except RunFileError as exc:
        raise PredictionsError(f"--out {run.path}: {exc}; use another --out") from None
    if existing is None:
        other = [n for n in run.entries() if n not in (PREDICTIONS_DIR, CACHE_FILE, LOCK_FILE)]
        if other:
            raise PredictionsError(f"--out {run.path} is not empty (it holds {', '.join(other)}) "
                                   "and is not a run scored from these predictions; use another "
                                   "--out or empty it")
        return
    source = ((existing.get("provenance") or {}).get("external") or {})
    if existing.get("config") != dict(config) or source.get("files") != dict(files):
        what = ("predictions scored with other files or options" if source
                else "a run trained by `clfd-bench train`")
        raise PredictionsError(f"--out {run.path} holds {what}; use another --out or delete it")


def score_predictions(
    predictions: str | os.PathLike[str],
    dataset: str,
    *,
    order: int = 0,
    node: str = "t",
    tasks: int | None = None,
    out: str | os.PathLike[str],
    sim: bool = True,
    method_name: str = "external",
    sim_workers: int = 1,
    log: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Scores predictions made elsewhere into a run directory, as if trained here.

    Writes ``out/predictions/after_task_{i}.npz`` (the predictions, as float64) and
    ``out/results.json`` (errors ``[i][j][demo]``, accuracy matrices, CL metrics, with
    ``config.profile = "external"``, ``checkpoint = None``, ``not_provided`` naming the
    fields and criteria left empty, and ``provenance.external``: source path, layout, the
    sha256 of every file read, NaN/inf predictions), then, with ``sim``, executes every
    prediction in simulation (``success``, ``sim_accuracy``, ``sim_cl_metrics``, ``sim``).
    Scoring the same files with the same options into the same ``out`` again is allowed
    (its rollouts come from the run's cache).

    Args:
        predictions: a directory of ``after_task_<i>.npz`` or one ``.npz`` (module
            docstring; ``docs/predictions.md``); ``[N_demos, T, D]`` per learned task ``i``
            and seen task ``j <= i``, in the dataset's units.
        dataset: ``lasa``, ``helloworld``, ``robotasks`` or ``robotasks9``.
        order: the task order the predictions follow (0, 1, 2).
        node: ``"t"`` or ``"i"``: the NODE variant the run is compared with (recorded only).
        tasks: score only the first K learned tasks (default: every one given).
        out: the run directory to write (new, or the same scoring's).
        sim: also execute the predictions in simulation.
        method_name: the run's method label (its leaderboard row).
        sim_workers: processes executing rollouts in parallel.
        log: where warnings (NaN/inf predictions) go (None: nowhere).

    Returns:
        The run's ``results.json`` as written.

    Raises:
        PredictionsError: bad predictions or options (one line; nothing is written).
        InputError: an unusable ``out``. DatasetError: missing or corrupt dataset files.
    """
    from clfd_bench.harness.evaluation import (
        dataset_provenance,
        metrics_for,
        package_versions,
        results_document,
        task_errors,
    )
    from clfd_bench.harness.run import run as run_a_run

    if not isinstance(method_name, str) or not _LABEL.fullmatch(method_name):
        raise PredictionsError(f"--method-name {method_name!r}: use letters, digits and . _ + - "
                               "(it labels the run's leaderboard row)")
    if isinstance(sim_workers, bool) or not isinstance(sim_workers, int) or sim_workers < 1:
        raise PredictionsError(f"--sim-workers {sim_workers!r}: must be an integer >= 1")
    ds = _load_dataset(dataset, order, node)
    check_run_out_dir(out)
    ext = read_predictions(predictions, ds, tasks)  # every check before anything is written
    m = ext.num_tasks
    config = {"method": method_name, "dataset": ds.name, "profile": "external", "order": order,
              "seed": None, "node": node, "tasks": m}
    run = RunDir(out)
    _check_out(run, config, ext.files)
    for bad in ext.nonfinite:
        if log is not None:
            log(f"warning: {ext.source / bad['file'] if ext.layout == 'directory' else ext.source}"
                f" {bad['key']}: predictions of demos {bad['demos']} hold NaN/inf; scored as "
                "failures (diverged), as a training run scores a diverged prediction")

    tasks_ = ds.tasks[:m]
    metrics = metrics_for(tasks_[0].is_pose)
    errors: dict[str, list[list[Any]]] = {k: [[None] * m for _ in range(m)] for k in metrics}
    for i in range(m):
        for j in range(i + 1):
            for metric, values in task_errors(tasks_[j], ext.predictions[i][j]).items():
                errors[metric][i][j] = values
    num_params, num_params_by_part = _per_part(ext.fields, "num_params")
    train_time, train_time_by_part = _per_part(ext.fields, "train_time_s")
    state = {
        "tasks": [t.name for t in tasks_],
        "train_time_s": train_time,
        "train_time_s_by_part": train_time_by_part,
        "iterations_per_s_by_part": None,
        "iterations_by_part": None,
        "final_loss_by_part": None,
        "num_params": num_params,
        "num_params_by_part": num_params_by_part,
        "stored_samples": ext.fields.get("stored_samples"),
        "errors": errors,
    }
    provenance = {
        "packages": package_versions(),
        "dataset": dataset_provenance(ds),
        "external": {
            "source": str(ext.source),
            "layout": ext.layout,
            "files": ext.files,
            "fields": sorted(ext.fields),
            "nonfinite": ext.nonfinite,
            "scored_at": datetime.datetime.now(datetime.timezone.utc).isoformat(
                timespec="seconds"),
        },
    }
    results = results_document(config, ds.name, tasks_, state, complete=True,
                               provenance=provenance, checkpoint=None)
    results["not_provided"] = _not_provided(ext.fields)
    return run_a_run(_Scored(ext, results), run.path, sim=sim, sim_workers=sim_workers)


@dataclass(frozen=True)
class _Scored:
    """The source of a run scored from predictions made elsewhere
    (:class:`clfd_bench.harness.run.Source`): it trains nothing, it writes the predictions
    and the scored ``results.json``."""

    ext: ExternalPredictions
    results: dict[str, Any]

    def owner(self, out: Path) -> str:
        return f"clfd-bench score {self.ext.source} --out {out}"

    def produce(self, out: Path, after_task: Any, log: Any) -> dict[str, Any]:
        run = RunDir(out)
        for i, row in enumerate(self.ext.predictions):
            run.save_predictions(i, row)
        return run.write_training_results(self.results)
