"""Replay dataset demonstrations (optionally perturbed) through an environment.

Checks the envs' success criteria both ways: every demonstration should succeed, and wrong
trajectories should fail: `reverse` (the demo time-reversed), `other-task` (demo j of the next
task of the same dataset, in the data layer's task order, cyclically) and `truncate` (the first
50 % of the demo).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from clfd_bench.envs.base import PandaEnv, load_task
from clfd_bench.sim.rollout import DEFAULT_SETTLE_S, rollout

PERTURBATIONS = ("reverse", "other-task", "truncate")
TRUNCATE_FRACTION = 0.5


@dataclasses.dataclass
class ReplayRecord:
    """One replayed demo: `success`, the env's decisive info entries, wall and simulated time."""

    env_id: str
    demo: int
    perturb: str | None
    success: bool
    info: dict[str, Any]
    wall_s: float
    sim_s: float
    max_tracking_error_m: float

    def to_json(self) -> dict[str, Any]:
        return {"env": self.env_id, "demo": self.demo, "perturb": self.perturb,
                "success": self.success, "info": _jsonable(self.info), "wall_s": self.wall_s,
                "sim_s": self.sim_s, "max_tracking_error_m": self.max_tracking_error_m}


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else str(v)
    if isinstance(x, (np.integer, np.bool_)):
        return x.item()
    return x


def _other_task_name(dataset: str, task_name: str) -> str:
    from clfd_bench.data import load_dataset

    names = list(load_dataset(dataset).task_names)
    return names[(names.index(task_name) + 1) % len(names)]


def _perturb_one(traj: np.ndarray, perturb: str, other: np.ndarray | None) -> np.ndarray:
    if perturb == "reverse":
        return traj[::-1].copy()
    if perturb == "truncate":
        return traj[: max(1, int(len(traj) * TRUNCATE_FRACTION))].copy()
    if perturb == "other-task":
        assert other is not None
        return other.copy()
    raise ValueError(f"unknown perturbation {perturb!r}; valid: {PERTURBATIONS}")


def replay_trajectory(env: PandaEnv, demo: int, perturb: str | None = None
                      ) -> np.ndarray | list[np.ndarray]:
    """The trajectory `clfd-bench replay` runs for demo `demo` of `env` (data units), perturbed
    as asked (see the module docstring)."""
    traj = env.demo_trajectory(demo)
    if perturb is None:
        return traj
    if perturb not in PERTURBATIONS:
        raise ValueError(f"unknown perturbation {perturb!r}; valid: {PERTURBATIONS}")
    if isinstance(traj, list):  # HelloWorld text: one trajectory per letter
        others: list[np.ndarray | None] = [None] * len(traj)
        if perturb == "other-task":
            letters = env.letters  # HelloWorldTextEnv
            others = [np.asarray(load_task(env.dataset, _other_task_name(env.dataset, c))
                                 .demos[demo], dtype=float) for c in letters]
        return [_perturb_one(np.asarray(t), perturb, o) for t, o in zip(traj, others,
                                                                       strict=True)]
    other = None
    if perturb == "other-task":
        name = _other_task_name(env.dataset, env.task_name)
        other = np.asarray(load_task(env.dataset, name).demos[demo], dtype=float)
    return _perturb_one(np.asarray(traj), perturb, other)


def replay(env_id: str, demos: Sequence[int] | None = None, perturb: str | None = None,
           settle_s: float = DEFAULT_SETTLE_S, env: gym.Env | None = None,
           **env_kwargs: Any) -> list[ReplayRecord]:
    """Replays demos of `env_id` (all when `demos` is None), perturbed as asked.

    Returns:
        One `ReplayRecord` per demo.
    """
    import clfd_bench.envs  # noqa: F401 - registers the ids

    own = env is None
    env = env if env is not None else gym.make(env_id, **env_kwargs)
    try:
        base = env.unwrapped
        if not isinstance(base, PandaEnv):
            raise TypeError(f"{env_id} is not a clfd-bench env")
        demo_ids = list(range(base.num_demos)) if demos is None else list(demos)
        bad = [j for j in demo_ids if not 0 <= j < base.num_demos]
        if bad:
            raise ValueError(f"{env_id} has demos 0..{base.num_demos - 1}; got {bad}")
        records = []
        for j in demo_ids:
            traj = replay_trajectory(base, j, perturb)
            t0 = time.perf_counter()
            result = rollout(env, traj, demo=j, settle_s=settle_s)
            wall = time.perf_counter() - t0
            records.append(ReplayRecord(
                env_id=env_id, demo=j, perturb=perturb, success=result.success,
                info={k: v for k, v in result.info.items()
                      if k not in ("tracking_error", "ik_error")},
                wall_s=wall, sim_s=result.steps * base.control_dt,
                max_tracking_error_m=float(np.nanmax(result.tracking_error_pos))))
        return records
    finally:
        if own:
            env.close()
