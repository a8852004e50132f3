"""The RoboTasks tasks: one line each. Every per-task table of the benchmark is derived from
`TASKS` (env ids and their registration, the task specs' datasets, the scenes, the
derivations, the docs, the own perturbation variants, the simulation-speed benchmark and the
motion-limit calibration), so adding a task is its folder `clfd_bench/envs/robotasks/<name>/`,
its assets `tasks/<name>.xml` and `tasks/<name>.toml` (generated), and one line here.

A task's folder holds, by name:

- `scene.py`: `SCENE`, its scene class (`clfd_bench.envs.robotasks.common.Scene`);
- `success.py`: its success predicate, a pure function of the measured quantities and the
  spec's bounds that returns the `clfd_bench.envs.checks.Check`s;
- `doc.py`: its paragraphs of the env's docstring and of tasks/README.md (the success rules,
  written once), the numbers they quote (`numbers`), and `CALIBRATION` (None, or what the
  motion-limit check of a task added after the calibration found);
- `derive.py`: `DESIGN` (its design constants, over the shared defaults), `OBSERVER` (the
  observer's argument for each design constant of a criterion) and `derive` (its scene and
  thresholds from the demonstrations; build time only, see `derive_spec`);
- `variants.py` (optional): `VARIANTS`, its own right and wrong trajectories
  (`clfd_bench.execution.task_variants`).

This module imports nothing heavy: registering the envs reads it.
"""

from __future__ import annotations

import dataclasses
import importlib
from types import ModuleType

__all__ = ["TASKS", "RoboTask", "by_env_name", "by_name", "task_module"]


@dataclasses.dataclass(frozen=True)
class RoboTask:
    """One simulated RoboTasks task.

    Attributes:
        name: the dataset's task name, also its folder and its assets' name ("openbox").
        env_name: the env id's name ("BoxOpening": `clfd/BoxOpening-v<version>`).
        dataset: the dataset of its demonstrations ("robotasks", "robotasks9").
    """

    name: str
    env_name: str
    dataset: str

    @property
    def package(self) -> str:
        """The task's folder as a module path."""
        return f"{__package__}.{self.name}"


TASKS: tuple[RoboTask, ...] = (
    RoboTask("openbox", "BoxOpening", "robotasks"),
    RoboTask("bottle2shelf", "BottleShelving", "robotasks"),
    RoboTask("platestandingtolying", "PlateStacking", "robotasks"),
    RoboTask("pouring", "Pouring", "robotasks"),
    RoboTask("wineglass", "WineGlass", "robotasks9"),
    RoboTask("pan2stove", "PanToStove", "robotasks9"),
    RoboTask("obstaclerotate", "ObstacleRotate", "robotasks9"),
    RoboTask("matfolding", "MatFolding", "robotasks9"),
    RoboTask("scoop", "Scoop", "robotasks9"),
)


def by_name(name: str) -> RoboTask:
    """The task named `name` ("openbox").

    Raises:
        KeyError: no such task (lists the valid ones).
    """
    for task in TASKS:
        if task.name == name:
            return task
    raise KeyError(f"no RoboTasks task {name!r}; valid: {[t.name for t in TASKS]}")


def by_env_name(env_name: str) -> RoboTask:
    """The task of env name `env_name` ("BoxOpening").

    Raises:
        KeyError: no such env (lists the valid ones).
    """
    for task in TASKS:
        if task.env_name == env_name:
            return task
    raise KeyError(f"no RoboTasks env {env_name!r}; valid: {[t.env_name for t in TASKS]}")


def task_module(name: str, part: str, optional: bool = False) -> ModuleType | None:
    """Module `part` ("scene", "doc", "derive", "variants", ...) of task `name`'s folder; with
    `optional`, None when the task has no such module."""
    package = by_name(name).package
    try:
        return importlib.import_module(f"{package}.{part}")
    except ModuleNotFoundError as exc:
        if optional and exc.name == f"{package}.{part}":
            return None
        raise
