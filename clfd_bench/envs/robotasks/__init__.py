"""The RoboTasks environments (`clfd/BoxOpening-v3`, ..., `clfd/Scoop-v3`): one class,
`RoboTaskEnv(task=...)` (`clfd_bench.envs.robotasks.env`), and one folder per task.

- `registry`: the tasks, one line each; every per-task table is derived from it;
- `<task>/`: the task's scene, success predicate, docs, design constants and derivation
  (`registry` lists what each module holds);
- `common`, `placing`, `predicates`: what the scenes share (tables, supports, the grasp spec;
  props laid on a support, racks that must not be knocked; the shared success checks);
- `specs`: the task specs `tasks/<task>.toml` (reading, checking, writing);
- `env`: the env; `doc`: its docstring and tasks/README.md's table, from the tasks' docs;
- `derive`, `derive_common`: build time only, `eval/make_task_specs.py` derives the specs with
  them; no env imports them.

`RoboTaskEnv` is imported from here on first use, so that reading the registry stays cheap.
"""

from __future__ import annotations

from typing import Any

__all__ = ["RoboTaskEnv"]


def __getattr__(name: str) -> Any:
    if name == "RoboTaskEnv":
        from clfd_bench.envs.robotasks.env import RoboTaskEnv

        return RoboTaskEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
