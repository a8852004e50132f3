"""Hypernetworks: ``theta = f_h(e)`` maps a task embedding to all weights of a target NODE.

* :class:`HyperNetwork` (HN): an MLP ``e -> hidden -> P`` whose output is every target weight.
  The original implementation used one output head per target tensor; concatenated, those
  heads are exactly one linear layer with ``P`` outputs, which is what this class evaluates.
* :class:`ChunkedHyperNetwork` (CHN): an MLP ``[e, c_k] -> hidden -> chunk_dim`` evaluated
  for every chunk embedding ``c_k`` (shared across tasks, regularised like the weights); the
  concatenated chunks, cut to ``P``, are the target weights.

Task embeddings are not part of a hypernetwork: the CL method keeps them (one per task), and
the hypernetwork's :attr:`regularized` parameters are what the output regulariser protects.
Both classes check at construction that their output matches the target network's shapes.
Both accept a batch of embeddings ``[B, E]`` and return ``[B, P]``; the batched output
regulariser uses this to evaluate all past tasks in one pass.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import Tensor, nn

from clfd_bench.learning.mlp import (
    activation,
    init_mlp_weights,
    mlp_param_shapes,
    num_weights,
    split_flat,
)

__all__ = ["ChunkedHyperNetwork", "HyperNetwork", "check_target_shapes"]


def check_target_shapes(shapes: Sequence[Sequence[int]]) -> list[tuple[int, ...]]:
    """Validate the shapes of the tensors a hypernetwork generates (any target network: the
    NODE's MLP, the stable NODE's MLP and ICNN; the target's own field checks its layout).

    Raises:
        ValueError: no shapes, or naming the first shape with a dimension below 1.
    """
    shapes = [tuple(int(v) for v in s) for s in shapes]
    if not shapes:
        raise ValueError("a hypernetwork needs at least one target tensor shape")
    for i, shape in enumerate(shapes):
        if not shape or min(shape) < 1:
            raise ValueError(f"target tensor {i} has shape {shape}; every dimension must be "
                             ">= 1 (at least one dimension)")
    return shapes


class HyperNetwork(nn.Module):
    """Full hypernetwork: one forward pass produces all ``P`` target weights.

    Args:
        target_shapes: shapes of the target network's tensors, in the order it takes them
            (checked: :func:`check_target_shapes`).
        emb_dim: task embedding size.
        hidden: hidden layer widths (the paper: ``(200, 200, 200)``).
        activation: hidden activation (the paper: ReLU).
        generator: random generator for the initialisation (torch.nn.Linear's default).
    """

    def __init__(
        self,
        target_shapes: Sequence[Sequence[int]],
        emb_dim: int,
        hidden: Sequence[int],
        activation_name: str = "relu",
        generator: torch.Generator | None = None,
    ):
        super().__init__()
        self.target_shapes = check_target_shapes(target_shapes)
        self.num_outputs = num_weights(self.target_shapes)
        self.emb_dim = int(emb_dim)
        self.hidden = tuple(int(h) for h in hidden)
        self._act = activation(activation_name)
        shapes = mlp_param_shapes(self.emb_dim, self.hidden, self.num_outputs)
        self.theta = nn.ParameterList(
            nn.Parameter(w) for w in init_mlp_weights(shapes, generator)
        )
        out_features = self.theta[-1].shape[0]
        if out_features != self.num_outputs:  # pragma: no cover - guards the layout code
            raise ValueError(
                f"hypernetwork emits {out_features} values, target needs {self.num_outputs}"
            )

    @property
    def regularized(self) -> list[nn.Parameter]:
        """The parameters ``h`` the output regulariser protects (all weights and biases)."""
        return list(self.theta)

    def forward(self, emb: Tensor, delta: Sequence[Tensor] | None = None) -> Tensor:
        """Target weights for embedding(s) ``emb: [E]`` or ``[B, E]`` -> ``[P]`` or ``[B, P]``.

        ``delta`` (same structure as :attr:`regularized`) evaluates ``f(e, h + delta)``.
        """
        if delta is not None and len(delta) != len(self.theta):
            raise ValueError(f"delta has {len(delta)} tensors, the hypernetwork has "
                             f"{len(self.theta)}")
        params = list(self.regularized)
        squeeze = emb.dim() == 1
        h = emb.unsqueeze(0) if squeeze else emb
        n = len(params) // 2
        for layer in range(n):
            w, b = params[2 * layer], params[2 * layer + 1]
            if delta is None:
                h_next = torch.addmm(b, h, w.t())
            elif layer < n - 1:
                h_next = torch.addmm(b + delta[2 * layer + 1], h, (w + delta[2 * layer]).t())
            else:  # (W + dW) h without materialising the large W + dW
                h_next = torch.addmm(b + delta[2 * layer + 1], h, w.t()) + h @ delta[2 * layer].t()
            h = self._act(h_next) if layer < n - 1 else h_next
        return h[0] if squeeze else h

    def target_weights(self, emb: Tensor, delta: Sequence[Tensor] | None = None) -> list[Tensor]:
        """The target network's weights for one embedding ``[E]``, shaped as ``target_shapes``."""
        return split_flat(self.forward(emb, delta), self.target_shapes)


class ChunkedHyperNetwork(nn.Module):
    """Chunked hypernetwork: ``ceil(P / chunk_dim)`` chunks, one per chunk embedding.

    Args:
        target_shapes: shapes of the target network's tensors (checked).
        emb_dim: task embedding size.
        hidden: hidden layer widths.
        chunk_emb_dim: chunk embedding size.
        chunk_dim: values produced per chunk (the paper: 8192).
        activation_name: hidden activation (ReLU).
        generator: random generator for the initialisation.

    The input of the inner MLP is ``[task embedding, chunk embedding]`` (original order);
    chunk embeddings start ~ N(0, 1) as in the original implementation.
    """

    def __init__(
        self,
        target_shapes: Sequence[Sequence[int]],
        emb_dim: int,
        hidden: Sequence[int],
        chunk_emb_dim: int,
        chunk_dim: int,
        activation_name: str = "relu",
        generator: torch.Generator | None = None,
    ):
        super().__init__()
        self.target_shapes = check_target_shapes(target_shapes)
        self.num_outputs = num_weights(self.target_shapes)
        if chunk_dim < 1 or chunk_emb_dim < 1:
            raise ValueError(
                f"chunk_dim and chunk_emb_dim must be >= 1, got {chunk_dim}, {chunk_emb_dim}"
            )
        self.emb_dim = int(emb_dim)
        self.chunk_dim = int(chunk_dim)
        self.num_chunks = math.ceil(self.num_outputs / self.chunk_dim)
        self.hidden = tuple(int(h) for h in hidden)
        if not self.hidden:
            raise ValueError("a chunked hypernetwork needs at least one hidden layer")
        self._act = activation(activation_name)
        shapes = mlp_param_shapes(self.emb_dim + chunk_emb_dim, self.hidden, self.chunk_dim)
        weights = init_mlp_weights(shapes, generator)
        chunk_embs = torch.randn(self.num_chunks, chunk_emb_dim, generator=generator)
        self.chunk_embs = nn.Parameter(chunk_embs)
        self.theta = nn.ParameterList(nn.Parameter(w) for w in weights)
        produced = self.num_chunks * self.theta[-1].shape[0]
        if not (produced >= self.num_outputs > produced - self.chunk_dim):
            raise ValueError(  # pragma: no cover - guards the layout code
                f"{self.num_chunks} chunks of {self.chunk_dim} do not cover {self.num_outputs}"
            )

    @property
    def regularized(self) -> list[nn.Parameter]:
        """Chunk embeddings followed by all weights and biases of the inner MLP."""
        return [self.chunk_embs, *self.theta]

    def forward(self, emb: Tensor, delta: Sequence[Tensor] | None = None) -> Tensor:
        """Target weights for ``emb: [E]`` or ``[B, E]`` -> ``[P]`` or ``[B, P]``."""
        params = _shifted(self.regularized, delta)
        chunk_embs, net = params[0], params[1:]
        squeeze = emb.dim() == 1
        e = emb.unsqueeze(0) if squeeze else emb  # [B, E]
        w0, b0 = net[0], net[1]  # w0: [H, E + CE]
        # First layer on [e, c_k] for every (task, chunk) pair, split into its two parts.
        task_part = torch.addmm(b0, e, w0[:, : self.emb_dim].t())  # [B, H]
        chunk_part = chunk_embs @ w0[:, self.emb_dim :].t()  # [C, H]
        h = self._act(task_part.unsqueeze(1) + chunk_part.unsqueeze(0))  # [B, C, H]
        h = h.reshape(-1, h.shape[-1])
        n = len(net) // 2
        for layer in range(1, n):
            h = torch.addmm(net[2 * layer + 1], h, net[2 * layer].t())
            if layer < n - 1:
                h = self._act(h)
        out = h.reshape(e.shape[0], -1)[:, : self.num_outputs]  # [B, P]
        return out[0] if squeeze else out

    def target_weights(self, emb: Tensor, delta: Sequence[Tensor] | None = None) -> list[Tensor]:
        """The target network's weights for one embedding ``[E]``, shaped as ``target_shapes``."""
        return split_flat(self.forward(emb, delta), self.target_shapes)


def _shifted(params: Sequence[Tensor], delta: Sequence[Tensor] | None) -> list[Tensor]:
    if delta is None:
        return list(params)
    if len(delta) != len(params):
        raise ValueError(f"delta has {len(delta)} tensors, the hypernetwork has {len(params)}")
    return [p + d for p, d in zip(params, delta, strict=True)]
