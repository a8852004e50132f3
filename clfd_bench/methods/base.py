"""The interface every continual-learning method implements.

A method is a strategy on the ONE training loop (:func:`clfd_bench.harness.loop.train_task`):
it owns the model (NODE weights, task embeddings, hypernetwork) and supplies

* :meth:`Method.on_task_start` / :meth:`Method.on_task_end` hooks (create a task's network
  or embedding, compute regulariser targets or importances, store replay data),
* :meth:`Method.trainable` -- what the optimiser updates while learning a task,
* :meth:`Method.field` -- the NODE vector field of a task (for training and prediction),
* :meth:`Method.extra_loss` -- a regulariser added after the task loss is back-propagated,
* :meth:`Method.before_step` -- edit the gradients once all are computed, before the
  optimiser step (A-GEM's projection, PackNet's frozen weights),
* :meth:`Method.after_step` and :meth:`Method.pick_task` for methods that need them (SI, REP).

Everything a method must remember between tasks is a parameter or buffer of the module, so
``state_dict()`` is a complete checkpoint; :meth:`Method.prepare_tasks` rebuilds the
structure (how many tasks) before ``load_state_dict``.

Methods written outside this package (plugins) subclass :class:`Method` the same way; their
own hyperparameters are declared in :attr:`Method.own_hyperparameters` and read with
``self.cfg.extra(name)``. docs/methods.md is the guide.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import torch
from torch import Tensor, nn

from clfd_bench.learning.batches import BatchSampler, BatchSpec
from clfd_bench.learning.fields import Field, FieldSpec
from clfd_bench.learning.part_config import PartConfig, Rule

__all__ = ["Method", "StepContext", "TaskData"]


@dataclass
class TaskData:
    """One task's training data, as the loop and the methods see it.

    Attributes:
        demos: ``[N, T, D]`` normalised demonstrations (float32 tensor).
        times: ``[T]`` time stamps in seconds.
    """

    demos: Tensor
    times: Tensor

    def sampler(self, spec: BatchSpec, iterations: int) -> BatchSampler:
        """A batch sampler over these demos."""
        return BatchSampler(self.demos, self.times, spec, iterations)

    @property
    def num_samples(self) -> int:
        """``N * T``: how many samples storing this task means."""
        return int(self.demos.shape[0] * self.demos.shape[1])


@dataclass
class StepContext:
    """What :meth:`Method.extra_loss` and :meth:`Method.before_step` may use in one
    iteration: the task being learned, the iteration (0-based, of ``cfg.iterations``), the
    task's optimiser and the loop's random generator (batches and task picks draw from it
    too, so a method that draws from it changes the later batches, reproducibly)."""

    task: int
    iteration: int
    optimizer: torch.optim.Optimizer
    generator: torch.Generator


class Method(nn.Module):
    """Base class of the CL methods (see the module docstring).

    Args:
        node: the target NODE architecture (``cond_dim`` is set by the method).
        cfg: the part's hyperparameters.
    """

    name: ClassVar[str] = ""
    """Registered name (``sg``, ``ft``, ...)."""

    hyperparameters: ClassVar[frozenset[str]] = frozenset()
    """Method-specific :class:`PartConfig` keys this method reads (``task_emb_dim``, ``beta``,
    ...); the common keys (``iterations``, ``lr``, ``node_hidden``, ...) every method gets."""

    own_hyperparameters: ClassVar[Mapping[str, Rule]] = {}
    """Hyperparameters that are not :class:`PartConfig` fields, each with the rule its value
    must satisfy (``{"ewc_lambda": Rule("float", lo=0)}``). Their values come from the
    method's TOML like any key (required there unless the rule is ``optional``) and are read
    with ``self.cfg.extra("ewc_lambda")``."""

    config_file: ClassVar[str | Path | None] = None
    """A plugin's hyperparameter file (same tables as ``baselines/<name>.toml``), relative to
    its module's folder; ``--config`` overrides it. Built-in methods use ``baselines/``."""

    def __init__(self, node: FieldSpec, cfg: PartConfig):
        super().__init__()
        self.cfg = cfg
        self.node_spec = node
        self.num_tasks = 0

    # -- structure ------------------------------------------------------------------
    def add_task(self) -> None:
        """Create what a new task needs (a network, an embedding). Called once per task,
        before :meth:`on_task_start`, with the global torch RNG seeded for the task."""
        self.num_tasks += 1

    def prepare_tasks(self, num_tasks: int, state: Mapping[str, Tensor]) -> None:
        """Rebuild the structure for ``num_tasks`` learned tasks before ``load_state_dict``."""
        while self.num_tasks < num_tasks:
            self.add_task()

    # -- model ----------------------------------------------------------------------
    def field(self, task: int) -> Field:
        """The vector field that reproduces ``task``."""
        raise NotImplementedError

    def trainable(self, task: int) -> list[nn.Parameter]:
        """Parameters the optimiser updates while learning ``task``."""
        raise NotImplementedError

    # -- hooks ----------------------------------------------------------------------
    def on_task_start(self, task: int, data: TaskData) -> None:
        """Before the first iteration on ``task``."""

    def on_task_end(self, task: int, data: TaskData) -> None:
        """After the last iteration on ``task`` (counted in its training time)."""

    def pick_task(self, task: int, generator: torch.Generator) -> int:
        """Which task's data the next iteration trains on (REP: any seen task)."""
        return task

    def replay_data(self, task: int) -> TaskData:
        """Stored data of an earlier task (only methods that store data)."""
        raise NotImplementedError(f"method {self.name!r} stores no data")

    def extra_loss(self, ctx: StepContext) -> Tensor | None:
        """A regulariser, back-propagated after the task loss and before the step."""
        return None

    def before_step(self, ctx: StepContext) -> None:
        """After all gradients of the iteration are computed (task loss and
        :meth:`extra_loss`), before the optimiser step; may modify ``.grad`` of the trainable
        parameters in place (A-GEM projects it, PackNet zeroes frozen weights'). A ``.grad``
        that is None stays None: the optimiser skips that parameter."""

    def after_step(self) -> None:
        """After each optimiser step (SI's running importance)."""

    # -- a task's snapshot -----------------------------------------------------------
    def step_state(self) -> dict[str, bool | int | float]:
        """What the hooks keep between the iterations of a task outside :meth:`state_dict`
        (plain values), for a task snapshot: a run killed in the middle of a task resumes
        from the snapshot's weights, optimiser and this, after :meth:`on_task_start` has run
        again on the task's starting state, and must end bit for bit where it would have
        (``tests/test_task_snapshot.py`` checks every registered method). State that
        :meth:`on_task_start` rebuilds from the starting weights, or that lives in buffers,
        needs nothing here."""
        return {}

    def load_step_state(self, state: dict[str, bool | int | float]) -> None:
        """Restore :meth:`step_state`'s ``state`` (after :meth:`on_task_start`)."""
        if state:
            raise ValueError(f"method {self.name!r} keeps no step state, got {sorted(state)}")

    # -- accounting -----------------------------------------------------------------
    def num_params(self) -> int:
        """Parameters the model must keep to reproduce every learned task (MS, FS)."""
        return sum(p.numel() for p in self.parameters())

    def stored_samples(self) -> int:
        """Demonstration samples kept from learned tasks (SSS)."""
        return 0
