"""SG: a separate, freshly initialised NODE per task (the paper's upper baseline)."""

from __future__ import annotations

from torch import nn

from clfd_bench.learning.fields import Field
from clfd_bench.methods.base import Method

__all__ = ["SingleNodePerTask"]


class SingleNodePerTask(Method):
    """SG: task ``k`` has its own NODE; earlier NODEs are frozen, so nothing is forgotten,
    at the price of one full network per task."""

    name = "sg"
    hyperparameters = frozenset()

    def __init__(self, node, cfg):
        super().__init__(node, cfg)
        self.nets = nn.ModuleList()

    def add_task(self) -> None:
        holder = nn.Module()
        holder.weights = nn.ParameterList(
            nn.Parameter(w) for w in self.node_spec.init_weights()
        )
        self.nets.append(holder)
        super().add_task()

    def field(self, task: int) -> Field:
        return self.node_spec.field(list(self.nets[task].weights))

    def trainable(self, task: int) -> list[nn.Parameter]:
        return list(self.nets[task].weights)
