"""Learners: what turns a :class:`~clfd_bench.data.Task` into NODE training data and back.

* :class:`PartLearner` is one learned model: ``position`` (planar points or 3-D positions,
  normalised per task with the task's mean/std) or ``orientation`` (unit quaternions mapped
  to tangent vectors ``Log(conj(q_g) * q)``, see :mod:`clfd_bench.learning.tangent`).
* :class:`Learner` holds the parts of a run (RoboTasks: one position and one orientation
  model trained with the same CL method, as in the paper) and predicts full trajectories in
  data units: ``[N, T, 2]`` planar, ``[N, T, 7]`` poses (metres, unit quaternions w, x, y, z).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch
from torch import Tensor

from clfd_bench.data.types import Task
from clfd_bench.harness.config import PartConfig, RunConfig
from clfd_bench.harness.loop import (
    TrainingDivergedError,
    TrainStats,
    solver_blew_up,
    solver_spec,
    train_task,
)
from clfd_bench.learning.node import NodeSpec
from clfd_bench.learning.normalize import Normalizer
from clfd_bench.learning.odeint import integrate
from clfd_bench.learning.tangent import quat_exp_relative, quat_log_relative
from clfd_bench.methods import Method, TaskData, get_method_class

__all__ = ["Learner", "PartLearner"]


class PartLearner:
    """One NODE model of a run (``kind`` = ``position`` or ``orientation``).

    Args:
        kind: ``position`` or ``orientation``.
        method: the CL method instance (owns the network weights).
        cfg: the part's hyperparameters.
    """

    def __init__(self, kind: str, method: Method, cfg: PartConfig):
        if kind not in ("position", "orientation"):
            raise ValueError(f"part kind must be position or orientation, got {kind!r}")
        self.kind, self.method, self.cfg = kind, method, cfg
        self.normalizers: list[Normalizer] = []
        self.goals: list[np.ndarray | None] = []  # orientation: the task goal quaternion

    # -- data conversion --------------------------------------------------------------
    def _raw(self, task: Task) -> tuple[np.ndarray, np.ndarray | None]:
        """The task's demos in this part's space (before normalisation) and the goals."""
        if self.kind == "position":
            return np.asarray(task.positions), None
        quats = task.quaternions
        if quats is None:
            raise ValueError(f"task {task.name!r} has no orientations to learn")
        goals = task.demo_goals[:, 3:] if self.cfg.tangent_goal == "demo" else task.goal[3:]
        return quat_log_relative(quats, goals), goals

    def task_data(self, task: Task) -> tuple[TaskData, Normalizer]:
        """Training data of ``task`` and the normaliser fitted on it."""
        raw, _ = self._raw(task)
        norm = Normalizer.fit(raw) if self.cfg.normalize else Normalizer.identity(raw.shape[-1])
        demos = torch.as_tensor(norm.apply(raw), dtype=torch.float32)
        times = torch.tensor(np.asarray(task.times), dtype=torch.float32)
        return TaskData(demos, times), norm

    # -- training ---------------------------------------------------------------------
    def learn(self, index: int, task: Task, generator: torch.Generator, desc: str) -> TrainStats:
        """Add task ``index`` to the model and train it (the global RNG is seeded by the caller)."""
        if index != self.method.num_tasks:
            raise ValueError(f"tasks are learned in order: expected task {self.method.num_tasks}, "
                             f"got {index}")
        data, norm = self.task_data(task)
        self.method.add_task()
        self.normalizers.append(norm)
        self.goals.append(None if self.kind == "position" else np.asarray(task.goal[3:]))
        return train_task(self.method, index, data, self.cfg, generator, desc=desc)

    # -- prediction -------------------------------------------------------------------
    @torch.no_grad()
    def predict(
        self,
        index: int,
        starts: np.ndarray,
        times: np.ndarray,
        goals: np.ndarray | None = None,
    ) -> np.ndarray:
        """Integrate task ``index``'s NODE from ``starts`` over ``times``.

        Args:
            starts: ``[N, 2|3]`` positions, or ``[N, 4]`` quaternions for orientation.
            times: ``[T]`` seconds (the NODE^T time input), starting where the starts are.
            goals: orientation only: ``[N, 4]`` or ``[4]`` goal quaternions for the tangent
                map; default: the task's goal (for ``tangent_goal = "demo"`` pass each demo's
                final quaternion to reproduce the paper's protocol).

        Returns:
            ``[N, T, 2|3]`` positions or ``[N, T, 4]`` unit quaternions, in data units.
        """
        if not 0 <= index < self.method.num_tasks:
            raise IndexError(f"task {index} not learned (learned: {self.method.num_tasks})")
        starts = np.asarray(starts, dtype=np.float64)
        if self.kind == "orientation":
            goals = self.goals[index] if goals is None else np.asarray(goals, dtype=np.float64)
            starts = quat_log_relative(starts, goals)
        norm = self.normalizers[index]
        y0 = torch.as_tensor(norm.apply(starts), dtype=torch.float32)
        t = torch.tensor(np.array(times, dtype=np.float64), dtype=torch.float32)
        self.method.eval()
        try:
            out = integrate(self.method.field(index), y0, t, solver_spec(self.cfg, evaluation=True))
        except (FloatingPointError, AssertionError, RuntimeError) as exc:
            if not solver_blew_up(exc):
                raise
            raise TrainingDivergedError(
                f"the trained {self.kind} model of task {index} diverged when predicting "
                f"({exc}); lower lr (now {self.cfg.lr:g}) or use a more accurate eval_solver",
                self.method.num_tasks - 1,
            ) from exc
        traj = norm.invert(out.double().numpy())
        if self.kind == "orientation":
            traj = quat_exp_relative(traj, goals)
        return traj

    # -- checkpoint -------------------------------------------------------------------
    def header(self) -> dict[str, Any]:
        """Plain data needed to rebuild this part (besides the tensors)."""
        return {
            "kind": self.kind,
            "num_tasks": self.method.num_tasks,
            "normalizers": [n.to_list() for n in self.normalizers],
            "goals": [None if g is None else g.tolist() for g in self.goals],
        }

    def restore(self, header: Mapping[str, Any], tensors: Mapping[str, Tensor]) -> None:
        """Load a checkpointed state (inverse of :meth:`header` + ``method.state_dict()``)."""
        self.method.prepare_tasks(header["num_tasks"], tensors)
        self.method.load_state_dict(dict(tensors), strict=True)
        self.normalizers = [Normalizer.from_list(n) for n in header["normalizers"]]
        self.goals = [None if g is None else np.asarray(g) for g in header["goals"]]


class Learner:
    """The models of a run (one per part) and how to predict whole trajectories.

    Build with :meth:`from_config`; the global torch RNG should be seeded first so the
    initial weights are reproducible.
    """

    def __init__(self, config: RunConfig, parts: Sequence[PartLearner]):
        self.config = config
        self.parts = {p.kind: p for p in parts}

    @classmethod
    def from_config(cls, config: RunConfig, dim: int) -> Learner:
        """Build the method instances for every part of ``config``.

        Args:
            dim: the data dimension (2 planar, 7 poses).
        """
        method_cls = get_method_class(config.method)
        parts = []
        for kind, cfg in config.parts:
            part_dim = (2 if dim == 2 else 3)
            spec = NodeSpec(dim=part_dim, hidden=cfg.node_hidden, time_input=config.node == "t",
                            activation=cfg.activation)
            parts.append(PartLearner(kind, method_cls(spec, cfg), cfg))
        if dim == 7 and set(p.kind for p in parts) != {"position", "orientation"}:
            raise ValueError("pose data needs a position and an orientation part")
        return cls(config, parts)

    @property
    def is_pose(self) -> bool:
        return "orientation" in self.parts

    @property
    def num_tasks(self) -> int:
        return min(p.method.num_tasks for p in self.parts.values())

    def predict(
        self,
        index: int,
        starts: np.ndarray,
        times: np.ndarray,
        goals: np.ndarray | None = None,
    ) -> np.ndarray:
        """Trajectories of task ``index`` from ``starts``.

        Args:
            starts: ``[N, D]`` in data units (D = 2, or 7 = position + quaternion w, x, y, z).
            times: ``[T]`` seconds from the start.
            goals: poses only: ``[N, 4]`` goal quaternions for the tangent map (default: the
                task goal; the protocol passes each demo's final quaternion when the config's
                ``tangent_goal`` is ``demo``).

        Returns:
            ``[N, T, D]`` in data units.
        """
        starts = np.asarray(starts, dtype=np.float64)
        if starts.ndim != 2:
            raise ValueError(f"starts must be [N, D], got shape {starts.shape}")
        if not self.is_pose:
            return self.parts["position"].predict(index, starts, times)
        if starts.shape[1] != 7:
            raise ValueError(
                f"pose starts must be [N, 7] (position + w, x, y, z), got {starts.shape}"
            )
        pos = self.parts["position"].predict(index, starts[:, :3], times)
        quat = self.parts["orientation"].predict(index, starts[:, 3:], times, goals)
        return np.concatenate([pos, quat], axis=-1)

    def demo_goals(self, task: Task) -> np.ndarray | None:
        """The goals the protocol passes for ``task``'s demos (None for planar data)."""
        if not self.is_pose:
            return None
        if self.parts["orientation"].cfg.tangent_goal == "demo":
            return np.asarray(task.demo_goals[:, 3:])
        return None
