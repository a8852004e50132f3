"""The task-conditioned NODE shared by FT, REP, SI and MAS.

One NODE takes a trainable task embedding as an extra input (``[e_k, y, t]``); a new
embedding ~ N(0, 1) is created for every task and trained only while its task is learned
(REP: whenever its task is replayed).
"""

from __future__ import annotations

import dataclasses

import torch
from torch import nn

from clfd_bench.learning.fields import Field, FieldSpec
from clfd_bench.methods.base import Method

__all__ = ["ConditionedNodeMethod"]


class ConditionedNodeMethod(Method):
    """Base of FT, REP, SI and MAS: one shared NODE plus one embedding per task."""

    hyperparameters = frozenset({"task_emb_dim"})

    def __init__(self, node: FieldSpec, cfg):
        if cfg.task_emb_dim < 1:
            raise ValueError(f"method {self.name!r} needs task_emb_dim >= 1")
        node = dataclasses.replace(node, cond_dim=cfg.task_emb_dim)
        super().__init__(node, cfg)
        self.weights = nn.ParameterList(
            nn.Parameter(w) for w in node.init_weights()
        )
        self.embeddings = nn.ParameterList()

    def add_task(self) -> None:
        self.embeddings.append(nn.Parameter(torch.randn(self.cfg.task_emb_dim)))
        super().add_task()

    def field(self, task: int) -> Field:
        return self.node_spec.field(list(self.weights), self.embeddings[task])

    def trainable(self, task: int) -> list[nn.Parameter]:
        return [*self.weights, self.embeddings[task]]

    def shared(self) -> list[nn.Parameter]:
        """The NODE weights (what SI/MAS regularise; embeddings are not regularised)."""
        return list(self.weights)
