"""An MLP vector field evaluated without autograd, with a hand-written reverse pass.

The fused solvers (:mod:`~clfd_bench.learning.rk4_fused`, :mod:`~clfd_bench.learning.
dopri5_fused`) run their forward sweep under ``no_grad`` through :class:`MLPTape`, which
records every evaluation's activations. Their backward sweep calls :meth:`MLPTape.vjp` on
the evaluations that influence the output, in reverse order; the tape records each layer's
output gradient, and :meth:`MLPTape.weight_grads` sums the weight gradients of ALL
evaluations in one matrix product per layer at the end (instead of one small product and
one accumulation per evaluation, as autograd does).

The field is ``f(t, y) = L_n(act(... act(W0y y + t w0t + b0) ...))``: the first layer's weight
split into its state part ``W0y: [H, D]``, time part ``w0t: [H]`` (NODE^T; None for NODE^I)
and bias ``b0: [H]`` (which may hold a task embedding's contribution).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor

__all__ = ["FUSED_ACTIVATIONS", "MLPTape", "needs_grad", "summed_weight_grads"]

FUSED_ACTIVATIONS = ("elu", "tanh", "relu")

_ACT = {"elu": torch.nn.functional.elu, "tanh": torch.tanh, "relu": torch.relu}


def _act_backward(name: str, grad: Tensor, out: Tensor) -> Tensor:
    """``d act / dz * grad`` from the activation's OUTPUT ``out``."""
    if name == "elu":
        return torch.ops.aten.elu_backward(grad, 1.0, 1, 1.0, True, out)
    if name == "tanh":
        return torch.ops.aten.tanh_backward(grad, out)
    return grad * (out > 0)


class MLPTape:
    """Evaluations of one MLP vector field, recorded for a later reverse pass.

    Args:
        w0y, w0t, b0: the first layer (see the module docstring).
        rest: ``[W1, b1, ..., WL, bL]``.
        act: hidden activation, one of :data:`FUSED_ACTIVATIONS`.
        record: keep activations (needed for :meth:`vjp`).
    """

    _matmul = staticmethod(torch.mm)
    """The product of :meth:`vjp` (a stacked tape's is ``torch.bmm``)."""

    def __init__(self, w0y: Tensor, w0t: Tensor | None, b0: Tensor, rest: Sequence[Tensor],
                 act: str, record: bool):
        if act not in FUSED_ACTIVATIONS:
            raise ValueError(f"fused solvers support activations {FUSED_ACTIVATIONS}, not {act!r}")
        self.w0y, self.w0t, self.b0, self.act = w0y, w0t, b0, act
        self.weights = list(rest[0::2])
        self._layers = list(zip([w.t() for w in rest[0::2]], rest[1::2], strict=True))
        self._w0y_t = w0y.t()
        self._act_fn = _ACT[act]
        self.record = record
        self.acts: list[list[Tensor]] = []  # per evaluation: [input u, hidden activations...]
        self.times: list[float | Tensor] = []  # per evaluation: its time (float or [B, 1])
        self._grad_outs: list[list[Tensor]] = [[] for _ in range(len(self.weights) + 1)]
        self._order: list[int] = []

    def bias(self, t: float | Tensor) -> Tensor:
        """First-layer bias at time ``t`` (``[H]``, or ``[B, H]`` for per-sample times)."""
        if self.w0t is None:
            return self.b0
        if isinstance(t, float):
            return torch.add(self.b0, self.w0t, alpha=t)
        return torch.addcmul(self.b0, t, self.w0t)

    def __call__(
        self, t: float | Tensor, u: Tensor, bias: Tensor | None = None, record: bool = True
    ) -> Tensor:
        """``f(t, u)`` for ``u: [B, D]``; ``bias`` may pass a precomputed :meth:`bias`;
        ``record=False`` keeps this evaluation off the tape (e.g. a step-size probe)."""
        act = self._act_fn
        z = act(torch.addmm(self.bias(t) if bias is None else bias, u, self._w0y_t))
        a = [u, z]
        for w_t, b in self._layers[:-1]:
            z = act(torch.addmm(b, z, w_t))
            a.append(z)
        if self.record and record:
            self.acts.append(a)
            self.times.append(t)
        w_t, b = self._layers[-1]
        return torch.addmm(b, z, w_t)

    @property
    def num_evals(self) -> int:
        """Evaluations recorded so far (the index of the next one)."""
        return len(self.acts)

    def discard_from(self, index: int) -> None:
        """Forget evaluations ``index, index + 1, ...`` (a rejected adaptive step)."""
        del self.acts[index:]
        del self.times[index:]

    def start_reverse(self) -> None:
        """Clear the recorded gradients (a reverse pass may run more than once)."""
        self._grad_outs = [[] for _ in range(len(self.weights) + 1)]
        self._order = []

    def vjp(self, g: Tensor, e: int) -> Tensor:
        """``J_e^T g``: the gradient w.r.t. evaluation ``e``'s input for output gradient ``g``.

        Records the layer gradients for :meth:`weight_grads`.
        """
        a = self.acts[e]
        n = len(self.weights)
        self._grad_outs[n].append(g)
        for j in range(n - 1, -1, -1):
            g = _act_backward(self.act, self._matmul(g, self.weights[j]), a[j + 1])
            self._grad_outs[j].append(g)
        self._order.append(e)
        return self._matmul(g, self.w0y)

    def weight_grads(self) -> tuple[Tensor, Tensor | None, Tensor, list[Tensor]]:
        """``(dW0y, dw0t, db0, [dW1, db1, ...])`` summed over every :meth:`vjp` call."""
        order = self._order
        if not order:
            zeros = [torch.zeros_like(w) for w in (self.w0y, self.b0)]
            rest = []
            for w, (_, b) in zip(self.weights, self._layers, strict=True):
                rest += [torch.zeros_like(w), torch.zeros_like(b)]
            w0t = None if self.w0t is None else torch.zeros_like(self.w0t)
            return zeros[0], w0t, zeros[1], rest
        grads = [torch.stack(g, 0) for g in self._grad_outs]  # [E, B, width] per layer
        acts = [torch.stack([self.acts[e][j] for e in order], 0)
                for j in range(len(self.weights) + 1)]
        times = None
        if self.w0t is not None:
            times = [self.times[e] for e in order]
            if not isinstance(times[0], float):
                times = torch.stack(times, 0)  # [E, B, 1]
        return summed_weight_grads(grads, acts, times)


def summed_weight_grads(grads: Sequence[Tensor], acts: Sequence[Tensor],
                        times: list[float] | Tensor | None
                        ) -> tuple[Tensor, Tensor | None, Tensor, list[Tensor]]:
    """An MLP field's weight gradients summed over E evaluations of n states each, one
    matrix product per layer: ``(dW0y, dw0t, db0, [dW1, db1, ...])``.

    Args:
        grads: per layer ``j``, ``[E, n, out_j]`` the gradients w.r.t. its pre-activations
            (contiguous, so every caller sums in the same order).
        acts: per layer ``j``, ``[E, n, in_j]`` its inputs (``acts[0]``: the states).
        times: each evaluation's time: ``E`` floats, or ``[E, n, 1]`` per state; None
            without a time input.
    """
    rest: list[Tensor] = []
    for g, a in zip(grads[1:], acts[1:], strict=True):
        g2 = g.reshape(-1, g.shape[-1])  # [E*n, out]
        rest += [g2.t() @ a.reshape(-1, a.shape[-1]), g2.sum(0)]
    g0, u0 = grads[0], acts[0]
    grad_w0y = g0.flatten(0, 1).t() @ u0.flatten(0, 1)
    grad_b0 = g0.sum((0, 1))
    grad_w0t = None
    if isinstance(times, list):
        grad_w0t = torch.tensor(times, dtype=g0.dtype) @ g0.sum(1)
    elif times is not None:
        grad_w0t = (g0 * times).sum((0, 1))
    return grad_w0y, grad_w0t, grad_b0, rest


def needs_grad(*tensors: Tensor | None) -> bool:
    """Whether a fused solver must record for a backward pass: gradients are enabled and one
    of ``tensors`` (None skipped) requires them."""
    return torch.is_grad_enabled() and any(t is not None and t.requires_grad for t in tensors)
