"""Classic RK4 through an MLP vector field with a hand-written backward pass.

Mathematically this is ``integrate(field, y0, t, SolverSpec("rk4", substeps=s))`` and its
gradient is exactly what autograd computes through those steps (discretise-then-optimise);
tests compare the two. It exists for speed: the NODEs of this project are small (batches of
8 states, widths of 100), so autograd's cost is dominated by per-operation overhead, not
arithmetic. Here the forward pass builds no graph, the backward pass is one reverse sweep of
plain tensor operations, and the weight gradients of all evaluations are summed in one
matrix product per layer (:class:`~clfd_bench.learning.fused_mlp.MLPTape`). Times may be
shared by the batch (``[K]``) or per sample (``[B, K]``, multiple shooting).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial

import torch
from torch import Tensor

from clfd_bench.learning.fused_mlp import FUSED_ACTIVATIONS, MLPTape, needs_grad

__all__ = ["FUSED_ACTIVATIONS", "fused_rk4", "rk4_march", "rk4_march_reverse", "rk4_mlp",
           "sweep_forward", "sweep_reverse"]


def sweep_forward(tape, y0: Tensor, times: Tensor, substeps: int):
    """The RK4 sweep through ``tape`` (an :class:`MLPTape` or any tape with its interface:
    ``tape(t, y, bias)``, ``w0t``, ``b0``); returns ``([B, K, D] states, step sizes)``."""
    per_sample = times.dim() == 2
    n_out = times.shape[-1]
    tk = times if per_sample else times.unsqueeze(0)  # [B or 1, K]
    h = (tk[:, 1:] - tk[:, :-1]) / substeps  # [B|1, K-1]
    s_idx = torch.arange(substeps, dtype=times.dtype)
    base = tk[:, :-1].unsqueeze(-1) + h.unsqueeze(-1) * s_idx  # [B|1, K-1, s]
    # stage times t, t + h/2, t + h of every step: [B|1, n_steps, 3]
    stage_t = torch.stack([base, base + 0.5 * h.unsqueeze(-1), base + h.unsqueeze(-1)], -1)
    n_steps = (n_out - 1) * substeps
    stage_t = stage_t.reshape(tk.shape[0], n_steps, 3)
    hs = h.repeat_interleave(substeps, dim=1)  # [B|1, n_steps]
    if per_sample:
        step_h = [hs[:, i : i + 1] for i in range(n_steps)]  # [B, 1] each
        st = stage_t.permute(1, 2, 0).unsqueeze(-1)  # [n_steps, 3, B, 1]
        stage_times = list(st.reshape(n_steps * 3, -1, 1).unbind(0))
    else:
        step_h = hs[0].tolist()  # Python floats
        stage_times = stage_t[0].reshape(-1).tolist()
    if tape.w0t is None:
        rows = None
    else:  # first-layer bias of every stage in one operation, as a list of views
        rows = (tape.b0 + stage_t.permute(1, 2, 0).unsqueeze(-1) * tape.w0t)
        rows = rows.reshape(n_steps * 3, *rows.shape[2:]).unbind(0)

    def f(u: Tensor, r: int) -> Tensor:
        return tape(stage_times[r], u, None if rows is None else rows[r])

    return torch.stack(rk4_march(f, y0, step_h, n_out, substeps), dim=1), step_h


def rk4_march(f, y0: Tensor, step_h: list, n_out: int, substeps: int) -> list[Tensor]:
    """The classic RK4 steps every fused sweep takes: ``substeps`` steps per output interval,
    ``f(u, r)`` the field at stage ``r`` (stages ``3 s``, ``3 s + 1``, ``3 s + 2`` of step ``s``
    are its times t, t + h/2, t + h). Step sizes are Python floats (times shared by every
    sample) or tensors broadcasting against the states (per-sample times), each with its own
    arithmetic. Returns the ``n_out`` states at the output times, ``y0`` first."""
    y = y0
    out = [y0]
    step = 0
    for _ in range(n_out - 1):
        for _ in range(substeps):
            hh = step_h[step]
            r = 3 * step
            if isinstance(hh, float):
                half = 0.5 * hh
                k1 = f(y, r)
                k2 = f(torch.add(y, k1, alpha=half), r + 1)
                k3 = f(torch.add(y, k2, alpha=half), r + 1)
                k4 = f(torch.add(y, k3, alpha=hh), r + 2)
                y = torch.add(y, torch.add(k1 + k4, k2 + k3, alpha=2.0), alpha=hh / 6)
            else:
                k1 = f(y, r)
                k2 = f(torch.addcmul(y, hh, k1, value=0.5), r + 1)
                k3 = f(torch.addcmul(y, hh, k2, value=0.5), r + 1)
                k4 = f(torch.addcmul(y, hh, k3), r + 2)
                y = torch.addcmul(y, hh, torch.add(k1 + k4, k2 + k3, alpha=2.0), value=1 / 6)
            step += 1
        out.append(y)
    return out


def rk4_march_reverse(vjp, step_h: list, substeps: int, grads: list[Tensor]) -> Tensor:
    """The reverse of :func:`rk4_march`: ``grads[k]`` the gradient w.r.t. output ``k``,
    ``vjp(g, e)`` the field's vector-Jacobian product at evaluation ``e`` (evaluation
    ``4 s + i`` is stage ``i + 1`` of step ``s``). Returns the gradient w.r.t. ``y0``."""
    # Reverse sweep of y' = y + h/6 (k1 + 2 k2 + 2 k3 + k4) with k1 = f(y),
    # k2 = f(y + h/2 k1), k3 = f(y + h/2 k2), k4 = f(y + h k3).

    def scaled(c: float, hh, g: Tensor) -> Tensor:
        return torch.mul(g, c * hh) if isinstance(hh, float) else g * (hh * c)

    def axpy(y: Tensor, c: float, hh, g: Tensor) -> Tensor:
        if isinstance(hh, float):
            return torch.add(y, g, alpha=c * hh)
        return torch.addcmul(y, hh, g, value=c)

    ybar = grads[-1]
    step = len(step_h)
    for k in range(len(grads) - 2, -1, -1):
        for _ in range(substeps):
            step -= 1
            hh = step_h[step]
            e0 = 4 * step
            k1b = scaled(1.0 / 6.0, hh, ybar)
            k2b = scaled(1.0 / 3.0, hh, ybar)
            u4 = vjp(k1b, e0 + 3)
            u3 = vjp(axpy(k2b, 1.0, hh, u4), e0 + 2)
            u2 = vjp(axpy(k2b, 0.5, hh, u3), e0 + 1)
            u1 = vjp(axpy(k1b, 0.5, hh, u2), e0)
            ybar = ybar + (u4 + u3) + (u2 + u1)
        ybar = ybar + grads[k]
    return ybar


class _FusedRK4(torch.autograd.Function):
    """RK4 through a tape, with the hand-written reverse sweep as its backward pass (the
    lone and the stacked fields alike: :func:`fused_rk4`)."""

    @staticmethod
    def forward(ctx, sweeps, make_tape, y0, times, substeps, w0y, w0t, b0, *rest):
        tape = make_tape(w0y, w0t, b0, rest, record=True)
        with torch.no_grad():
            result, step_h = sweeps[0](tape, y0, times, substeps)
        ctx.tape, ctx.step_h, ctx.substeps, ctx.reverse = tape, step_h, substeps, sweeps[1]
        return result

    @staticmethod
    def backward(ctx, grad_out):
        ybar = ctx.reverse(ctx.tape, ctx.step_h, ctx.substeps, grad_out)
        grad_w0y, grad_w0t, grad_b0, grads_rest = ctx.tape.weight_grads()
        return (None, None, ybar, None, None, grad_w0y, grad_w0t, grad_b0, *grads_rest)


def fused_rk4(sweeps, make_tape, y0: Tensor, times: Tensor, substeps: int, w0y: Tensor,
              w0t: Tensor | None, b0: Tensor, rest: Sequence[Tensor]) -> Tensor:
    """RK4 through the tape ``make_tape(w0y, w0t, b0, rest, record=...)`` builds, with
    ``sweeps = (forward, reverse)`` its sweep pair (:func:`sweep_forward` /
    :func:`sweep_reverse`, or the stacked ones); the forward sweep alone, recording nothing,
    when no gradient is needed."""
    if not needs_grad(y0, w0y, w0t, b0, *rest):
        with torch.no_grad():
            tape = make_tape(w0y, w0t, b0, rest, record=False)
            return sweeps[0](tape, y0, times, substeps)[0]
    return _FusedRK4.apply(sweeps, make_tape, y0, times, substeps, w0y, w0t, b0, *rest)


def sweep_reverse(tape, step_h: list, substeps: int, grad_out: Tensor) -> Tensor:
    """The reverse sweep of :func:`sweep_forward` for the output gradient ``grad_out: [B, K, D]``:
    returns the gradient w.r.t. ``y0`` and leaves the weight gradients on ``tape``."""
    tape.start_reverse()
    return rk4_march_reverse(tape.vjp, step_h, substeps, list(grad_out.unbind(1)))


def rk4_mlp(
    y0: Tensor,
    times: Tensor,
    w0y: Tensor,
    w0t: Tensor | None,
    b0: Tensor,
    rest: Sequence[Tensor],
    act: str = "elu",
    substeps: int = 1,
) -> Tensor:
    """RK4-integrate ``f(t, y) = MLP`` from ``y0`` over ``times`` (see the module docstring).

    Args:
        y0: ``[B, D]`` initial states.
        times: ``[K]`` shared or ``[B, K]`` per-sample output times (increasing).
        w0y: ``[H, D]`` first-layer weights on the state.
        w0t: ``[H]`` first-layer weights on the time (NODE^T) or None (NODE^I).
        b0: ``[H]`` first-layer bias.
        rest: ``[W1, b1, ..., WL, bL]`` the remaining layers.
        act: hidden activation, one of :data:`FUSED_ACTIVATIONS`.
        substeps: RK4 steps per output interval.

    Returns:
        ``[B, K, D]`` states at the output times; differentiable w.r.t. ``y0`` and all weights.
    """
    if act not in FUSED_ACTIVATIONS:
        raise ValueError(f"fused RK4 supports activations {FUSED_ACTIVATIONS}, not {act!r}")
    if times.shape[-1] < 2:
        return y0.unsqueeze(1)
    if times.dim() == 2 and times.shape[0] != y0.shape[0]:
        raise ValueError(f"per-sample times [B, K] need B = {y0.shape[0]}, got {times.shape}")
    return fused_rk4((sweep_forward, sweep_reverse), partial(MLPTape, act=act), y0,
                     times.to(y0.dtype), int(substeps), w0y, w0t, b0, rest)
