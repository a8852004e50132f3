"""Learners: what turns a :class:`~clfd_bench.data.Task` into NODE training data and back.

* :class:`PartLearner` is one learned model: ``position`` (planar points or 3-D positions,
  normalised per task with the task's mean/std; a stable NODE's with the task's goal in
  place of the mean, so that the goal is the origin its field converges to) or
  ``orientation`` (unit quaternions mapped to tangent vectors ``Log(conj(q_g) * q)``, see
  :mod:`clfd_bench.learning.tangent`, times the config's ``tangent_scale``). Its time axis
  is the task's ``times`` or, with ``time_axis = "first_demo"``, the first demo's own time
  stamps; prediction times are given on the data's axis and mapped onto the NODE's.
* :class:`Learner` holds the parts of a run (RoboTasks: one position and one orientation
  model trained with the same CL method, as in the paper) and predicts full trajectories in
  data units: ``[N, T, 2]`` planar, ``[N, T, 7]`` poses (metres, unit quaternions w, x, y, z).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch
from torch import Tensor

from clfd_bench.data.types import Task
from clfd_bench.harness.config import PartConfig
from clfd_bench.harness.loop import (
    TrainingDivergedError,
    solver_blew_up,
    solver_spec,
)
from clfd_bench.harness.run_config import RunConfig
from clfd_bench.learning.batches import subsample_index
from clfd_bench.learning.node import NodeSpec
from clfd_bench.learning.normalize import Normalizer
from clfd_bench.learning.odeint import FIXED_SOLVERS, SolverSpec, integrate
from clfd_bench.learning.stable import StableSpec
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
        if kind == "position" and cfg.tangent_scale != 1.0:
            raise ValueError(f"tangent_scale = {cfg.tangent_scale:g} is for orientation "
                             "models; a position model needs tangent_scale = 1")
        self.kind, self.method, self.cfg = kind, method, cfg
        self.normalizers: list[Normalizer] = []
        self.goals: list[np.ndarray | None] = []  # orientation: the task goal quaternion
        self.time_factors: list[float] = []  # NODE time = data time * factor, per task

    # -- data conversion --------------------------------------------------------------
    def _to_raw(self, states: np.ndarray, goals: np.ndarray | None) -> np.ndarray:
        """Data units -> this part's NODE space before normalisation: positions unchanged,
        quaternions ``[..., 4]`` -> ``Log(conj(q_g) * q) * tangent_scale`` ``[..., 3]``."""
        if self.kind == "position":
            return states
        return quat_log_relative(states, goals) * self.cfg.tangent_scale

    def _from_raw(self, raw: np.ndarray, goals: np.ndarray | None) -> np.ndarray:
        """Inverse of :meth:`_to_raw`: tangent vectors are divided by ``tangent_scale``
        before the Exp map, so predictions are in data units whatever the scale."""
        if self.kind == "position":
            return raw
        return quat_exp_relative(raw / self.cfg.tangent_scale, goals)

    def _raw(self, task: Task) -> np.ndarray:
        """The task's demos in this part's space (before normalisation)."""
        if self.kind == "position":
            return np.asarray(task.positions)
        quats = task.quaternions
        if quats is None:
            raise ValueError(f"task {task.name!r} has no orientations to learn")
        goals = task.demo_goals[:, 3:] if self.cfg.tangent_goal == "demo" else task.goal[3:]
        return self._to_raw(quats, goals)

    def train_times(self, task: Task) -> np.ndarray:
        """``[T]`` the NODE's time stamps of ``task``'s samples (``time_axis``)."""
        if self.cfg.time_axis == "first_demo":
            return np.asarray(task.demo_times[0], dtype=np.float64)
        return np.asarray(task.times, dtype=np.float64)

    def time_factor(self, task: Task) -> float:
        """NODE time per second of ``task.times``: 1, or for ``first_demo`` the ratio of the
        first demo's sampling period to the task's (heee: 3.91 s / 5.10 s = 0.767).

        Raises:
            ValueError: the first demo's stamps are not ``task.times`` times one factor
                (not evenly sampled, or not starting at 0).
        """
        if self.cfg.time_axis == "uniform":
            return 1.0
        node_t, data_t = self.train_times(task), np.asarray(task.times, dtype=np.float64)
        factor = float(node_t[-1] / data_t[-1])
        if not np.allclose(node_t, factor * data_t, rtol=1e-9, atol=1e-12):
            raise ValueError(
                f"task {task.name!r}: the first demo's time stamps are not the task's times "
                f"scaled by one factor, which time_axis = first_demo needs; use "
                f"time_axis = uniform"
            )
        return factor

    @property
    def stable(self) -> bool:
        """Whether this part learns a stable NODE (its goal must be the origin)."""
        return isinstance(self.method.node_spec, StableSpec)

    def _goal_raw(self, task: Task) -> np.ndarray:
        """The task's goal in this part's space before normalisation: the common end point
        of the positions; for orientation the tangent vector of the goal itself, 0."""
        if self.kind == "position":
            return np.asarray(task.goal[: task.positions.shape[-1]], dtype=np.float64)
        return np.zeros(3)

    def task_data(self, task: Task) -> tuple[TaskData, Normalizer]:
        """Training data of ``task`` and the normaliser fitted on it (a stable NODE's is
        centred on the goal instead of the mean)."""
        raw = self._raw(task)
        norm = Normalizer.fit(raw) if self.cfg.normalize else Normalizer.identity(raw.shape[-1])
        if self.stable:
            norm = Normalizer(mean=self._goal_raw(task), std=norm.std)
        demos = torch.as_tensor(norm.apply(raw), dtype=torch.float32)
        times = torch.tensor(self.train_times(task), dtype=torch.float32)
        return TaskData(demos, times), norm

    def node_states(self, index: int, states: np.ndarray,
                    goals: np.ndarray | None = None) -> np.ndarray:
        """Data-unit states of task ``index`` as its NODE sees them (tangent map, scale,
        normaliser): ``[N, 2|3]`` positions or ``[N, 4]`` quaternions -> ``[N, 2|3]``.

        Args:
            goals: orientation only, as for :meth:`predict` (default: the task's goal).
        """
        states = np.asarray(states, dtype=np.float64)
        if self.kind == "orientation":
            goals = self.goals[index] if goals is None else np.asarray(goals, dtype=np.float64)
        return self.normalizers[index].apply(self._to_raw(states, goals))

    def data_states(self, index: int, states: np.ndarray,
                    goals: np.ndarray | None = None) -> np.ndarray:
        """Inverse of :meth:`node_states`: NODE states ``[..., 2|3]`` of task ``index`` ->
        data units (orientation: divided by ``tangent_scale``, then the Exp map)."""
        if self.kind == "orientation":
            goals = self.goals[index] if goals is None else np.asarray(goals, dtype=np.float64)
        raw = self.normalizers[index].invert(np.asarray(states, dtype=np.float64))
        return self._from_raw(raw, goals)

    def node_times(self, index: int, times: np.ndarray) -> np.ndarray:
        """Times on the data's axis (seconds, e.g. ``task.times``) -> the NODE's axis."""
        return np.asarray(times, dtype=np.float64) * self.time_factors[index]

    # -- training ---------------------------------------------------------------------
    def add_task(self, task: Task) -> TaskData:
        """Add ``task`` to the model untrained (its normaliser, goal and time factor) and
        return its training data."""
        data, norm = self.task_data(task)
        factor = self.time_factor(task)
        self.method.add_task()
        self.normalizers.append(norm)
        self.time_factors.append(factor)
        self.goals.append(None if self.kind == "position" else np.asarray(task.goal[3:]))
        return data

    def add_next(self, index: int, task: Task) -> TaskData:
        """:meth:`add_task` for task ``index``, which must be the next one (tasks are learned
        in order); the global RNG is seeded by the caller."""
        if index != self.method.num_tasks:
            raise ValueError(f"tasks are learned in order: expected task {self.method.num_tasks}, "
                             f"got {index}")
        return self.add_task(task)

    # -- prediction -------------------------------------------------------------------
    @torch.no_grad()
    def predict(
        self,
        index: int,
        starts: np.ndarray,
        times: np.ndarray,
        goals: np.ndarray | None = None,
        solver: SolverSpec | None = None,
    ) -> np.ndarray:
        """Integrate task ``index``'s NODE from ``starts`` over ``times``.

        Args:
            starts: ``[N, 2|3]`` positions, or ``[N, 4]`` quaternions for orientation.
            times: ``[T]`` seconds on the data's time axis (``task.times`` reproduces the
                demos), starting where the starts are; mapped onto the NODE's axis
                (:meth:`node_times`) for the NODE^T time input.
            goals: orientation only: ``[N, 4]`` or ``[4]`` goal quaternions for the tangent
                map; default: the task's goal (for ``tangent_goal = "demo"`` pass each demo's
                final quaternion to reproduce the paper's protocol).
            solver: how to integrate (default: the config's ``eval_solver``).

        Returns:
            ``[N, T, 2|3]`` positions or ``[N, T, 4]`` unit quaternions, in data units.
        """
        if not 0 <= index < self.method.num_tasks:
            raise IndexError(f"task {index} not learned (learned: {self.method.num_tasks})")
        y0 = torch.as_tensor(self.node_states(index, starts, goals), dtype=torch.float32)
        t = torch.tensor(self.node_times(index, times), dtype=torch.float32)
        self.method.eval()
        try:
            out = integrate(self.method.field(index), y0, t,
                            solver or solver_spec(self.cfg, evaluation=True))
        except (FloatingPointError, AssertionError, RuntimeError) as exc:
            if not solver_blew_up(exc):
                raise
            raise TrainingDivergedError(
                f"the trained {self.kind} model of task {index} diverged when predicting "
                f"({exc}); lower lr (now {self.cfg.lr:g}) or use a more accurate eval_solver",
                self.method.num_tasks - 1,
            ) from exc
        return self.data_states(index, out.double().numpy(), goals)

    def solver_gap(self, index: int, task: Task, goals: np.ndarray | None = None,
                   fine: np.ndarray | None = None, substeps: int | None = None
                   ) -> float | None:
        """How far task ``index``'s model, integrated as training integrates it, is from the
        same model integrated as predictions are: the largest distance over the demos' starts
        and the training samples (positions: data units; orientation: degrees). A fixed-step
        training solver (``trajectories`` batches: one step, or ``substeps``, per subsampled
        interval) sees the field only at its stages, so a field can fit the demos through
        those steps while its ODE, solved finely, does something else in between; the
        prediction is the ODE's. None where training's steps follow the solution (adaptive
        solvers) or are the data's own (``windows``).

        Args:
            goals: orientation only, as for :meth:`predict`.
            fine: this part's prediction of the task from its demos' starts over
                ``task.times`` (:meth:`predict`), if already made; else it is made here.
            substeps: the training solver's steps per interval (default the config's; a
                task ``refine_gap`` refined was trained with more).
        """
        cfg = self.cfg
        if cfg.solver not in FIXED_SOLVERS or cfg.batch != "trajectories":
            return None
        times = np.asarray(task.times, dtype=np.float64)
        idx = subsample_index(len(times), cfg.points)
        raw = task.positions if self.kind == "position" else task.quaternions
        starts = np.asarray(raw)[:, 0]
        coarse_solver = solver_spec(self.cfg)
        if substeps is not None:
            coarse_solver = dataclasses.replace(coarse_solver, substeps=substeps)
        coarse = self.predict(index, starts, times[idx], goals, solver=coarse_solver)
        if fine is None:
            fine = self.predict(index, starts, times, goals)
        fine = np.asarray(fine)[:, idx]
        if self.kind == "position":
            return float(np.linalg.norm(coarse - fine, axis=-1).max())
        dot = np.clip(np.abs((coarse * fine).sum(-1)), 0.0, 1.0)
        return float(np.degrees(2.0 * np.arccos(dot)).max())

    # -- checkpoint -------------------------------------------------------------------
    def header(self) -> dict[str, Any]:
        """Plain data needed to rebuild this part (besides the tensors)."""
        return {
            "kind": self.kind,
            "num_tasks": self.method.num_tasks,
            "normalizers": [n.to_list() for n in self.normalizers],
            "goals": [None if g is None else g.tolist() for g in self.goals],
            "time_factors": list(self.time_factors),
        }

    def restore(self, header: Mapping[str, Any], tensors: Mapping[str, Tensor]) -> None:
        """Load a checkpointed state (inverse of :meth:`header` + ``method.state_dict()``)."""
        self.method.prepare_tasks(header["num_tasks"], tensors)
        self.method.load_state_dict(dict(tensors), strict=True)
        self.normalizers = [Normalizer.from_list(n) for n in header["normalizers"]]
        self.goals = [None if g is None else np.asarray(g) for g in header["goals"]]
        # checkpoints from before time_axis existed: every task on the data's axis
        self.time_factors = [float(f) for f in
                             header.get("time_factors", [1.0] * header["num_tasks"])]


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
            spec: NodeSpec | StableSpec
            if config.node == "s":
                spec = StableSpec(dim=part_dim, hidden=cfg.node_hidden,
                                  lyap_hidden=cfg.lyap_hidden, clock=cfg.snode_clock,
                                  activation=cfg.activation, alpha=cfg.snode_alpha,
                                  eps=cfg.snode_eps, rehu_d=cfg.snode_rehu,
                                  tangent=cfg.snode_tangent)
            else:
                spec = NodeSpec(dim=part_dim, hidden=cfg.node_hidden,
                                time_input=config.node == "t", activation=cfg.activation)
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
            times: ``[T]`` seconds from the start on the data's axis (``task.times``).
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

    def solver_gaps(self, index: int, task: Task, prediction: np.ndarray | None = None,
                    substeps: Mapping[str, int] | None = None) -> dict[str, float | None]:
        """:meth:`PartLearner.solver_gap` of every part for ``task``'s demos (the goals the
        protocol passes); ``prediction``: :meth:`predict`'s ``[N, T, D]`` for them, if
        already made (each part's share of it is reused); ``substeps``: per part, the steps
        per interval its training ended with (default: each config's)."""
        shares = {kind: None for kind in self.parts}
        if prediction is not None:
            shares = ({"position": prediction[..., :3], "orientation": prediction[..., 3:]}
                      if self.is_pose else {"position": prediction})
        return {kind: self.solver_gap(kind, index, task, shares[kind],
                                      (substeps or {}).get(kind))
                for kind in self.parts}

    def solver_gap(self, kind: str, index: int, task: Task, fine: np.ndarray | None = None,
                   substeps: int | None = None) -> float | None:
        """:meth:`PartLearner.solver_gap` of part ``kind`` for ``task``'s demos, with the
        goals the protocol passes (``fine``, ``substeps``: as there)."""
        goals = self.demo_goals(task) if kind == "orientation" else None
        return self.parts[kind].solver_gap(index, task, goals, fine, substeps)

    def demo_goals(self, task: Task) -> np.ndarray | None:
        """The goals the protocol passes for ``task``'s demos (None for planar data)."""
        if not self.is_pose:
            return None
        if self.parts["orientation"].cfg.tangent_goal == "demo":
            return np.asarray(task.demo_goals[:, 3:])
        return None
