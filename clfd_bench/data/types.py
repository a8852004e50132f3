"""The two types every later part of the project receives: :class:`Task` and :class:`Dataset`."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Dataset", "Task"]


@dataclass(frozen=True, eq=False)
class Task:
    """One skill: its demonstrations in one clean, documented form.

    Attributes:
        name: the task's file name upstream (``"h"``, ``"openbox"``, ``"Angle"``).
        dataset: the dataset's registered name (``"helloworld"``, ...).
        demos: ``[N, T, D]`` float64. ``D = 2`` for planar data (LASA, HelloWorld),
            ``D = 7`` for poses ``(px, py, pz, qw, qx, qy, qz)``: positions in :attr:`units`,
            unit quaternions scalar first.
        times: ``[T]`` time stamps in seconds, starting at 0: ``arange(T) / 60`` for the
            data recorded at 60 Hz, ``arange(T) * dt`` for LASA with the file's ``dt`` (the
            mean sampling period of its seven demos).
        goal: ``[D]`` where the demonstrations end. Positions: the common end point
            (identical for every demo of every dataset). Quaternion part: the normalised
            chordal mean of the demos' end orientations, which differ by up to ~25 deg
            between demos in RoboTasks (see :attr:`demo_goals`).
        demo_goals: ``[N, D]`` the last sample of each demo.
        units: ``"m"`` (HelloWorld, RoboTasks: converted from the files' cm) or ``"lasa"``
            (LASA's native units, the tablet's millimetre-like units, unchanged).
        sim_scale: metres per data unit used by the simulator to lay a planar shape on the
            writing surface (1.0 when the data are already metres).
        source: where the demonstrations were read from (a file path).
        sha256: the sha256 of that file.
        demo_times: ``[N, T]`` each demo's own time stamps in seconds (default: every demo
            on :attr:`times`). Only LASA has its own: each demo is resampled to 1000 points
            over its own duration (heee: 3.91 s to 5.99 s, mean 5.10 s = ``times[-1]``).
    """

    name: str
    dataset: str
    demos: np.ndarray
    times: np.ndarray
    goal: np.ndarray
    demo_goals: np.ndarray
    units: str
    sim_scale: float
    source: str
    sha256: str
    demo_times: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.demos.ndim != 3:
            raise ValueError(f"task {self.name!r}: demos must be [N, T, D], got {self.demos.shape}")
        n, t, d = self.demos.shape
        if self.times.shape != (t,):
            raise ValueError(f"task {self.name!r}: times must be [{t}], got {self.times.shape}")
        if self.demo_times is None:
            object.__setattr__(self, "demo_times", np.broadcast_to(self.times, (n, t)).copy())
        elif self.demo_times.shape != (n, t):
            raise ValueError(f"task {self.name!r}: demo_times must be [{n}, {t}], got "
                             f"{self.demo_times.shape}")
        if self.goal.shape != (d,) or self.demo_goals.shape != (n, d):
            raise ValueError(
                f"task {self.name!r}: goal shapes do not match demos {self.demos.shape}"
            )
        for arr in (self.demos, self.times, self.goal, self.demo_goals, self.demo_times):
            arr.setflags(write=False)

    @property
    def num_demos(self) -> int:
        """N, the number of demonstrations."""
        return int(self.demos.shape[0])

    @property
    def num_steps(self) -> int:
        """T, the number of samples per demonstration."""
        return int(self.demos.shape[1])

    @property
    def dim(self) -> int:
        """D, the dimension of one sample."""
        return int(self.demos.shape[2])

    @property
    def is_pose(self) -> bool:
        """True when samples are poses (position + quaternion), D = 7."""
        return self.dim == 7

    @property
    def positions(self) -> np.ndarray:
        """``[N, T, 3]`` for poses, ``[N, T, 2]`` for planar data (a view)."""
        return self.demos[..., :3] if self.is_pose else self.demos

    @property
    def quaternions(self) -> np.ndarray | None:
        """``[N, T, 4]`` unit quaternions (w, x, y, z) for poses, else ``None``."""
        return self.demos[..., 3:] if self.is_pose else None

    @property
    def dt(self) -> float:
        """The sampling period in seconds."""
        return float(self.times[1] - self.times[0])


@dataclass(frozen=True, eq=False)
class Dataset:
    """A sequence of tasks in one task order.

    Attributes:
        name: registered name (``lasa``, ``helloworld``, ``robotasks``, ``robotasks9``).
        order: the task order index (0, 1, 2: the paper's appendix table "Task orders";
            RoboTasks9 has only order 0, its upstream sequence file).
        tasks: the tasks in training order.
        source: the directory the files were read from.
        files: file name -> sha256 of every data file used (provenance).
    """

    name: str
    order: int
    tasks: tuple[Task, ...]
    source: str
    files: dict[str, str] = field(default_factory=dict)

    @property
    def task_names(self) -> list[str]:
        """Task names in training order."""
        return [t.name for t in self.tasks]

    def task(self, name: str) -> Task:
        """The task called ``name``; a KeyError lists the valid names."""
        for t in self.tasks:
            if t.name == name:
                return t
        raise KeyError(f"dataset {self.name!r} has no task {name!r}; tasks: {self.task_names}")

    def __len__(self) -> int:
        return len(self.tasks)

    def __getitem__(self, index: int) -> Task:
        return self.tasks[index]

    def __iter__(self) -> Iterator[Task]:
        return iter(self.tasks)
