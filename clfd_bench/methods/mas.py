"""MAS: Memory Aware Synapses (Aljundi et al. 2018) on the task-conditioned NODE.

Same loss form as SI with ``lambda`` in place of ``c``; the importance of a NODE weight is
(paper Eq. mas_regu) the mean over data points ``x_n`` of the absolute gradient of the
squared L2 norm of the NODE's output, ``1/N sum_n |d ||f(x_n)||^2 / d theta_k|``. The data
points are the task's (normalised) demonstration samples with their times and the task's
embedding: all of them, or ``mas_points`` evenly spaced ones. Importances of successive tasks
add up; ``theta*`` is the weights after the last task. With ``importance_merge =
"cumulative"`` the released code's merge is kept (its current-task importance is never reset,
so task ``l`` adds ``sum_{j<=l}`` of the tasks' estimates; one more buffer, ``running``, which
the model size counts as the released code's ``omega_curr``).

Where the released code (``tr_mas_node.py``, ``imitation_cl/model/node.py``) differs, this
follows the paper's equation: the original estimated the importance from 2 x ``num_iter``
random window starts evaluated at the last time ``t[-1]``, not from the task's data points;
it computed importance and anchor only from task 1 on (inside ``if calc_reg``), so the first
task was never protected; its current-task importance was never reset, so earlier tasks'
importances were added again at every merge (available as ``importance_merge =
"cumulative"``); and it cleared gradients once per iteration,
taking the absolute value of gradients summed over samples rather than the mean of per-sample
absolute gradients. (Checked in closed form by ``tests/test_si_mas_closed_form.py``.)
"""

from __future__ import annotations

import torch
from torch import Tensor
from torch.func import grad, vmap

from clfd_bench.methods.base import TaskData
from clfd_bench.methods.conditioned import ConditionedNodeMethod
from clfd_bench.methods.importance import ImportancePenaltyMethod

__all__ = ["MemoryAwareSynapses", "output_norm_importance"]

_CHUNK_FLOATS = 2**25  # per-sample gradients materialised at once (~128 MB in float32)


def output_norm_importance(
    field_of: callable, weights: list[Tensor], ys: Tensor, ts: Tensor
) -> list[Tensor]:
    """``1/N sum_n |d ||f(t_n, y_n)||^2 / d w|`` for every weight tensor ``w``.

    Args:
        field_of: ``weights -> Field``.
        weights: the NODE weights (plain tensors).
        ys: ``[N, D]`` states. ts: ``[N]`` their times.
    """
    def sq_norm(ws, y, t):
        return field_of(ws)(t, y.unsqueeze(0)).pow(2).sum()

    per_sample = vmap(grad(sq_norm), in_dims=(None, 0, 0))
    n_params = sum(w.numel() for w in weights)
    chunk = max(1, _CHUNK_FLOATS // n_params)
    total = [torch.zeros_like(w) for w in weights]
    detached = tuple(w.detach() for w in weights)
    for start in range(0, ys.shape[0], chunk):
        grads = per_sample(detached, ys[start : start + chunk], ts[start : start + chunk])
        for acc, g in zip(total, grads, strict=True):
            acc.add_(g.abs().sum(0))
    return [acc / ys.shape[0] for acc in total]


class MemoryAwareSynapses(ImportancePenaltyMethod):
    """MAS (see the module docstring). Buffers: ``importance`` (Omega), ``anchor``; with
    ``importance_merge = "cumulative"`` also ``running`` (the never-reset task importance)."""

    name = "mas"
    hyperparameters = ConditionedNodeMethod.hyperparameters | {
        "mas_lambda", "mas_points", "importance_merge"
    }

    def __init__(self, node, cfg):
        super().__init__(node, cfg)
        if cfg.importance_merge == "cumulative":
            for i, w in enumerate(self.weights):
                self.register_buffer(f"running_{i}", torch.zeros_like(w))

    @property
    def strength(self) -> float:
        return self.cfg.mas_lambda

    def on_task_end(self, task: int, data: TaskData) -> None:
        n, t, d = data.demos.shape
        ys = data.demos.reshape(-1, d)
        ts = data.times.to(ys.dtype).repeat(n)
        if 0 < self.cfg.mas_points < ys.shape[0]:
            idx = torch.linspace(0, ys.shape[0] - 1, self.cfg.mas_points).round().long()
            ys, ts = ys[idx], ts[idx]
        emb = self.embeddings[task].detach()
        importance = output_norm_importance(
            lambda ws: self.node_spec.field(list(ws), emb), list(self.weights), ys, ts
        )
        with torch.no_grad():
            for i, w in enumerate(self.weights):
                if self.cfg.importance_merge == "cumulative":
                    importance[i] = self._buf("running", i).add_(importance[i])
                self._buf("importance", i).add_(importance[i])
                self._buf("anchor", i).copy_(w)
