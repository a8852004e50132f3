"""The NODE vector field: an MLP ``f(y, t)`` (NODE^T) or ``f(y)`` (NODE^I) with explicit weights.

A task-conditioned NODE (FT, REP, SI, MAS) takes the task embedding as an extra input; the
input is ordered ``[embedding, y, t]`` as in the original implementation. Because the
embedding and the time are constant across a batch, their part of the first layer is folded
into the bias once per call instead of concatenating inputs at every function evaluation;
this is the same affine map evaluated in a different order.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch
from torch import Tensor

from clfd_bench.learning.mlp import activation, init_mlp_weights, mlp_forward, mlp_param_shapes

__all__ = ["NodeSpec", "VectorField"]


@dataclass(frozen=True)
class NodeSpec:
    """Architecture of a NODE vector field.

    Attributes:
        dim: D, the state dimension (2 for planar data, 3 for positions or tangent vectors).
        hidden: hidden layer widths, e.g. ``(1000, 1000, 1000)``.
        time_input: NODE^T (True) takes the time as an input, NODE^I (False) does not.
        cond_dim: size of a task embedding given as an extra input (0: none).
        activation: hidden activation (the paper: ``elu``).
    """

    dim: int
    hidden: tuple[int, ...]
    time_input: bool = True
    cond_dim: int = 0
    activation: str = "elu"

    def __post_init__(self) -> None:
        activation(self.activation)  # validates the name
        if self.dim < 1 or self.cond_dim < 0 or not self.hidden:
            raise ValueError(f"invalid NodeSpec {self}: dim >= 1, cond_dim >= 0, hidden non-empty")

    @property
    def n_in(self) -> int:
        """Input width of the MLP: ``cond_dim + dim + time_input``."""
        return self.cond_dim + self.dim + int(self.time_input)

    def param_shapes(self) -> list[tuple[int, ...]]:
        """Shapes of the weights ``[W0, b0, ..., WL, bL]`` the field needs."""
        return mlp_param_shapes(self.n_in, self.hidden, self.dim)

    def init_weights(self, generator: torch.Generator | None = None,
                     dtype: torch.dtype = torch.float32) -> list[Tensor]:
        """Fresh weights (``torch.nn.Linear``'s initialisation, as the original code)."""
        return init_mlp_weights(self.param_shapes(), generator, dtype)

    def field(self, weights: Sequence[Tensor], cond: Tensor | None = None) -> VectorField:
        """The vector field with these weights (``param_shapes()``) and task embedding."""
        return VectorField(self, weights, cond)


def check_field_inputs(what: str, spec, weights: Sequence[Tensor],
                       cond: Tensor | None) -> None:
    """Raise a ValueError unless ``weights`` have ``spec.param_shapes()`` and ``cond`` is a
    ``[cond_dim]`` embedding exactly when ``spec.cond_dim > 0`` (``what`` names the network in
    the message). Shared by every field class."""
    shapes = spec.param_shapes()
    got = [tuple(w.shape) for w in weights]
    if got != shapes:
        raise ValueError(f"weights have shapes {got}, {what} {spec} needs {shapes}")
    if (cond is None) != (spec.cond_dim == 0):
        raise ValueError(
            f"{what} with cond_dim={spec.cond_dim} needs "
            f"{'a' if spec.cond_dim else 'no'} task embedding"
        )
    if cond is not None and tuple(cond.shape) != (spec.cond_dim,):
        raise ValueError(
            f"task embedding has shape {tuple(cond.shape)}, expected ({spec.cond_dim},)"
        )


class VectorField:
    """``dy/dt = f(t, y)`` for a batch of states, with weights given explicitly.

    Args:
        spec: the architecture.
        weights: ``[W0, b0, ...]`` matching ``spec.param_shapes()`` (may carry gradients).
        cond: ``[cond_dim]`` task embedding when ``spec.cond_dim > 0``.

    Call as ``field(t, y)`` with ``t`` a scalar (or ``[B, 1]`` per-sample times) and
    ``y: [B, dim]``; returns ``[B, dim]``. :func:`clfd_bench.learning.odeint.integrate` runs
    fixed-step RK4 through such a field with a fused forward/backward pass.
    """

    def __init__(self, spec: NodeSpec, weights: Sequence[Tensor], cond: Tensor | None = None):
        check_field_inputs("NODE", spec, weights, cond)
        self.spec = spec
        self._act = activation(spec.activation)
        w0, b0 = weights[0], weights[1]
        c, d = spec.cond_dim, spec.dim
        bias = b0 if cond is None else b0 + w0[:, :c] @ cond
        self.w0y = w0[:, c : c + d]  # [H, D]
        self._w0y_t = self.w0y.t()  # [D, H]
        self.w0t = w0[:, c + d] if spec.time_input else None  # [H]
        self.bias = bias  # [H], with the embedding's contribution folded in
        self.rest = list(weights[2:])  # [W1, b1, ..., WL, bL]

    def __call__(self, t: Tensor, y: Tensor) -> Tensor:
        bias = self.bias if self.w0t is None else self.bias + t * self.w0t
        h = self._act(torch.addmm(bias, y, self._w0y_t))
        return mlp_forward(h, self.rest, self._act)
