"""HN and CHN: a (chunked) hypernetwork generates every weight of the task's NODE.

Two-step optimisation per iteration (paper Eqs. our_hn_loss_1 and hn_loss_2, see
:mod:`clfd_bench.learning.hnet_reg`): the task loss is back-propagated into the hypernetwork
parameters ``h`` and the current task embedding; the look-ahead ``dh`` is the Adam step that
gradient would cause; then ``beta * R(h + dh)`` is back-propagated, where ``R`` keeps the
outputs for all earlier task embeddings at their values from before the current task. The
embedding of the current task gets only the task-loss gradient (R does not depend on it).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from clfd_bench.learning.fields import Field
from clfd_bench.learning.hnet_reg import adam_lookahead, output_regularizer
from clfd_bench.learning.hypernet import ChunkedHyperNetwork, HyperNetwork
from clfd_bench.methods.base import Method, StepContext, TaskData

__all__ = ["ChunkedHypernetworkMethod", "HypernetworkMethod"]


class HypernetworkMethod(Method):
    """HN: a full hypernetwork; the NODE (``node_hidden``) has no weights of its own."""

    name = "hn"
    hyperparameters = frozenset(
        {"task_emb_dim", "hnet_hidden", "hnet_activation", "beta", "hnet_reg", "hnet_reg_samples"}
    )

    def __init__(self, node, cfg):
        super().__init__(node, cfg)
        if cfg.task_emb_dim < 1 or not cfg.hnet_hidden:
            raise ValueError(f"method {self.name!r} needs task_emb_dim >= 1 and hnet_hidden")
        self.hnet = self._build_hnet()
        self.embeddings = nn.ParameterList()
        self._targets: Tensor | None = None
        self._past: Tensor | None = None
        self._delta: list[Tensor] | None = None  # the look-ahead's buffers during a task

    def _build_hnet(self) -> nn.Module:
        return HyperNetwork(
            self.node_spec.param_shapes(), self.cfg.task_emb_dim, self.cfg.hnet_hidden,
            self.cfg.hnet_activation,
        )

    def add_task(self) -> None:
        self.embeddings.append(nn.Parameter(torch.randn(self.cfg.task_emb_dim)))
        super().add_task()

    def field(self, task: int) -> Field:
        return self.node_spec.field(self.hnet.target_weights(self.embeddings[task]))

    def trainable(self, task: int) -> list[nn.Parameter]:
        return [*self.hnet.regularized, self.embeddings[task]]

    @torch.no_grad()
    def on_task_start(self, task: int, data: TaskData) -> None:
        if task == 0:
            self._past = self._targets = None
            return
        self._past = torch.stack([e.detach().clone() for e in self.embeddings[:task]])
        self._targets = self.hnet(self._past).detach()  # f(e_l, h*) for l < task

    def on_task_end(self, task: int, data: TaskData) -> None:
        self._past = self._targets = self._delta = None

    def extra_loss(self, ctx: StepContext) -> Tensor | None:
        if self._targets is None or self.cfg.beta == 0:
            return None
        params = self.hnet.regularized
        if self._delta is None:  # one allocation per task, not one per iteration
            self._delta = [torch.empty_like(p, requires_grad=False) for p in params]
        delta = adam_lookahead(ctx.optimizer, params, out=self._delta)
        reg = output_regularizer(
            self.hnet, self._past, self._targets, delta, mode=self.cfg.hnet_reg,
            samples=self.cfg.hnet_reg_samples, generator=ctx.generator,
        )
        return self.cfg.beta * reg


class ChunkedHypernetworkMethod(HypernetworkMethod):
    """CHN: a chunked hypernetwork; chunk embeddings are shared and regularised."""

    name = "chn"
    hyperparameters = HypernetworkMethod.hyperparameters | {"chunk_emb_dim", "chunk_dim"}

    def _build_hnet(self) -> nn.Module:
        if self.cfg.chunk_dim < 1 or self.cfg.chunk_emb_dim < 1:
            raise ValueError("method 'chn' needs chunk_dim >= 1 and chunk_emb_dim >= 1")
        return ChunkedHyperNetwork(
            self.node_spec.param_shapes(), self.cfg.task_emb_dim, self.cfg.hnet_hidden,
            self.cfg.chunk_emb_dim, self.cfg.chunk_dim, self.cfg.hnet_activation,
        )
