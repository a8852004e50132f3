"""Predictions made elsewhere: their format, and reading and checking them.

:func:`read_predictions` reads a directory or ``.npz`` of predictions and checks every array
and field against the dataset; scoring the checked predictions into a run directory is
:func:`clfd_bench.harness.external.score_predictions` (``clfd-bench score``). The format is
documented, with a script that writes it, in ``docs/predictions.md``.

**Format.** For every learned task ``i`` (``0 <= i < M``) and every seen task ``j <= i``: the
predicted trajectories of task ``j`` after learning task ``i``, ``[N_demos, T, D]`` numbers,
prediction ``d`` integrated from demo ``d``'s start (``task.demos[d, 0]``) at the demos' time
stamps (``task.times``), in the dataset's units: HelloWorld and RoboTasks positions in metres
(Panda base frame), LASA in its own units; RoboTasks poses ``(px, py, pz, qw, qx, qy, qz)``
of the Menagerie ``hand`` frame, unit quaternions scalar first. Two layouts:

* a directory of ``after_task_<i>.npz`` files holding arrays ``task_<j>`` -- exactly what a
  run saves in ``RUN_DIR/predictions/`` -- plus an optional ``meta.json``;
* one ``.npz`` holding arrays ``after_task_<i>/task_<j>`` plus optional field arrays.

Keys ``task_<j>`` with ``j > i`` (tasks not learned yet) are ignored; any other unknown key is
an error (a typo must not pass silently).

**Optional fields** (:data:`OPTIONAL_FIELDS`), which the CL criteria that are not about
accuracy need: ``num_params`` (MS, FS), ``train_time_s`` (TE), ``stored_samples`` (SSS), each
``[M]`` (one value per learned task), and for methods with one model per part (RoboTasks:
position and orientation) ``num_params_by_part`` / ``train_time_s_by_part``,
``{"position": [M], "orientation": [M]}``. They are the keys a run's ``results.json`` uses. A
criterion whose field is missing is left empty (None in ``results.json``, listed under
``not_provided``; "—" in a leaderboard), never estimated.

**Diverged predictions** (NaN or inf) are treated as a training run treats them: such a
prediction's errors are None and it counts as inaccurate, and in simulation it is a failure of
kind ``diverged``, not executed. Each file and key holding one is named in a warning and in
``results.json`` (``provenance.external.nonfinite``).

Every other defect (a missing file or key, a wrong shape or number of demos, non-numeric
values, an unknown key or field, a bad ``--out``) raises :class:`PredictionsError`, one line
naming the file, the key, what was expected and what to do, before anything is written.
"""

from __future__ import annotations

import json
import os
import re
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.data.types import Dataset, Task
from clfd_bench.harness.validate import InputError
from clfd_bench.io import sha256_file
from clfd_bench.runs import PREDICTIONS_DIR

__all__ = [
    "META_FILE",
    "OPTIONAL_FIELDS",
    "ExternalPredictions",
    "PredictionsError",
    "read_predictions",
]

META_FILE = "meta.json"
"""The optional fields' file in the directory layout."""

OPTIONAL_FIELDS: dict[str, str] = {
    "num_params": "model size after learning each task (e.g. parameter count), [M] numbers > 0",
    "train_time_s": "seconds spent learning each task, [M] numbers > 0",
    "stored_samples": "training samples kept in memory after each task, [M] numbers >= 0",
    "num_params_by_part": '{"position": [M], "orientation": [M]}: num_params per model',
    "train_time_s_by_part": '{"position": [M], "orientation": [M]}: train_time_s per model',
}
"""The optional fields of the predictions and what each holds."""

PARTS = ("position", "orientation")
_FILE = re.compile(r"after_task_(0|[1-9][0-9]*)\.npz")
_TASK_KEY = re.compile(r"task_(0|[1-9][0-9]*)")
_NPZ_KEY = re.compile(r"after_task_(0|[1-9][0-9]*)/task_(0|[1-9][0-9]*)")
_DOC = "see docs/predictions.md"


class PredictionsError(InputError):
    """Predictions that cannot be scored: one line naming the file, the key, what was
    expected and what to do (``clfd-bench`` prints it and exits with code 2)."""


@dataclass(frozen=True)
class ExternalPredictions:
    """Checked predictions, ready to score.

    Attributes:
        source: the directory or ``.npz`` they were read from (absolute).
        layout: ``"directory"`` or ``"npz"``.
        files: every file read, relative to ``source`` (the file name for ``.npz``) ->
            its sha256.
        predictions: ``predictions[i][j]``: ``[N_j, T, D]`` float64, task ``j``'s
            predictions after learning task ``i`` (``j <= i``), in data units.
        fields: the optional fields given (:data:`OPTIONAL_FIELDS`), each cut to ``M``
            values, as plain lists (``_by_part``: ``{part: [M]}``).
        nonfinite: ``{"file", "key", "demos"}`` of every array with NaN/inf predictions.
    """

    source: Path
    layout: str
    files: dict[str, str]
    predictions: list[list[np.ndarray]]
    fields: dict[str, Any] = field(default_factory=dict)
    nonfinite: list[dict[str, Any]] = field(default_factory=list)

    @property
    def num_tasks(self) -> int:
        """M, the number of learned tasks."""
        return len(self.predictions)


# ---------------------------------------------------------------------------- expectations
def _units(task: Task) -> str:
    length = "metres" if task.units == "m" else f"{task.units} units"
    if task.is_pose:
        return f"px, py, pz in {length}, then the unit quaternion qw, qx, qy, qz"
    return f"x, y in {length}"


def _expected(ds: Dataset, m: int) -> str:
    """What the predictions of ``ds``'s first ``m`` tasks must look like, in words."""
    tasks = ds.tasks[:m]
    names = ", ".join(repr(t.name) for t in tasks)
    shapes = {tuple(t.demos.shape) for t in tasks}
    if len(shapes) == 1:
        shape = f"each [N_demos, T, D] = {list(next(iter(shapes)))}"
    else:
        shape = "[N_demos, T, D] = " + ", ".join(f"{list(t.demos.shape)}" for t in tasks)
    return (f"{ds.name} order {ds.order} expects task_0..task_{m - 1} = {names}, {shape} "
            f"({_units(tasks[0])})")


def _error(where: str, what: str, ds: Dataset, m: int, fix: str) -> PredictionsError:
    return PredictionsError(f"{where}: {what}; {_expected(ds, m)}; {fix} ({_DOC})")


# ---------------------------------------------------------------------------- reading
def _open_npz(path: Path, ds: Dataset, m: int):
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise _error(str(path), f"not a readable .npz file ({exc})", ds, m,
                     "write it with numpy.savez") from None


def _array(npz, key: str, where: str, ds: Dataset, m: int) -> np.ndarray:
    try:
        arr = npz[key]
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        # allow_pickle=False refuses object arrays: not plain numbers
        raise _error(where, f"key {key!r} is not an array of numbers ({exc})", ds, m,
                     "save float arrays (numpy.asarray(x, dtype=float))") from None
    if arr.dtype.kind not in "iuf":
        raise _error(where, f"key {key!r} holds {arr.dtype} values, not real numbers", ds, m,
                     "save float arrays (numpy.asarray(x, dtype=float))")
    return arr


def _prediction(npz, key: str, where: str, task: Task, j: int, ds: Dataset, m: int,
                nonfinite: list[dict[str, Any]], file: str) -> np.ndarray:
    arr = _array(npz, key, where, ds, m)
    expected = tuple(task.demos.shape)
    if arr.shape != expected:
        what = f"key {key!r} has shape {list(arr.shape)}, expected {list(expected)}"
        if arr.ndim == 3 and arr.shape[1:] == expected[1:]:
            what += (f" (task {j} {task.name!r} has {expected[0]} demos, the file "
                     f"{arr.shape[0]} predictions)")
        elif arr.ndim == 3 and arr.shape[2] != expected[2]:
            what += f" (D = {arr.shape[2]}, {ds.name} has D = {expected[2]}: is --dataset right?)"
        raise _error(where, what, ds, m,
                     f"save one prediction per demo of task {task.name!r}, from its start, at "
                     "the demos' time stamps")
    arr = np.asarray(arr, dtype=np.float64)
    if not np.isfinite(arr).all():
        bad = ~np.isfinite(arr.reshape(arr.shape[0], -1)).all(axis=1)
        nonfinite.append({"file": file, "key": key,
                          "demos": [int(d) for d in np.flatnonzero(bad)]})
    ratio, offset = size_ratio(arr, task), start_offset(arr, task)
    if offset > 0.1 and not 1.0 / SIZE_RATIO_LIMIT <= ratio <= SIZE_RATIO_LIMIT:
        raise _error(where, f"key {key!r}: the predictions are {ratio:.3g}x the size of task "
                     f"{task.name!r}'s demos and do not start at their starts (off by "
                     f"{offset:.0%} of the demos' extent): other units? (metres for LASA "
                     "units is 0.003x, millimetres for metres 1000x)", ds, m,
                     "save predictions in the dataset's units, from each demo's start")
    return arr


SIZE_RATIO_LIMIT = 30.0
"""Predictions are refused as being in other units when they are more than this factor larger
(or smaller) than the demos (:func:`size_ratio`) *and* do not start at the demos' starts
(:func:`start_offset` > 10 % of the extent): m vs mm is 1000x, LASA units vs m 333x. A wrong
skill in the right units passes (another task's demos: 0.35-2.9x on every dataset, none
refused); so does a diverging or motionless prediction, which starts where its demo does."""


def _finite_positions(predictions: np.ndarray, dim: int) -> np.ndarray:
    pos = predictions[..., :dim].reshape(-1, dim)
    return pos[np.isfinite(pos).all(axis=1)]


def size_ratio(predictions: np.ndarray, task: Task) -> float:
    """How large the predicted positions ``[N, T, D]`` are against ``task``'s demos: the
    median distance of the finite predicted positions from their own mean, over the same for
    the demos (1 for the demos, ``k`` for the demos times ``k``; 1 when nothing is finite)."""
    dim = task.positions.shape[-1]
    demos, pos = task.positions.reshape(-1, dim), _finite_positions(predictions, dim)
    if len(pos) < 2:
        return 1.0
    spread = float(np.median(np.linalg.norm(pos - pos.mean(axis=0), axis=1)))
    return spread / float(np.median(np.linalg.norm(demos - demos.mean(axis=0), axis=1)))


def start_offset(predictions: np.ndarray, task: Task) -> float:
    """Median distance of each prediction's first position from its demo's, as a fraction of
    the demos' extent (the largest range of a position coordinate); 0 when none is finite."""
    dim = task.positions.shape[-1]
    d = np.linalg.norm(predictions[:, 0, :dim] - task.positions[:, 0], axis=1)
    d = d[np.isfinite(d)]
    extent = float(np.ptp(task.positions.reshape(-1, dim), axis=0).max())
    return float(np.median(d)) / extent if len(d) else 0.0


def _numbers(value: Any, name: str, m: int, minimum_exclusive: bool, where: str,
             ds: Dataset) -> list[float]:
    try:
        arr = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        arr = None
    ok = (arr is not None and np.ndim(value) == 1 and arr.size >= m
          and np.isfinite(arr[:m]).all()
          and bool(np.all(arr[:m] > 0) if minimum_exclusive else np.all(arr[:m] >= 0)))
    if not ok:
        bound = "> 0" if minimum_exclusive else ">= 0"
        got = repr(value.tolist() if isinstance(value, np.ndarray) else value)
        got = got if len(got) <= 60 else got[:57] + "..."
        raise _error(where, f"field {name!r} must be a list of one finite number {bound} per "
                     f"learned task ({m}), got {got}", ds, m,
                     f"fix it or leave it out ({name}: {OPTIONAL_FIELDS[name.split('/')[0]]})")
    return [float(x) for x in arr[:m]]


def _check_fields(raw: Mapping[str, Any], m: int, where: str, ds: Dataset) -> dict[str, Any]:
    """The optional fields, checked and cut to ``m`` values."""
    out: dict[str, Any] = {}
    for name, value in raw.items():
        if name not in OPTIONAL_FIELDS:
            raise _error(where, f"unknown field {name!r}", ds, m,
                         f"the optional fields are {', '.join(OPTIONAL_FIELDS)}")
        strict = name != "stored_samples"
        if name.endswith("_by_part"):
            if not isinstance(value, Mapping) or not value or set(value) - set(PARTS):
                raise _error(where, f"field {name!r} must map parts {list(PARTS)} to [M] "
                             f"lists, got {value!r:.80}", ds, m, "fix it or leave it out")
            out[name] = {part: _numbers(v, f"{name}/{part}", m, strict, where, ds)
                         for part, v in value.items()}
        else:
            out[name] = _numbers(value, name, m, strict, where, ds)
    return out


def _tasks_wanted(found: Sequence[int], tasks: int | None, ds: Dataset, where: str) -> int:
    """M: ``tasks`` or one more than the largest ``after_task`` index found."""
    n = len(ds)
    if not found:
        raise _error(where, "holds no predictions (no after_task_<i>.npz file, no "
                     "after_task_<i>/task_<j> key)", ds, n,
                     "write after_task_0 .. after_task_<M-1> for the M learned tasks")
    m = max(found) + 1 if tasks is None else tasks
    if tasks is None and m > n:
        raise _error(where, f"holds predictions after task {m - 1}, but {ds.name} has only "
                     f"{n} tasks (after_task_0..after_task_{n - 1})", ds, n,
                     "remove the extra ones")
    return m


def _read_directory(source: Path, ds: Dataset, tasks: int | None) -> ExternalPredictions:
    indices = sorted(int(mt.group(1)) for p in source.iterdir()
                     if (mt := _FILE.fullmatch(p.name)) and p.is_file())
    if not indices and (source / PREDICTIONS_DIR).is_dir():
        raise _error(str(source), f"holds no after_task_<i>.npz, but a {PREDICTIONS_DIR}/ "
                     "folder (a run directory?)", ds, len(ds),
                     f"pass {source / PREDICTIONS_DIR}")
    m = _tasks_wanted(indices, tasks, ds, str(source))
    missing = [f"after_task_{i}.npz" for i in range(m) if i not in indices]
    if missing:
        raise _error(str(source / missing[0]), f"missing (the predictions after every learned "
                     f"task 0..{m - 1} are needed; missing: {', '.join(missing)})", ds, m,
                     "write it, or pass --tasks K to score only the first K tasks")
    files: dict[str, str] = {}
    predictions: list[list[np.ndarray]] = []
    nonfinite: list[dict[str, Any]] = []
    for i in range(m):
        name = f"after_task_{i}.npz"
        path = source / name
        files[name] = sha256_file(path)
        with _open_npz(path, ds, m) as npz:
            keys = list(npz.files)
            for key in keys:
                if not _TASK_KEY.fullmatch(key):
                    raise _error(str(path), f"unknown key {key!r} (keys: {keys})", ds, m,
                                 f"name the arrays task_0 .. task_{i}")
            row = []
            for j in range(i + 1):
                key = f"task_{j}"
                if key not in keys:
                    raise _error(str(path), f"missing key {key!r} (the predictions of task {j} "
                                 f"{ds.tasks[j].name!r} after learning task {i}; keys: {keys})",
                                 ds, m, f"save every seen task task_0 .. task_{i}")
                row.append(_prediction(npz, key, str(path), ds.tasks[j], j, ds, m, nonfinite,
                                       name))
            predictions.append(row)
    fields: dict[str, Any] = {}
    meta = source / META_FILE
    if meta.is_file():
        files[META_FILE] = sha256_file(meta)
        try:
            raw = json.loads(meta.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise _error(str(meta), f"not readable JSON ({exc})", ds, m,
                         "fix it or remove it") from None
        if not isinstance(raw, dict):
            raise _error(str(meta), "must hold a JSON object of optional fields", ds, m,
                         f"the optional fields are {', '.join(OPTIONAL_FIELDS)}")
        fields = _check_fields(raw, m, str(meta), ds)
    return ExternalPredictions(source, "directory", files, predictions, fields, nonfinite)


def _read_npz(source: Path, ds: Dataset, tasks: int | None) -> ExternalPredictions:
    where = str(source)
    with _open_npz(source, ds, len(ds)) as npz:
        keys = list(npz.files)
        pairs: dict[tuple[int, int], str] = {}
        raw: dict[str, Any] = {}
        for key in keys:
            if mt := _NPZ_KEY.fullmatch(key):
                pairs[int(mt.group(1)), int(mt.group(2))] = key
            elif key.split("/")[0] not in OPTIONAL_FIELDS:
                raise _error(where, f"unknown key {key!r}", ds, len(ds),
                             "name the arrays after_task_<i>/task_<j>; optional fields: "
                             f"{', '.join(OPTIONAL_FIELDS)}")
        m = _tasks_wanted(sorted({i for i, _ in pairs}), tasks, ds, where)
        for key in keys:
            if key in pairs.values():
                continue
            name, _, part = key.partition("/")
            value = _array(npz, key, where, ds, m)
            if part:
                raw.setdefault(name, {})[part] = value
            else:
                raw[name] = value
        predictions: list[list[np.ndarray]] = []
        nonfinite: list[dict[str, Any]] = []
        for i in range(m):
            row = []
            for j in range(i + 1):
                key = f"after_task_{i}/task_{j}"
                if (i, j) not in pairs:
                    raise _error(where, f"missing key {key!r} (the predictions of task {j} "
                                 f"{ds.tasks[j].name!r} after learning task {i})", ds, m,
                                 f"save after_task_<i>/task_<j> for every 0 <= j <= i < {m}, "
                                 "or pass --tasks K to score only the first K tasks")
                row.append(_prediction(npz, key, where, ds.tasks[j], j, ds, m, nonfinite,
                                       source.name))
            predictions.append(row)
    fields = _check_fields(raw, m, where, ds)
    return ExternalPredictions(source, "npz", {source.name: sha256_file(source)}, predictions,
                               fields, nonfinite)


def read_predictions(source: str | os.PathLike[str], ds: Dataset,
                     tasks: int | None = None) -> ExternalPredictions:
    """Reads and checks predictions made elsewhere (module docstring: the format).

    Args:
        source: a directory of ``after_task_<i>.npz`` (+ optional ``meta.json``) or one
            ``.npz`` with keys ``after_task_<i>/task_<j>``.
        ds: the dataset, in the task order the predictions follow.
        tasks: score only the first K learned tasks (default: every ``after_task`` given).

    Returns:
        The predictions ``[i][j]`` ``[N_j, T, D]`` float64, their files' sha256s and the
        optional fields.

    Raises:
        PredictionsError: one line naming the file, the key and what is expected.
    """
    path = Path(source).absolute()
    if tasks is not None and (isinstance(tasks, bool) or not isinstance(tasks, int)
                              or not 1 <= tasks <= len(ds)):
        raise PredictionsError(f"--tasks {tasks}: must be an integer from 1 to {len(ds)} "
                               f"({ds.name} has {len(ds)} tasks)")
    if path.is_dir():
        return _read_directory(path, ds, tasks)
    if path.is_file():
        return _read_npz(path, ds, tasks)
    raise _error(str(path), "not found", ds, len(ds),
                 "pass a directory of after_task_<i>.npz files or one .npz")
