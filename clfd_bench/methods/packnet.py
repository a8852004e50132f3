"""PackNet: one NODE whose weights are split between the tasks by iterative pruning.

Mallya & Lazebnik 2018, "PackNet: Adding Multiple Tasks to a Single Network by Iterative
Pruning" (CVPR), Sec. 3. Every weight is *owned* by the task that kept it, or *free*. Task k
trains the free weights (the weights of earlier tasks are used but frozen), then, in every
weight matrix, the ``packnet_prune`` fraction of its free-for-k weights with the smallest
magnitude is released (pruned); the kept ones are retrained briefly alone and become task k's,
frozen from then on. Task j's field uses only the weights owned by tasks ``<= j``, so every
learned task is reproduced exactly, whatever is learned later (no forgetting by
construction), at the price of capacity: task k can train only the weights earlier tasks left
free (``packnet_prune^k`` of each matrix).

Choices where the paper is not specific to NODEs (or to this loop):

* **Retraining is folded into the task's iterations**: the loop gives every method
  ``iterations`` steps per task; PackNet prunes after the first ``iterations - R`` of them
  and spends the last ``R = floor(packnet_retrain * iterations)`` on retraining the kept
  weights (``packnet_retrain`` is a share, so it follows ``--set iterations=...``), with the
  loop's Adam and learning-rate schedule (the paper retrains for a few extra epochs; here the
  cosine schedule is low by then). The training budget and time stay those of FT.
  ``packnet_retrain = 0`` prunes after the last iteration, without retraining. The stop rule
  (``stop_window > 0``) would end a task before its retraining share, so PackNet refuses it
  unless ``packnet_retrain = 0``.
* **Pruned weights are set to zero** when the task ends (pruning removes them from the
  network) and the next task trains them from zero, so it starts from the pruned network of
  the earlier tasks rather than from random values. Pruning is per weight matrix (the paper
  prunes every layer by the same fraction), ties broken by position.
* **Biases** are trained with the first task and frozen afterwards, as in the paper (which
  keeps them fixed after the first task): they are never pruned and belong to task 0.
* **Task embeddings stay** (this is the task-conditioned NODE of FT, SI, MAS, so only the
  CL method differs): task k's embedding is trained only while task k is learned, and enters
  through the first layer's embedding columns, which are masked like every weight. The
  masks, not the embedding, keep earlier tasks intact.
* The last task of a sequence is pruned too (a method does not know which task is last).

State: one owner map per weight matrix (``owner_{i}``, int16: the owning task, or
:data:`FREE`) as a buffer, so the checkpoint is complete and a run resumes exactly. Model
size (MS, FS): the NODE, the embeddings and the owner maps (one small integer per weight,
counted as one parameter each).
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from clfd_bench.learning.fields import Field
from clfd_bench.learning.part_config import ConfigError, Rule
from clfd_bench.methods.base import StepContext, TaskData
from clfd_bench.methods.conditioned import ConditionedNodeMethod

__all__ = ["FREE", "PackNet", "prune_smallest"]

FREE = torch.iinfo(torch.int16).max
"""The owner of a weight no task has kept (yet)."""


def prune_smallest(weight: Tensor, owner: Tensor, task: int, fraction: float) -> int:
    """Release the ``fraction`` of ``task``'s weights with the smallest magnitude: their owner
    becomes :data:`FREE` (in place) -> how many were released
    (``floor(fraction * n + 0.5)`` of the ``n`` weights ``task`` owns)."""
    candidates = (owner == task).flatten().nonzero().squeeze(1)  # [n]
    n_prune = math.floor(fraction * candidates.numel() + 0.5)
    if n_prune == 0:
        return 0
    magnitude = weight.detach().flatten()[candidates].abs()
    order = torch.sort(magnitude, stable=True).indices[:n_prune]
    owner.view(-1)[candidates[order]] = FREE
    return n_prune


class PackNet(ConditionedNodeMethod):
    """PackNet (see the module docstring). Buffers ``owner_{i}`` for every weight matrix
    ``i`` (0, 2, 4, ... of the NODE's ``[W0, b0, W1, b1, ...]``)."""

    name = "packnet"
    own_hyperparameters = {
        "packnet_prune": Rule("float", lo=0, hi=1, lo_open=True, hi_open=True,
                              what="share of each task's weights released after the task"),
        "packnet_retrain": Rule("float", lo=0, hi=1, hi_open=True,
                                what="share of each task's iterations spent retraining the "
                                     "kept weights after pruning"),
    }

    def __init__(self, node, cfg):
        if cfg.stop_window > 0 and cfg.extra("packnet_retrain") > 0:
            raise ConfigError(
                f"packnet retrains in the last packnet_retrain = {cfg.extra('packnet_retrain')}"
                f" of a task's iterations, which the stop rule (stop_window = "
                f"{cfg.stop_window}) would cut off, pruning without retraining; set "
                "stop_window=0 or packnet_retrain=0")
        super().__init__(node, cfg)
        for i in self.matrices:
            self.register_buffer(
                f"owner_{i}", torch.full(self.weights[i].shape, FREE, dtype=torch.int16))
        self._task = -1
        self._iteration = -1
        self._pruned = True

    @property
    def matrices(self) -> range:
        """Indices of the weight matrices in ``self.weights`` (biases are the odd ones)."""
        return range(0, len(self.weights), 2)

    def owner(self, i: int) -> Tensor:
        """The owner map of weight matrix ``i``."""
        return getattr(self, f"owner_{i}")

    @property
    def prune_at(self) -> int:
        """The iteration from which the kept weights are retrained (pruning happens after
        the step of the iteration before); ``iterations``: pruning after the last step."""
        iterations = self.cfg.iterations
        return iterations - math.floor(self.cfg.extra("packnet_retrain") * iterations)

    # -- model ----------------------------------------------------------------------
    def masked_weights(self, task: int) -> list[Tensor]:
        """The NODE weights task ``task`` uses: each matrix times the mask of the weights
        owned by tasks ``<= task``; biases as they are."""
        out = list(self.weights)
        for i in self.matrices:
            out[i] = out[i] * (self.owner(i) <= task).to(out[i].dtype)
        return out

    def field(self, task: int) -> Field:
        return self.node_spec.field(self.masked_weights(task), self.embeddings[task])

    # -- hooks ----------------------------------------------------------------------
    def on_task_start(self, task: int, data: TaskData) -> None:
        with torch.no_grad():
            for i in self.matrices:
                owner = self.owner(i)
                owner[owner == FREE] = task  # every free weight is task's until pruning
        self._task, self._iteration, self._pruned = task, -1, False

    def step_state(self) -> dict[str, bool | int | float]:
        return {"iteration": self._iteration, "pruned": self._pruned}

    def load_step_state(self, state: dict[str, bool | int | float]) -> None:
        self._iteration, self._pruned = int(state["iteration"]), bool(state["pruned"])

    def before_step(self, ctx: StepContext) -> None:
        self._iteration = ctx.iteration
        with torch.no_grad():
            for i, w in enumerate(self.weights):
                if i % 2 == 1:  # a bias: not trained after the first task (not trainable)
                    if ctx.task > 0:
                        w.grad = None
                elif w.grad is not None:  # earlier tasks' weights frozen (pruned: masked)
                    w.grad.mul_((self.owner(i) == ctx.task).to(w.grad.dtype))

    def after_step(self) -> None:
        if not self._pruned and self._iteration == self.prune_at - 1:
            self.prune(self._task)

    def prune(self, task: int) -> list[int]:
        """Release the ``packnet_prune`` share of ``task``'s weights in every matrix ->
        the number released per matrix."""
        self._pruned = True
        fraction = self.cfg.extra("packnet_prune")
        return [prune_smallest(self.weights[i], self.owner(i), task, fraction)
                for i in self.matrices]

    def on_task_end(self, task: int, data: TaskData) -> None:
        if not self._pruned:  # hooks called outside the loop (after_step prunes in it)
            self.prune(task)
        with torch.no_grad():
            for i in self.matrices:
                self.weights[i][self.owner(i) == FREE] = 0.0
        self._task = -1

    def trainable(self, task: int) -> list[nn.Parameter]:
        if task == 0:
            return super().trainable(task)
        # biases are frozen after the first task: leave them out of the optimiser
        return [*(self.weights[i] for i in self.matrices), self.embeddings[task]]

    # -- accounting -----------------------------------------------------------------
    def owned(self, task: int) -> int:
        """How many weights ``task`` owns."""
        return sum(int((self.owner(i) == task).sum()) for i in self.matrices)

    def num_params(self) -> int:
        """The NODE, the embeddings and the owner maps."""
        return super().num_params() + sum(b.numel() for b in self.buffers())
