"""Fixed-step solvers through a stable NODE with a hand-written backward pass.

``rk4`` and ``euler`` through a :class:`~clfd_bench.learning.stable.StableField`, as
:func:`~clfd_bench.learning.odeint.integrate` computes them with autograd
(discretise-then-optimise; ``tests/test_stable_fused.py`` compares the two to ~1e-12 in
float64), but the forward sweep builds no graph: the field's evaluations are recorded on a
:class:`~clfd_bench.learning.stable_tape.StableTape`, the backward pass is one reverse sweep,
and each weight's gradient is one matrix product over all evaluations. The autograd graph
holds one node per integration instead of ~60 per field evaluation, which is where an
sNODE's training time went (its tensors are small: overhead, not arithmetic).

Times may be shared by the batch (``[K]``) or per sample (``[B, K]``).
"""

from __future__ import annotations

import torch
from torch import Tensor

from clfd_bench.learning import rk4_fused
from clfd_bench.learning.fused_mlp import FUSED_ACTIVATIONS, needs_grad
from clfd_bench.learning.stable import StableField
from clfd_bench.learning.stable_tape import StableTape

__all__ = ["FUSED_SOLVERS", "integrate_stable"]

FUSED_SOLVERS = ("rk4", "euler")


def _tape(settings: tuple, layout: tuple[int, int], tensors: tuple[Tensor | None, ...],
          record: bool) -> StableTape:
    """The tape over ``tensors`` as :meth:`StableField.tape_tensors` lays them out
    (``layout``: the number of later ``f_hat`` layers' tensors and of ICNN layers)."""
    act, dim, clock, alpha, eps, rehu_d, tangent = settings
    n_rest, k = layout
    fhat = (*tensors[:3], list(tensors[3 : 3 + n_rest]))
    i = 3 + n_rest
    a, c, u = tensors[i : i + k], tensors[i + k : i + 2 * k], tensors[i + 2 * k : i + 3 * k - 1]
    g0 = tensors[i + 3 * k - 1]
    dg0 = tensors[i + 3 * k] if tangent else None
    return StableTape(fhat, list(a), list(c), list(u), g0, act, dim, clock, alpha,
                      eps, rehu_d, record, dg0)


def _sweep(tape: StableTape, method: str, y0: Tensor, times: Tensor, substeps: int):
    """The forward sweep of ``method``: ``([B, K, D] states, step sizes)``."""
    if method == "rk4":
        return rk4_fused.sweep_forward(tape, y0, times, substeps)
    return _euler_forward(tape, y0, times, substeps)


def _euler_forward(tape: StableTape, y0: Tensor, times: Tensor, substeps: int):
    """Explicit Euler over ``times`` (``[K]`` or ``[B, K]``) with ``substeps`` steps per
    interval; returns ``([B, K, D] states, the step size of every step)``."""
    per_sample = times.dim() == 2
    tk = times if per_sample else times.unsqueeze(0)
    steps: list[float | Tensor] = []
    y, out = y0, [y0]
    for k in range(tk.shape[1] - 1):
        if per_sample:
            t0 = tk[:, k : k + 1]
            h = (tk[:, k + 1 : k + 2] - t0) / substeps
        else:
            t0 = float(tk[0, k])
            h = (float(tk[0, k + 1]) - t0) / substeps
        for s in range(substeps):
            f = tape(t0 + s * h, y)
            y = torch.add(y, f, alpha=h) if isinstance(h, float) else torch.addcmul(y, h, f)
            steps.append(h)
        out.append(y)
    return torch.stack(out, dim=1), steps


def _euler_reverse(tape: StableTape, steps: list, substeps: int, grad_out: Tensor) -> Tensor:
    """The reverse sweep of :func:`_euler_forward`: ``y' = y + h f(y)`` gives
    ``ybar = ybar' + J^T (h ybar')``."""
    tape.start_reverse()
    ybar = grad_out[:, -1]
    step = len(steps)
    for k in range(grad_out.shape[1] - 2, -1, -1):
        for _ in range(substeps):
            step -= 1
            h = steps[step]
            scaled = torch.mul(ybar, h) if isinstance(h, float) else ybar * h
            ybar = ybar + tape.vjp(scaled, step)
        ybar = ybar + grad_out[:, k]
    return ybar


class _FusedStable(torch.autograd.Function):
    @staticmethod
    def forward(ctx, y0, times, method, substeps, settings, layout, *tensors):
        tape = _tape(settings, layout, tensors, record=True)
        with torch.no_grad():
            result, steps = _sweep(tape, method, y0, times, substeps)
        ctx.tape, ctx.steps, ctx.method, ctx.substeps = tape, steps, method, substeps
        ctx.g0_shape = tape.g0.shape
        return result

    @staticmethod
    def backward(ctx, grad_out):
        tape = ctx.tape
        if ctx.method == "rk4":
            ybar = rk4_fused.sweep_reverse(tape, ctx.steps, ctx.substeps, grad_out)
        else:
            ybar = _euler_reverse(tape, ctx.steps, ctx.substeps, grad_out)
        (w0y, w0t, b0, rest), da, dc, du, dg0 = tape.weight_grads()
        grads = [w0y, w0t, b0, *rest, *da, *dc, *du, dg0.reshape(ctx.g0_shape)]
        tangent = tape.tangent_grad()
        if tangent is not None:
            grads.append(tangent)
        return (ybar, None, None, None, None, None, *grads)


def integrate_stable(field: StableField, y0: Tensor, times: Tensor, method: str,
                     substeps: int = 1) -> Tensor:
    """Integrate the stable NODE ``field`` from ``y0`` over ``times`` (module docstring).

    Args:
        field: the field with its weights (gradients flow to them and to its embedding).
        y0: ``[B, D]`` initial states.
        times: ``[K]`` shared or ``[B, K]`` per-sample output times (increasing).
        method: ``rk4`` or ``euler``.
        substeps: steps per output interval.

    Returns:
        ``[B, K, D]`` states at the output times; differentiable w.r.t. ``y0`` and the weights.
    """
    if method not in FUSED_SOLVERS:
        raise ValueError(f"fused stable solvers: {FUSED_SOLVERS}, not {method!r}")
    spec = field.spec
    if spec.activation not in FUSED_ACTIVATIONS:
        raise ValueError(f"fused solvers support activations {FUSED_ACTIVATIONS}, "
                         f"not {spec.activation!r}")
    if times.shape[-1] < 2:
        return y0.unsqueeze(1)
    if times.dim() == 2 and times.shape[0] != y0.shape[0]:
        raise ValueError(f"per-sample times [B, K] need B = {y0.shape[0]}, got {times.shape}")
    times = times.to(y0.dtype)
    tensors, n_rest, n_layers = field.tape_tensors()
    settings = (spec.activation, spec.dim, spec.clock, spec.alpha, spec.eps, spec.rehu_d,
                spec.tangent)
    layout = (n_rest, n_layers)
    if not needs_grad(y0, *tensors):
        with torch.no_grad():
            tape = _tape(settings, layout, tensors, record=False)
            return _sweep(tape, method, y0, times, int(substeps))[0]
    return _FusedStable.apply(y0, times, method, int(substeps), settings, layout, *tensors)
