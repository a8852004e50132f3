"""torchdiffeq's adaptive dopri5, re-run through an MLP field with a hand-written backward.

The forward pass is the algorithm of ``torchdiffeq.odeint(method="dopri5")`` step for step:
the same Dormand-Prince tableau (read from torchdiffeq), the same initial step selection
(Hairer et al. II.4), RMS error norm over the whole batch, acceptance when the error ratio
is <= 1, the same step-size controller (safety 0.9, growth <= 10, shrink >= 0.2, order 5)
and the same 4th-order dense output between accepted steps. Only floating-point rounding of
the step sizes can differ (they are Python floats here).

The backward pass is the exact gradient of the computed outputs with respect to the
initial states and the weights, holding the accepted step sizes fixed: a reverse sweep over
the accepted steps' stages (FSAL: a step's first stage is the previous step's last) with
:class:`~clfd_bench.learning.fused_mlp.MLPTape`, whose weight gradients are summed in one
matrix product per layer. (Backpropagating through torchdiffeq also holds the step sizes
fixed, except that its very first step size keeps a graph to the initial slope; that term
is dropped here.) This is what makes the ``paper`` profile several times faster than the
original implementation with the same models and mathematics.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import Tensor

from clfd_bench.learning.fused_mlp import MLPTape, needs_grad

__all__ = ["dopri5_mlp", "initial_step"]

try:  # the method's constants, from the library the paper used
    from torchdiffeq._impl.dopri5 import _DORMAND_PRINCE_SHAMPINE_TABLEAU as _TAB
    from torchdiffeq._impl.dopri5 import DPS_C_MID as _MID
except ImportError as exc:  # pragma: no cover - torchdiffeq is a dependency
    raise ImportError(
        "clfd_bench.learning.dopri5_fused reads the Dormand-Prince tableau from torchdiffeq; "
        "install torchdiffeq>=0.2.4"
    ) from exc

ALPHA = [float(a) for a in _TAB.alpha]
BETA = [[float(b) for b in row] for row in _TAB.beta]
C_ERROR = [float(c) for c in _TAB.c_error]
C_MID = [float(c) for c in _MID]
SAFETY, IFACTOR, DFACTOR, ORDER = 0.9, 10.0, 0.2, 5
MAX_STEPS = 100_000


def _rms(x: Tensor) -> float:
    return float(x.pow(2).mean().sqrt())


def _interp_weights(x: float) -> list[float]:
    """Stage weights ``W_j`` of the dense output: ``y(t0 + x dt) = y0 + dt sum_j W_j k_j``.

    torchdiffeq fits ``e + d x + c x^2 + b x^3 + a x^4`` to ``y0, y1, y_mid, f0, f1``; with
    ``y1 = y0 + dt sum_j beta_6j k_j`` and ``y_mid = y0 + dt sum_j c_mid_j k_j`` that
    polynomial is the combination below (the ``y0`` weights sum to one).
    """
    x2, x3, x4 = x * x, x**3, x**4
    w_y1 = -5 * x2 + 14 * x3 - 8 * x4
    w_mid = 16 * x2 - 32 * x3 + 16 * x4
    w_f0 = x - 4 * x2 + 5 * x3 - 2 * x4
    w_f1 = x2 - 3 * x3 + 2 * x4
    last = BETA[-1] + [0.0]
    w = [w_y1 * last[j] + w_mid * C_MID[j] for j in range(7)]
    w[0] += w_f0
    w[6] += w_f1
    return w


def _combine(base: Tensor, terms: Sequence[Tensor], coeffs: Sequence[float], scale: float):
    out = base
    for k, c in zip(terms, coeffs, strict=False):
        if c != 0.0:
            out = torch.add(out, k, alpha=scale * c)
    return out


def initial_step(field, t0: float, y0: Tensor, rtol: float, atol: float,
                 f0: Tensor | None = None) -> float:
    """torchdiffeq's first step size (Hairer, Norsett & Wanner II.4, order 4), as a float.

    Args:
        field: ``f(t, y)``; evaluated once more at ``t0 + h0`` (and at ``t0`` without ``f0``).
    """
    f0 = field(t0, y0) if f0 is None else f0
    scale = atol + y0.abs() * rtol
    d0, d1 = _rms(y0 / scale), _rms(f0 / scale)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    f1 = field(t0 + h0, torch.add(y0, f0, alpha=h0))
    d2 = _rms((f1 - f0) / scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 5.0)
    return min(100 * h0, h1)


def _optimal_step(dt: float, ratio: float) -> float:
    if ratio == 0.0:
        return dt * IFACTOR
    dfactor = 1.0 if ratio < 1.0 else DFACTOR
    return dt * min(IFACTOR, max(SAFETY / ratio ** (1.0 / ORDER), dfactor))


def _forward(tape: MLPTape, y0: Tensor, times: list[float], rtol: float, atol: float):
    """The dopri5 sweep; returns outputs ``[B, K, D]``, accepted steps, output locations."""
    f = tape(times[0], y0)
    f_id = 0
    probe = lambda t, y: tape(t, y, record=False)  # noqa: E731
    dt = initial_step(probe, times[0], y0, rtol, atol, f0=f)

    steps: list[tuple[float, float, list[int]]] = []  # accepted: (t0, dt, stage eval ids)
    t, y = times[0], y0
    current: tuple[float, float, Tensor, list[Tensor]] | None = None
    outputs, locations = [y0], []
    attempts = 0
    for t_out in times[1:]:
        while t_out > t:
            attempts += 1
            if attempts > MAX_STEPS:
                raise RuntimeError(f"dopri5 needed more than {MAX_STEPS} steps (rtol={rtol}); "
                                   "the learned dynamics are too stiff or diverged")
            mark = tape.num_evals
            t1 = t + dt
            ks, ids = [f], [f_id]
            u = y
            for i in range(6):
                ti = t1 if ALPHA[i] == 1.0 else t + ALPHA[i] * dt
                u = _combine(y, ks, BETA[i], dt)
                ids.append(tape.num_evals)
                ks.append(tape(ti, u))
            y1 = u
            err = _combine(torch.zeros_like(y), ks, C_ERROR, dt)
            tol = atol + rtol * torch.maximum(y.abs(), y1.abs())
            ratio = _rms(err / tol)
            if not math.isfinite(ratio):
                raise FloatingPointError("dopri5: non-finite error estimate (diverged dynamics)")
            if ratio <= 1.0:
                steps.append((t, dt, ids))
                current = (t, dt, y, ks)
                y, f, f_id, t = y1, ks[6], ids[6], t1
            else:
                tape.discard_from(mark)
            dt = _optimal_step(dt, ratio)
        t0s, dts, ys, kss = current  # type: ignore[misc]
        x = (t_out - t0s) / dts
        outputs.append(_combine(ys, kss, _interp_weights(x), dts))
        locations.append((len(steps) - 1, x))
    return torch.stack(outputs, dim=1), steps, locations


class _Dopri5MLP(torch.autograd.Function):
    @staticmethod
    def forward(ctx, y0, times, rtol, atol, act, w0y, w0t, b0, *rest):
        tape = MLPTape(w0y, w0t, b0, rest, act, record=True)
        with torch.no_grad():
            out, steps, locations = _forward(tape, y0, times.tolist(), rtol, atol)
        ctx.tape, ctx.steps, ctx.locations = tape, steps, locations
        return out

    @staticmethod
    def backward(ctx, grad_out):
        tape, steps = ctx.tape, ctx.steps
        tape.start_reverse()
        per_step: dict[int, list[tuple[float, Tensor]]] = {}
        for k, (s, x) in enumerate(ctx.locations, start=1):
            per_step.setdefault(s, []).append((x, grad_out[:, k]))

        def acc(a: Tensor | None, b: Tensor) -> Tensor:
            return b if a is None else a + b

        a_next: Tensor | None = None  # adjoint of the state at the end of the step
        carry: Tensor | None = None  # adjoint of the shared FSAL evaluation
        for s in range(len(steps) - 1, -1, -1):
            _, dt, ids = steps[s]
            kbar: list[Tensor | None] = [None] * 7
            kbar[6] = carry
            ybar: Tensor | None = None
            for x, g in per_step.get(s, []):
                ybar = acc(ybar, g)
                for j, w in enumerate(_interp_weights(x)):
                    if w != 0.0:
                        kbar[j] = acc(kbar[j], g * (dt * w))
            if kbar[6] is not None:  # k7 = f(t1, y_{s+1})
                a_next = acc(a_next, tape.vjp(kbar[6], ids[6]))
            if a_next is not None:  # y_{s+1} = y_s + dt sum_j beta_6j k_j
                ybar = acc(ybar, a_next)
                for j, c in enumerate(BETA[5]):
                    if c != 0.0:
                        kbar[j] = acc(kbar[j], a_next * (dt * c))
            for i in range(5, 0, -1):  # k_{i+1} = f(t_i, y_s + dt sum_j beta_{i-1,j} k_j)
                if kbar[i] is None:
                    continue
                u = tape.vjp(kbar[i], ids[i])
                ybar = acc(ybar, u)
                for j, c in enumerate(BETA[i - 1]):
                    if c != 0.0:
                        kbar[j] = acc(kbar[j], u * (dt * c))
            carry = kbar[0]
            if s == 0 and carry is not None:  # the initial slope f(t0, y0)
                ybar = acc(ybar, tape.vjp(carry, ids[0]))
            a_next = ybar
        grad_y0 = grad_out[:, 0] if a_next is None else a_next + grad_out[:, 0]
        grad_w0y, grad_w0t, grad_b0, grads_rest = tape.weight_grads()
        return (grad_y0, None, None, None, None, grad_w0y, grad_w0t, grad_b0, *grads_rest)


def dopri5_mlp(
    y0: Tensor,
    times: Tensor,
    w0y: Tensor,
    w0t: Tensor | None,
    b0: Tensor,
    rest: Sequence[Tensor],
    act: str = "elu",
    rtol: float = 1e-6,
    atol: float = 1e-7,
) -> Tensor:
    """Adaptive dopri5 through ``f(t, y) = MLP`` (see the module docstring).

    Args:
        y0: ``[B, D]`` initial states.
        times: ``[K]`` increasing output times (shared by the batch).
        w0y, w0t, b0, rest, act: the field (:class:`~clfd_bench.learning.fused_mlp.MLPTape`).
        rtol, atol: tolerances (the original code: 1e-6, 1e-7).

    Returns:
        ``[B, K, D]``; differentiable w.r.t. ``y0`` and the weights.
    """
    if times.dim() != 1:
        raise ValueError(f"dopri5 needs times shared by the batch, [K]; got {tuple(times.shape)}")
    if times.shape[0] < 2:
        return y0.unsqueeze(1)
    if not needs_grad(y0, w0y, w0t, b0, *rest):
        with torch.no_grad():
            tape = MLPTape(w0y, w0t, b0, rest, act, record=False)
            return _forward(tape, y0, times.tolist(), rtol, atol)[0]
    return _Dopri5MLP.apply(y0, times.double(), float(rtol), float(atol), act, w0y, w0t, b0,
                            *rest)
