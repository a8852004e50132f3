"""Gymnasium registration of every clfd-bench environment (namespace `clfd`).

Ids (each env has its own version, `env_version(name)`; the RoboTasks scenes are `-v2`, the
writing envs `-v3` today):

| id | task | entry point |
|---|---|---|
| `clfd/<EnvName>-v3` | a RoboTasks(9) task (`robotasks.registry`) | `...robotasks:RoboTaskEnv` |
| `clfd/HelloWorld-<letter>-v3` | letter h,e,l,o,w,r,d | `...writing:HelloWorldLetterEnv` |
| `clfd/HelloWorld-v3` | a text (default "hello world") | `...writing:HelloWorldTextEnv` |
| `clfd/LASA-<Shape>-v3` | the paper's 26 LASA shapes | `...writing:LasaShapeEnv` |

LASA shape names map to ids unchanged (e.g. `clfd/LASA-JShape_2-v3`, `clfd/LASA-heee-v3`): every
one of the paper's 26 names uses only letters, digits and `_`, which Gymnasium ids allow.
`lasa_env_name` refuses names with other characters rather than guess a mapping.

The RoboTasks ids come from `clfd_bench.envs.robotasks.registry.TASKS` (env name and dataset
task of each: `clfd/BoxOpening-v3` runs `openbox`, ..., `clfd/Scoop-v3` runs `scoop`).

`register_envs()` is idempotent and imports no env module (entry points are strings), so
registering is cheap; a missing entry point fails when that id is made.
"""

from __future__ import annotations

import re

import gymnasium as gym

from clfd_bench.data.orders import TASK_ORDERS
from clfd_bench.envs.robotasks.registry import TASKS as ROBOTASKS

NAMESPACE = "clfd"

#: RoboTasks env name -> dataset task name (`clfd_bench.envs.robotasks.registry.TASKS`).
ROBOTASKS_ENVS: dict[str, str] = {t.env_name: t.name for t in ROBOTASKS}
ROBOTASKS_ENTRY_POINT = "clfd_bench.envs.robotasks:RoboTaskEnv"
#: The seven letters, in the paper's order 0 (the data layer's `TASK_ORDERS`, written once).
HELLOWORLD_LETTERS: tuple[str, ...] = TASK_ORDERS["helloworld"][0]
#: The paper's 26 LASA shapes, alphabetical, case-insensitive (as the data layer orders them).
LASA_SHAPES: tuple[str, ...] = tuple(sorted(TASK_ORDERS["lasa"][0], key=str.lower))
WRITING_MODULE = "clfd_bench.envs.writing"
#: Version of each family of envs; a behaviour change bumps the version of what it changes
#: (and adds a line to the env class's Version History). Gymnasium then refuses the old id
#: with a message naming the new one.
FAMILY_VERSIONS: dict[str, int] = {"robotasks": 3, "letters": 3, "text": 3, "lasa": 3}
#: Versions of single envs that moved on without their family, e.g. {"Pouring": 2}.
ENV_VERSIONS: dict[str, int] = {}
_VALID_NAME = re.compile(r"^[A-Za-z0-9_]+$")


def env_version(name: str) -> int:
    """The current version of env `name` (the id without namespace and version, e.g.
    "BoxOpening", "HelloWorld-h", "LASA-Angle"): its entry in `ENV_VERSIONS`, else the
    version of its family (`FAMILY_VERSIONS`: "robotasks", "letters", "text", "lasa")."""
    if name in ENV_VERSIONS:
        return ENV_VERSIONS[name]
    if name in ROBOTASKS_ENVS:
        return FAMILY_VERSIONS["robotasks"]
    if name == "HelloWorld":
        return FAMILY_VERSIONS["text"]
    if name.startswith("HelloWorld-"):
        return FAMILY_VERSIONS["letters"]
    if name.startswith("LASA-"):
        return FAMILY_VERSIONS["lasa"]
    raise KeyError(f"no clfd-bench env named {name!r}")


def _env_id(name: str) -> str:
    return f"{NAMESPACE}/{name}-v{env_version(name)}"


def lasa_env_name(shape: str) -> str:
    """The id part of a LASA shape (the name itself; it must be letters, digits and `_`)."""
    if not _VALID_NAME.match(shape):
        raise ValueError(f"LASA shape name {shape!r} has characters a Gymnasium id cannot hold; "
                         "only letters, digits and '_' are supported")
    return f"LASA-{shape}"


def env_specs() -> dict[str, tuple[str, dict]]:
    """Every clfd-bench env: {id: (entry point, kwargs)}."""
    specs: dict[str, tuple[str, dict]] = {}
    for name, task in ROBOTASKS_ENVS.items():
        specs[_env_id(name)] = (ROBOTASKS_ENTRY_POINT, {"task": task})
    for letter in HELLOWORLD_LETTERS:
        specs[_env_id(f"HelloWorld-{letter}")] = (f"{WRITING_MODULE}:HelloWorldLetterEnv",
                                                  {"letter": letter})
    specs[_env_id("HelloWorld")] = (f"{WRITING_MODULE}:HelloWorldTextEnv", {})
    for shape in LASA_SHAPES:
        specs[_env_id(lasa_env_name(shape))] = (f"{WRITING_MODULE}:LasaShapeEnv",
                                                {"shape": shape})
    return specs


def register_envs() -> list[str]:
    """Registers every clfd-bench id with Gymnasium (idempotent). Returns the ids."""
    ids = []
    for env_id, (entry_point, kwargs) in env_specs().items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=entry_point, kwargs=dict(kwargs))
        ids.append(env_id)
    return ids


def registered_env_ids() -> list[str]:
    """The clfd-bench ids currently in the Gymnasium registry, sorted."""
    return sorted(i for i in gym.registry if i.startswith(f"{NAMESPACE}/"))


def env_id_for(dataset: str, task_name: str) -> str:
    """The env id that executes a task of a dataset.

    Args:
        dataset: "helloworld", "lasa", "robotasks" or "robotasks9".
        task_name: the data layer's task name ("h", "Angle", "openbox", ...).

    Raises:
        KeyError: the dataset or task has no env; the message lists the valid names.
    """
    ds = dataset.lower()
    if ds == "helloworld":
        if task_name not in HELLOWORLD_LETTERS:
            raise KeyError(f"HelloWorld has no letter {task_name!r}; valid: {HELLOWORLD_LETTERS}")
        return _env_id(f"HelloWorld-{task_name}")
    if ds == "lasa":
        if task_name not in LASA_SHAPES:
            raise KeyError(f"no LASA env for shape {task_name!r}; valid: {LASA_SHAPES}")
        return _env_id(lasa_env_name(task_name))
    if ds in ("robotasks", "robotasks9"):
        by_task = {task: name for name, task in ROBOTASKS_ENVS.items()}
        if task_name not in by_task:
            raise KeyError(f"no simulated env for {dataset} task {task_name!r}; tasks with an env: "
                           f"{sorted(by_task)}")
        return _env_id(by_task[task_name])
    raise KeyError(f"no envs for dataset {dataset!r}; valid: ['helloworld', 'lasa', 'robotasks', "
                   "'robotasks9']")
