"""Gymnasium environments of clfd-bench (namespace `clfd`).

`register_envs()` (called on `import clfd_bench`) registers every id; `env_id_for(dataset, task)`
finds the env of a dataset task. The env classes live in `clfd_bench.envs.base` (`PandaEnv`, the
shared loop), `clfd_bench.envs.writing` (HelloWorld, LASA) and `clfd_bench.envs.robotasks`
(RoboTasks scenes, one folder per task, listed in `clfd_bench.envs.robotasks.registry`); they
are imported only when an env is made.
"""

from clfd_bench.envs.registration import (
    env_id_for,
    env_specs,
    register_envs,
    registered_env_ids,
)

__all__ = ["env_id_for", "env_specs", "register_envs", "registered_env_ids"]
