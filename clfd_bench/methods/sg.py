"""SG: a separate, freshly initialised NODE per task (the paper's upper baseline)."""

from __future__ import annotations

from torch import nn

from clfd_bench.learning.mlp import init_mlp_weights
from clfd_bench.learning.node import VectorField
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
            nn.Parameter(w) for w in init_mlp_weights(self.node_spec.param_shapes())
        )
        self.nets.append(holder)
        super().add_task()

    def field(self, task: int) -> VectorField:
        return VectorField(self.node_spec, list(self.nets[task].weights))

    def trainable(self, task: int) -> list[nn.Parameter]:
        return list(self.nets[task].weights)
