"""A-GEM: Averaged Gradient Episodic Memory, on the task-conditioned NODE.

Chaudhry et al. 2019, "Efficient Lifelong Learning with A-GEM" (ICLR), Sec. 4 / Eq. 11. An
episodic memory keeps a few samples of every learned task. At each iteration of task m > 0
the gradient ``g`` of the task loss is compared with a reference gradient ``g_ref``, the
gradient of the loss on a batch from the memory of earlier tasks; if ``g . g_ref < 0`` (the
step would increase the memory loss to first order) the step uses the projection::

    g~ = g - (g . g_ref) / (g_ref . g_ref) * g_ref          (then g~ . g_ref = 0)

else ``g`` itself. The projection is applied in :meth:`~clfd_bench.methods.base.Method.
before_step`, to the gradient the optimiser is about to use (:func:`project_gradient`).

Choices where the paper is not specific to NODEs:

* **A memory sample is a demonstration**: a NODE learns from trajectories, so the memory of a
  task holds ``agem_memory`` of its demos, whole (every time step, as REP stores its tasks),
  drawn at random when the task ends (from the global RNG, which the protocol seeds per
  task). They are buffers (``memory_demos_k``, ``memory_times_k``): part of the checkpoint,
  counted as stored samples (SSS), not as parameters. ``agem_memory`` above a task's number
  of demos keeps all of them.
* **The memory batch**: the field depends on the task (its embedding), so a memory batch is
  built per task: ``agem_ref_tasks`` earlier tasks are drawn without replacement (the loop's
  generator) and each contributes a batch of its memory demos drawn exactly as a training
  batch at the current iteration (same horizon, segments, windows); the reference loss is the
  mean of their training losses, each with its own task's embedding. The paper's memory
  batch mixes tasks the same way (a random batch of the union of all memories).
* **What is projected**: ``g`` and ``g_ref`` are vectors over all trainable parameters (the
  NODE weights and the current task's embedding, whose reference gradient is 0 as the memory
  loss does not depend on it); the dot products run over all of them in float64.
* The optimiser is the loop's Adam (as for every method); the paper used SGD. The projected
  gradient is what Adam receives, so its moments are those of the projected gradients.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import torch
from torch import Tensor

from clfd_bench.learning.batches import BatchSampler
from clfd_bench.learning.objective import batch_spec, solver_spec, trajectory_loss
from clfd_bench.learning.part_config import Rule
from clfd_bench.methods.base import StepContext, TaskData
from clfd_bench.methods.conditioned import ConditionedNodeMethod
from clfd_bench.methods.memory import DemoMemory

__all__ = ["AveragedGEM", "project_gradient"]


def project_gradient(g: Sequence[Tensor], g_ref: Sequence[Tensor]) -> tuple[list[Tensor], bool]:
    """A-GEM's projection of ``g`` (a list of tensors, one vector) against ``g_ref`` ->
    ``(g~, projected)``: ``g`` unchanged if ``g . g_ref >= 0`` (or ``g_ref = 0``), else
    ``g - (g . g_ref) / (g_ref . g_ref) g_ref``. Dot products are taken in float64."""
    dot = sum(float((a.double() * b.double()).sum()) for a, b in zip(g, g_ref, strict=True))
    ref_sq = sum(float(b.double().pow(2).sum()) for b in g_ref)
    if dot >= 0 or ref_sq == 0:
        return list(g), False
    scale = dot / ref_sq
    return [a - scale * b for a, b in zip(g, g_ref, strict=True)], True


class AveragedGEM(DemoMemory, ConditionedNodeMethod):
    """A-GEM (see the module docstring). Buffers ``memory_demos_k`` ``[m, T, D]`` and
    ``memory_times_k`` ``[T]`` per learned task; ``projections`` counts the projected steps of
    the current task (for inspection; not part of the state)."""

    name = "agem"
    own_hyperparameters = {
        "agem_memory": Rule("int", lo=1, what="demos kept per task in the episodic memory"),
        "agem_ref_tasks": Rule("int", lo=1,
                               what="earlier tasks in each reference (memory) batch"),
    }

    def __init__(self, node, cfg):
        super().__init__(node, cfg)
        self._samplers: dict[int, BatchSampler] = {}
        self.projections = 0

    # -- memory (DemoMemory: store, memory, stored_samples) ------------------------
    def prepare_tasks(self, num_tasks: int, state: Mapping[str, Tensor]) -> None:
        super().prepare_tasks(num_tasks, state)
        self._samplers.clear()

    def on_task_start(self, task: int, data: TaskData) -> None:
        self.projections = 0
        self._samplers.clear()

    def step_state(self) -> dict[str, bool | int | float]:
        return {"projections": self.projections}

    def load_step_state(self, state: dict[str, bool | int | float]) -> None:
        self.projections = int(state["projections"])

    def on_task_end(self, task: int, data: TaskData) -> None:
        n = data.demos.shape[0]
        keep = min(self.cfg.extra("agem_memory"), n)
        idx = torch.randperm(n)[:keep].sort().values  # the global RNG, seeded per task
        self.store(task, data.demos[idx], data.times)

    # -- the projection -------------------------------------------------------------
    def reference_loss(self, ctx: StepContext) -> Tensor:
        """The mean training loss of ``agem_ref_tasks`` earlier tasks on batches of their
        memory (drawn as training batches at ``ctx.iteration``)."""
        n_ref = min(self.cfg.extra("agem_ref_tasks"), ctx.task)
        picks = torch.randperm(ctx.task, generator=ctx.generator)[:n_ref].tolist()
        solver = solver_spec(self.cfg)
        losses = []
        for k in picks:
            sampler = self._samplers.get(k)
            if sampler is None:
                sampler = self._samplers[k] = self.memory(k).sampler(
                    batch_spec(self.cfg), self.cfg.iterations)
            t, y = sampler.sample(ctx.iteration, ctx.generator)
            losses.append(trajectory_loss(self.field(k), t, y, solver))
        return torch.stack(losses).mean()

    def before_step(self, ctx: StepContext) -> None:
        if ctx.task == 0:
            return
        params = [p for p in self.trainable(ctx.task) if p.grad is not None]
        ref = torch.autograd.grad(self.reference_loss(ctx), params, allow_unused=True)
        g_ref = [torch.zeros_like(p) if r is None else r for p, r in zip(params, ref,
                                                                           strict=True)]
        projected, changed = project_gradient([p.grad for p in params], g_ref)
        if changed:
            self.projections += 1
            with torch.no_grad():
                for p, g in zip(params, projected, strict=True):
                    p.grad.copy_(g)
