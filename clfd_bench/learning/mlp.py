"""Fully connected networks whose weights are passed in explicitly.

The target networks of the hypernetworks do not own their weights: a hypernetwork produces
them. Every network in this package is therefore described by its parameter *shapes* and
evaluated by a pure function of ``(input, weights)``; networks that do own their weights
(SG, FT, ...) keep them in an ``nn.ParameterList`` and call the same function.

Weight layout (the order a hypernetwork emits them in): ``[W0, b0, W1, b1, ..., WL, bL]``
with ``Wl: [out_l, in_l]`` and ``bl: [out_l]``, as ``torch.nn.Linear`` stores them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import torch
import torch.nn.functional as F
from torch import Tensor

__all__ = [
    "ACTIVATIONS",
    "activation",
    "init_mlp_weights",
    "mlp_forward",
    "mlp_param_shapes",
    "num_weights",
    "split_flat",
]

ACTIVATIONS: dict[str, Callable[[Tensor], Tensor]] = {
    "elu": F.elu,
    "relu": F.relu,
    "tanh": torch.tanh,
}
"""Activation functions by name (the paper: ELU in NODEs, ReLU in hypernetworks)."""


def activation(name: str) -> Callable[[Tensor], Tensor]:
    """The activation called ``name``; a ValueError lists the valid names."""
    try:
        return ACTIVATIONS[name]
    except KeyError:
        raise ValueError(
            f"unknown activation {name!r}; valid: {', '.join(sorted(ACTIVATIONS))}"
        ) from None


def mlp_param_shapes(n_in: int, hidden: Sequence[int], n_out: int) -> list[tuple[int, ...]]:
    """Shapes ``[(out, in), (out,), ...]`` of a fully connected net ``n_in -> hidden -> n_out``."""
    if n_in < 1 or n_out < 1 or any(h < 1 for h in hidden):
        raise ValueError(
            f"layer sizes must be positive, got n_in={n_in}, hidden={list(hidden)}, n_out={n_out}"
        )
    shapes: list[tuple[int, ...]] = []
    prev = n_in
    for size in [*hidden, n_out]:
        shapes += [(size, prev), (size,)]
        prev = size
    return shapes


def num_weights(shapes: Sequence[Sequence[int]]) -> int:
    """Total number of scalars in tensors of the given shapes."""
    return int(sum(math.prod(s) for s in shapes))


def split_flat(flat: Tensor, shapes: Sequence[Sequence[int]]) -> list[Tensor]:
    """Views of a flat vector ``[P]`` (or ``[..., P]``) as tensors of ``shapes``."""
    sizes = [math.prod(s) for s in shapes]
    if flat.shape[-1] != sum(sizes):
        raise ValueError(
            f"flat weight vector has {flat.shape[-1]} entries, shapes need {sum(sizes)}"
        )
    lead = flat.shape[:-1]
    parts = torch.split(flat, sizes, dim=-1)
    return [p.reshape(*lead, *s) for p, s in zip(parts, shapes, strict=True)]


def init_mlp_weights(
    shapes: Sequence[Sequence[int]],
    generator: torch.Generator | None = None,
    dtype: torch.dtype = torch.float32,
) -> list[Tensor]:
    """Fresh weights with ``torch.nn.Linear``'s default initialisation.

    Weights ~ U(-1/sqrt(fan_in), 1/sqrt(fan_in)) (Kaiming uniform with a = sqrt(5)),
    biases ~ U(-1/sqrt(fan_in), 1/sqrt(fan_in)), as the original implementation used.
    """
    out: list[Tensor] = []
    for i in range(0, len(shapes), 2):
        w_shape, b_shape = tuple(shapes[i]), tuple(shapes[i + 1])
        bound = 1.0 / math.sqrt(w_shape[1])
        w = (torch.rand(w_shape, generator=generator, dtype=dtype) * 2 - 1) * bound
        b = (torch.rand(b_shape, generator=generator, dtype=dtype) * 2 - 1) * bound
        out += [w, b]
    return out


def mlp_forward(
    x: Tensor,
    weights: Sequence[Tensor],
    act: Callable[[Tensor], Tensor],
) -> Tensor:
    """Evaluate the network: ``x: [B, in] -> [B, out]``; no activation after the last layer."""
    n_layers = len(weights) // 2
    h = x
    for layer in range(n_layers):
        w, b = weights[2 * layer], weights[2 * layer + 1]
        h = torch.addmm(b, h, w.t()) if h.dim() == 2 else F.linear(h, w, b)
        if layer < n_layers - 1:
            h = act(h)
    return h
