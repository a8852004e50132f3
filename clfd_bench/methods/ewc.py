"""EWC (online): Elastic Weight Consolidation with one running Fisher, on the task-conditioned
NODE.

Kirkpatrick et al. 2017, "Overcoming catastrophic forgetting in neural networks" (PNAS), in
the online form of Schwarz et al. 2018, "Progress & Compress: A scalable framework for
continual learning" (ICML), Sec. 2.3 / Eq. 6. Loss while learning task m > 0::

    L_m + lambda / 2 * sum_k F_k (theta_k - theta*_k)^2

with ``theta*`` the NODE weights after task m - 1 and the diagonal Fisher updated at the end
of every task as ``F <- gamma * F + F_task`` (``F`` starts at 0; ``gamma = 1`` is a sum of the
tasks' Fishers, i.e. Kirkpatrick's EWC with one penalty for all earlier tasks; ``gamma < 1``
forgets old tasks' importance geometrically). Like SI and MAS, only the NODE weights are
regularised; the task embeddings are not (each is trained only while its task is learned).

Choices where the papers are not specific to NODEs:

* **Fisher**: the *empirical* diagonal Fisher, the mean over samples of the squared gradient
  of the sample's loss at the weights after the task (Kirkpatrick's Eq. 3 approximated with
  the observed targets, as most implementations do).
* **A sample and its loss** (``row`` of a training batch): each row of a batch drawn exactly
  as in training, at the task's *last* iteration (so the ``fast`` profile's horizon is the
  whole trajectory), and its loss is the training loss of a batch holding only that row
  (:func:`clfd_bench.learning.objective.trajectory_loss`): the mean squared error of the
  demo's predicted trajectory (``fast``: the whole trajectory at ``points`` samples from the
  demo's start) or window (``paper``: ``tsub`` samples from the window's first one) against
  the demo. This is the negative log-likelihood of a Gaussian model of the demo up to a
  constant factor, which ``lambda`` absorbs. ``ewc_batches`` batches are drawn (from a
  generator seeded from the global RNG, which the protocol seeds per task), so
  ``N x ewc_batches`` samples: for random windows more batches cover more of the demos;
  whole trajectories without segments are the same every time, one batch is all there is.
* **Scale**: the empirical Fisher of a well-fitted regression is small (it grows with the
  squared residuals), so ``lambda`` is large; it was chosen by a sweep (``baselines/ewc.toml``).
* **The penalty's gamma**: Progress & Compress writes the penalty with ``gamma * F`` of the
  previous tasks; here it is ``F`` itself (a constant factor ``gamma`` that ``lambda``
  absorbs), as in the formula above.
* The optimiser is the loop's Adam (as for every method), not SGD.

What it does here (HelloWorld, ``fast``; numbers in ``baselines/ewc.toml``): it forgets less
than FT as counted by REM/BWT (letters it keeps within the DTW threshold; 7 letters, lambda
1e4: REM 0.54 against FT's 0, ACC 0.42 against 0.25), but a letter it does not keep ends
*further* from its demos than under FT ('h' after 'e' at lambda 1e4: DTW 97 m, FT: 52 m).
The Fisher of the last layer is 100-1000x that of the hidden layers (measured); the likely
reason is that a penalty strong enough to matter holds the output layer and the new letter
is learned by moving the hidden layers, whose small Fisher says they do not matter to the
earlier letters, while through the integration they do (the Fisher-weighted drift is ~300x
smaller than FT's, tests/test_methods_more.py). Only lambda ~1e5 keeps the earlier letters
(REM 0.87), and then new letters are not learned (ACC 0.34). A Monte-Carlo "true" Fisher
did no better. The paper found SI and MAS, the other importance-weighted penalties, poor on
these NODEs too.

Model size (MS, FS): the NODE, the embeddings, and the Fisher and the anchor (2 buffers the
size of the NODE), as for MAS.
"""

from __future__ import annotations

import torch
from torch import Tensor

from clfd_bench.learning.batches import BatchSpec
from clfd_bench.learning.fields import FieldSpec
from clfd_bench.learning.objective import batch_spec, row_batch, solver_spec, trajectory_loss
from clfd_bench.learning.odeint import SolverSpec
from clfd_bench.learning.part_config import Rule
from clfd_bench.methods.base import StepContext, TaskData
from clfd_bench.methods.conditioned import ConditionedNodeMethod

__all__ = ["OnlineEWC", "empirical_fisher"]


def empirical_fisher(
    field_of: callable,
    weights: list[Tensor],
    batches: list[tuple[Tensor, Tensor]],
    solver: SolverSpec,
) -> list[Tensor]:
    """The diagonal empirical Fisher ``1/S sum_s (d loss_s / d w)^2`` for every weight tensor
    ``w``, over the ``S`` rows of all ``batches``.

    Args:
        field_of: ``weights -> Field`` (the task's field with these weights).
        weights: the weights (tensors that require gradients).
        batches: training batches ``(t [L] or [B, L], y [B, L, D])``; every row is a sample
            whose loss is :func:`~clfd_bench.learning.objective.trajectory_loss` of that row.
        solver: how to integrate (the training solver).
    """
    total = [torch.zeros_like(w) for w in weights]
    count = 0
    for t, y in batches:
        for row in range(y.shape[0]):
            t_row, y_row = row_batch(t, y, row)
            loss = trajectory_loss(field_of(weights), t_row, y_row, solver)
            grads = torch.autograd.grad(loss, weights)
            for acc, g in zip(total, grads, strict=True):
                acc.add_(g.detach().pow(2))
            count += 1
    return [acc / max(count, 1) for acc in total]


class OnlineEWC(ConditionedNodeMethod):
    """Online EWC (see the module docstring). Buffers: ``fisher_{i}`` (the running diagonal
    Fisher ``F``) and ``anchor_{i}`` (``theta*``), one per NODE weight tensor."""

    name = "ewc"
    own_hyperparameters = {
        "ewc_lambda": Rule("float", lo=0, what="weight of the Fisher penalty (lambda)"),
        "ewc_gamma": Rule("float", lo=0, hi=1,
                          what="decay of earlier tasks' Fisher, F <- gamma F + F_task"),
        "ewc_batches": Rule("int", lo=1, what="training batches drawn for each task's Fisher"),
    }

    def __init__(self, node: FieldSpec, cfg):
        super().__init__(node, cfg)
        for i, w in enumerate(self.weights):
            self.register_buffer(f"fisher_{i}", torch.zeros_like(w))
            self.register_buffer(f"anchor_{i}", w.detach().clone())

    def _buf(self, kind: str, i: int) -> Tensor:
        return getattr(self, f"{kind}_{i}")

    def fisher_batches(self, data: TaskData, spec: BatchSpec | None = None,
                       generator: torch.Generator | None = None) -> list[tuple[Tensor, Tensor]]:
        """The ``ewc_batches`` batches the Fisher of a task is estimated on: drawn as at the
        task's last training iteration."""
        spec = spec or batch_spec(self.cfg)
        sampler = data.sampler(spec, self.cfg.iterations)
        if generator is None:  # seeded by the run (the global RNG is seeded per task)
            generator = torch.Generator().manual_seed(int(torch.randint(0, 2**62, (1,))))
        last = self.cfg.iterations - 1
        return [sampler.sample(last, generator) for _ in range(self.cfg.extra("ewc_batches"))]

    def task_fisher(self, task: int, data: TaskData) -> list[Tensor]:
        """``F_task``: the empirical Fisher of ``task`` at the current weights."""
        emb = self.embeddings[task].detach()
        weights = [w.detach().clone().requires_grad_(True) for w in self.weights]
        return empirical_fisher(
            lambda ws: self.node_spec.field(ws, emb), weights,
            self.fisher_batches(data), solver_spec(self.cfg),
        )

    def on_task_end(self, task: int, data: TaskData) -> None:
        fisher = self.task_fisher(task, data)
        gamma = self.cfg.extra("ewc_gamma")
        with torch.no_grad():
            for i, w in enumerate(self.weights):
                self._buf("fisher", i).mul_(gamma).add_(fisher[i])
                self._buf("anchor", i).copy_(w)

    def extra_loss(self, ctx: StepContext) -> Tensor | None:
        strength = self.cfg.extra("ewc_lambda")
        if ctx.task == 0 or strength == 0:
            return None  # nothing to protect while the first task is learned
        total = sum(
            (self._buf("fisher", i) * (w - self._buf("anchor", i)).pow(2)).sum()
            for i, w in enumerate(self.weights)
        )
        return 0.5 * strength * total

    def num_params(self) -> int:
        """The NODE, the embeddings, the Fisher and the anchor."""
        return super().num_params() + sum(b.numel() for b in self.buffers())
