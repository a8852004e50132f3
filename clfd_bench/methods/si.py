"""SI: Synaptic Intelligence (Zenke et al. 2017) on the task-conditioned NODE.

Loss for task m: ``L_m + c * sum_k Omega_k (theta*_k - theta_k)^2`` (paper Eq. si_loss) with
``Omega^m_k = sum_{l<m} omega^l_k / ((Delta^l_k)^2 + xi)`` (Eq. si_regu), where
``omega^l_k = -sum_steps g_k * (change of theta_k in that step)`` is the path integral of
the gradient along task ``l``'s trajectory and ``Delta^l_k`` the total change over task
``l``. ``g`` is the gradient the step used (task loss + regulariser), as in the original and
in van de Ven's SI code. With ``importance_merge = "per_task"`` ``omega`` restarts at 0 for
every task, as the paper's equation states; with ``"cumulative"`` it is never reset, as in the
released code (``SINODETaskEmbedding``: ``W`` is only ever added to), so task ``l`` adds
``sum_{j<=l} omega^j / ((Delta^l)^2 + xi)``. Only the NODE weights are regularised;
embeddings are not.
"""

from __future__ import annotations

import torch

from clfd_bench.methods.base import TaskData
from clfd_bench.methods.conditioned import ConditionedNodeMethod
from clfd_bench.methods.importance import ImportancePenaltyMethod

__all__ = ["SynapticIntelligence"]


class SynapticIntelligence(ImportancePenaltyMethod):
    """SI (see the module docstring). Buffers: ``omega`` (running path integral of the
    current task), ``importance`` (Omega), ``anchor`` (theta*), ``previous`` (theta before
    the last step)."""

    name = "si"
    hyperparameters = ConditionedNodeMethod.hyperparameters | {"si_c", "si_xi", "importance_merge"}

    def __init__(self, node, cfg):
        super().__init__(node, cfg)
        for i, w in enumerate(self.weights):
            self.register_buffer(f"omega_{i}", torch.zeros_like(w))
            self.register_buffer(f"previous_{i}", w.detach().clone())

    @property
    def strength(self) -> float:
        return self.cfg.si_c

    @property
    def _reset(self) -> bool:
        return self.cfg.importance_merge == "per_task"

    def on_task_start(self, task: int, data: TaskData) -> None:
        with torch.no_grad():
            for i, w in enumerate(self.weights):
                if self._reset:
                    self._buf("omega", i).zero_()
                self._buf("previous", i).copy_(w)

    @torch.no_grad()
    def after_step(self) -> None:
        for i, w in enumerate(self.weights):
            prev = self._buf("previous", i)
            if w.grad is not None:
                self._buf("omega", i).add_(-w.grad * (w - prev))
            prev.copy_(w)

    @torch.no_grad()
    def on_task_end(self, task: int, data: TaskData) -> None:
        for i, w in enumerate(self.weights):
            anchor = self._buf("anchor", i)
            delta = w - anchor
            self._buf("importance", i).add_(self._buf("omega", i) / (delta.pow(2) + self.cfg.si_xi))
            anchor.copy_(w)
            if self._reset:
                self._buf("omega", i).zero_()
