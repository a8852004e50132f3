"""Classic RK4 through R independent MLP vector fields at once (batched matrix products).

The stacked analogue of :mod:`~clfd_bench.learning.rk4_fused`: R fields that share their
architecture but not their weights (e.g. R training runs that differ only in seed), each with
its own batch of B states and its own per-sample output times, integrated in ONE sweep. Every
layer of every evaluation is one ``torch.baddbmm`` / ``torch.bmm`` over the R fields, so R
runs cost about as many operations as one; for the small networks of this project the cost is
dominated by per-operation overhead, so R runs take little longer than one.

Row ``r`` of :func:`rk4_mlp_stacked` is :func:`~clfd_bench.learning.rk4_fused.rk4_mlp` on row
``r`` of every argument, with the same RK4 arithmetic in the same order, for times shared by
every sample (Python-float steps, as ``rk4_mlp`` takes them for ``[K]`` times) or per sample
(``[R, B, K]``); field ``r`` may use only its first ``rows[r]`` states (the rest padding).
The backward pass is hand-written as in ``rk4_fused``: one reverse sweep, then each field's
weight gradients summed over its own states exactly as ``MLPTape.weight_grads`` sums them
(one matrix product per layer and field). So the only place where a row can differ from
``rk4_mlp`` is inside a batched product (``bmm`` against ``mm``): on CPU with BLAS the
slices are usually bit-identical, and
:func:`~clfd_bench.learning.objective.stacked_trajectory_losses` checks it per shape before
it uses this pass.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial

import torch
from torch import Tensor

from clfd_bench.learning.fused_mlp import _ACT, FUSED_ACTIVATIONS, MLPTape, summed_weight_grads
from clfd_bench.learning.rk4_fused import fused_rk4, rk4_march, rk4_march_reverse

__all__ = [
    "FUSED_ACTIVATIONS",
    "StackedMLPTape",
    "rk4_mlp_stacked",
    "stacked_sweep_forward",
    "stacked_sweep_reverse",
]


class StackedMLPTape(MLPTape):
    """Evaluations of R independent MLP vector fields, recorded for a later reverse pass.

    The batched analogue of :class:`~clfd_bench.learning.fused_mlp.MLPTape` (whose reverse
    pass, :meth:`~clfd_bench.learning.fused_mlp.MLPTape.vjp`, it runs with batched products);
    every tensor has a leading dimension R (one slice per field).

    Args:
        w0y: ``[R, H, D]`` first-layer weights on the state.
        w0t: ``[R, H]`` first-layer weights on the time, or None.
        b0: ``[R, H]`` first-layer bias.
        rest: ``[W1 [R, out, in], b1 [R, out], ..., WL, bL]``.
        act: hidden activation, one of :data:`FUSED_ACTIVATIONS`.
        record: keep activations (needed for :meth:`vjp`).
        rows: field ``r``'s states are the first ``rows[r]`` of B (None: all B); the weight
            gradients sum over those only.
    """

    _matmul = staticmethod(torch.bmm)

    def __init__(self, w0y: Tensor, w0t: Tensor | None, b0: Tensor, rest: Sequence[Tensor],
                 act: str, record: bool, rows: Sequence[int] | None = None):
        if act not in FUSED_ACTIVATIONS:
            raise ValueError(f"fused solvers support activations {FUSED_ACTIVATIONS}, not {act!r}")
        self.w0y, self.w0t, self.b0, self.act = w0y, w0t, b0, act
        self.weights = list(rest[0::2])  # [R, out, in]
        self.biases = list(rest[1::2])  # [R, out]
        # transposed weights made contiguous once: bmm is markedly faster on them than on
        # transposed views (unlike mm, which passes a transpose flag to BLAS)
        self._weights_t = [w.transpose(1, 2).contiguous() for w in self.weights]  # [R, in, out]
        self._w0y_t = w0y.transpose(1, 2).contiguous()  # [R, D, H]
        self._b0 = b0.unsqueeze(1)  # [R, 1, H]
        self._batch = -1  # B of the biases below, expanded to [R, B, out] (faster baddbmm)
        self._full_biases: list[Tensor] = []
        self._full_b0 = self._b0
        self._w0t = None if w0t is None else w0t.unsqueeze(1)  # [R, 1, H]
        self._act_fn = _ACT[act]
        self.record = record
        self.rows = None if rows is None else [int(r) for r in rows]
        self.acts: list[list[Tensor]] = []  # per evaluation: [input u, hidden activations...]
        self.times: list[float | Tensor] = []  # per evaluation: its time (float or [R, B, 1])
        self._grad_outs: list[list[Tensor]] = [[] for _ in range(len(self.weights) + 1)]
        self._order: list[int] = []

    def bias(self, t: float | Tensor) -> Tensor:
        """First-layer bias at time ``t`` (a float, or ``[R, B, 1]``): ``[R, 1|B, H]``."""
        if self._w0t is None:
            return self._b0
        if isinstance(t, float):
            return torch.add(self._b0, self._w0t, alpha=t)
        return self._b0 + t * self._w0t

    def __call__(self, t: float | Tensor, u: Tensor, bias: Tensor | None = None,
                 record: bool = True) -> Tensor:
        """``f(t, u)`` for ``t`` a float or ``[R, B, 1]``, ``u: [R, B, D]``; ``bias``
        (``[R, B, H]`` or ``[R, 1, H]``) may pass a precomputed :meth:`bias`; ``record=False``
        keeps this evaluation off the tape."""
        act = self._act_fn
        if u.shape[1] != self._batch:
            self._expand_biases(u.shape[1])
        if bias is None:
            bias = self._full_b0 if self._w0t is None else self.bias(t)
        if bias.shape[1] != u.shape[1]:
            bias = bias.expand(u.shape[0], u.shape[1], bias.shape[2])
        z = act(torch.baddbmm(bias, u, self._w0y_t))
        a = [u, z]
        n = len(self._weights_t)
        for j in range(n - 1):
            z = act(torch.baddbmm(self._full_biases[j], z, self._weights_t[j]))
            a.append(z)
        if self.record and record:
            self.acts.append(a)
            self.times.append(t)
        return torch.baddbmm(self._full_biases[n - 1], z, self._weights_t[n - 1])

    def _expand_biases(self, batch: int) -> None:
        r = self.b0.shape[0]
        self._full_biases = [b.unsqueeze(1).expand(r, batch, b.shape[1]).contiguous()
                             for b in self.biases]
        self._full_b0 = self._b0.expand(r, batch, self._b0.shape[2]).contiguous()
        self._batch = batch

    def weight_grads(self) -> tuple[Tensor, Tensor | None, Tensor, list[Tensor]]:
        """``(dW0y, dw0t, db0, [dW1, db1, ...])`` (each ``[R, ...]``) summed over every
        :meth:`vjp` call: per field over its own ``rows`` states, by
        :func:`~clfd_bench.learning.fused_mlp.summed_weight_grads` as ``MLPTape`` sums a
        lone field's (so each field's gradients are those of ``rk4_mlp``)."""
        order = self._order
        if not order:
            rest: list[Tensor] = []
            for w, b in zip(self.weights, self.biases, strict=True):
                rest += [torch.zeros_like(w), torch.zeros_like(b)]
            w0t = None if self.w0t is None else torch.zeros_like(self.w0t)
            return torch.zeros_like(self.w0y), w0t, torch.zeros_like(self.b0), rest
        n_fields, batch = self.w0y.shape[0], self.acts[order[0]][0].shape[1]
        rows = self.rows or [batch] * n_fields
        # every evaluation's layer inputs and output gradients, [R, E, B, width] per layer
        grads = [torch.stack(g, 1) for g in self._grad_outs]
        acts = [torch.stack([self.acts[e][j] for e in order], 1)
                for j in range(len(self.weights) + 1)]
        times = None
        if self.w0t is not None:
            times = [self.times[e] for e in order]
            if not isinstance(times[0], float):
                times = torch.stack(times, 1)  # [R, E, B, 1]

        def own(x: Tensor, r: int) -> Tensor:  # field r's [E, n, width], contiguous
            return x[r, :, : rows[r]].contiguous()

        per_field = [summed_weight_grads([own(g, r) for g in grads], [own(a, r) for a in acts],
                                         times if not isinstance(times, Tensor)
                                         else own(times, r))
                     for r in range(n_fields)]
        grad_w0y, grad_w0t, grad_b0, rest = zip(*per_field, strict=True)
        return (torch.stack(grad_w0y), None if grad_w0t[0] is None else torch.stack(grad_w0t),
                torch.stack(grad_b0), [torch.stack(g) for g in zip(*rest, strict=True)])


def _stage_schedule(times: Tensor, substeps: int):
    """Step sizes per RK4 step and the stage times (t, t + h/2, t + h) of every step, computed
    as in ``rk4_fused.sweep_forward``: for shared times ``[K]`` Python floats and a stage-time
    tensor ``[n_steps * 3, 1, 1, 1]``; for per-sample times ``[R, B, K]`` tensors ``[R, B, 1]``
    and ``[n_steps * 3, R, B, 1]``. Returns ``(step_h, stage_times, stage_t)``."""
    per_sample = times.dim() == 3
    n_out = times.shape[-1]
    tk = times if per_sample else times.reshape(1, 1, -1)  # [R|1, B|1, K]
    h = (tk[..., 1:] - tk[..., :-1]) / substeps  # [R|1, B|1, K-1]
    s_idx = torch.arange(substeps, dtype=times.dtype)
    base = tk[..., :-1].unsqueeze(-1) + h.unsqueeze(-1) * s_idx  # [R|1, B|1, K-1, s]
    stage_t = torch.stack([base, base + 0.5 * h.unsqueeze(-1), base + h.unsqueeze(-1)], -1)
    n_steps = (n_out - 1) * substeps
    r, b = tk.shape[:2]
    stage_t = stage_t.reshape(r, b, n_steps, 3)
    hs = h.repeat_interleave(substeps, dim=2)  # [R|1, B|1, n_steps]
    if per_sample:
        step_h = list(hs.unsqueeze(-1).unbind(2))  # [R, B, 1] each
        stage_times = list(stage_t.permute(2, 3, 0, 1).reshape(n_steps * 3, r, b, 1).unbind(0))
    else:
        step_h = hs[0, 0].tolist()  # Python floats
        stage_times = stage_t[0, 0].reshape(-1).tolist()
    stage_t = stage_t.permute(2, 3, 0, 1).reshape(n_steps * 3, r, b, 1)
    return step_h, stage_times, stage_t


def stacked_sweep_forward(tape: StackedMLPTape, y0: Tensor, times: Tensor, substeps: int):
    """The RK4 sweep of all R fields through ``tape``; returns ``([R, B, K, D] states, step
    sizes)``: the steps of :func:`~clfd_bench.learning.rk4_fused.rk4_march`, as
    ``sweep_forward`` takes them (per sample: tensor steps; shared: Python-float steps)."""
    n_out = times.shape[-1]
    step_h, stage_times, stage_t = _stage_schedule(times, substeps)
    if tape.w0t is None:
        rows = None
    else:  # first-layer bias of every stage in one operation: [n_steps * 3, R, B|1, H]
        rows = (tape.b0.unsqueeze(1) + stage_t * tape.w0t.unsqueeze(1)).unbind(0)

    def f(u: Tensor, r: int) -> Tensor:
        return tape(stage_times[r], u, None if rows is None else rows[r])

    return torch.stack(rk4_march(f, y0, step_h, n_out, substeps), dim=2), step_h


def stacked_sweep_reverse(tape: StackedMLPTape, step_h: list, substeps: int,
                          grad_out: Tensor) -> Tensor:
    """The reverse sweep of :func:`stacked_sweep_forward` for ``grad_out: [R, B, K, D]``:
    returns the gradient w.r.t. ``y0`` and leaves the weight gradients on ``tape``
    (:func:`~clfd_bench.learning.rk4_fused.rk4_march_reverse`, as ``sweep_reverse``)."""
    tape.start_reverse()
    return rk4_march_reverse(tape.vjp, step_h, substeps, list(grad_out.unbind(2)))


def _shape(t: Tensor) -> tuple[int, ...]:
    return tuple(t.shape)


def _check_shapes(y0: Tensor, times: Tensor, w0y: Tensor, w0t: Tensor | None, b0: Tensor,
                  rest: Sequence[Tensor]) -> None:
    if y0.dim() != 3:
        raise ValueError(f"y0 must be [R, B, D], got shape {_shape(y0)}")
    r, b, d = y0.shape
    if not (times.dim() == 1 or (times.dim() == 3 and times.shape[:2] == (r, b))) or (
            times.shape[-1] < 1):
        raise ValueError(f"times must be [K] or [R, B, K] = [{r}, {b}, K] with K >= 1 (y0 "
                         f"is [R, B, D] = {_shape(y0)}), got shape {_shape(times)}")
    if w0y.dim() != 3 or w0y.shape[0] != r or w0y.shape[2] != d:
        raise ValueError(f"w0y must be [R, H, D] = [{r}, H, {d}], got shape {_shape(w0y)}")
    h = w0y.shape[1]
    if _shape(b0) != (r, h):
        raise ValueError(f"b0 must be [R, H] = [{r}, {h}], got shape {_shape(b0)}")
    if w0t is not None and _shape(w0t) != (r, h):
        raise ValueError(f"w0t must be [R, H] = [{r}, {h}] or None, got shape {_shape(w0t)}")
    if len(rest) == 0 or len(rest) % 2:
        raise ValueError(f"rest must be [W1, b1, ..., WL, bL] with L >= 1, got {len(rest)} "
                         "tensors")
    width = h
    for i in range(0, len(rest), 2):
        w, bias = rest[i], rest[i + 1]
        n = i // 2 + 1
        if w.dim() != 3 or w.shape[0] != r or w.shape[2] != width:
            raise ValueError(f"W{n} must be [R, out, in] = [{r}, out, {width}], got shape "
                             f"{_shape(w)}")
        if _shape(bias) != (r, w.shape[1]):
            raise ValueError(f"b{n} must be [R, out] = [{r}, {w.shape[1]}], got shape "
                             f"{_shape(bias)}")
        width = w.shape[1]
    if width != d:
        raise ValueError(f"the last layer must output D = {d} features (y0 is {_shape(y0)}), "
                         f"got {width}")


def rk4_mlp_stacked(
    y0: Tensor,
    times: Tensor,
    w0y: Tensor,
    w0t: Tensor | None,
    b0: Tensor,
    rest: Sequence[Tensor],
    act: str = "elu",
    substeps: int = 1,
    rows: Sequence[int] | None = None,
) -> Tensor:
    """RK4-integrate R independent MLP fields in one sweep (see the module docstring).

    Args:
        y0: ``[R, B, D]`` initial states.
        times: ``[K]`` output times shared by every sample of every field, or ``[R, B, K]``
            per sample (increasing along K).
        w0y: ``[R, H, D]`` first-layer weights on the state.
        w0t: ``[R, H]`` first-layer weights on the time (NODE^T) or None (NODE^I).
        b0: ``[R, H]`` first-layer bias.
        rest: ``[W1 [R, out, in], b1 [R, out], ..., WL, bL]`` the remaining layers.
        act: hidden activation, one of :data:`FUSED_ACTIVATIONS`.
        substeps: RK4 steps per output interval.
        rows: field ``r`` uses the first ``rows[r]`` states only (the others are padding,
            whose output gradient must be zero); None: all B.

    Returns:
        ``[R, B, K, D]``; row ``r`` equals ``rk4_mlp(y0[r], times[r], w0y[r], w0t[r], b0[r],
        [w[r] for w in rest], act, substeps)`` (``times`` for shared times) up to the
        summation order inside batched products (bit for bit where
        :func:`~clfd_bench.learning.objective.stacked_trajectory_losses`' check holds).
        Differentiable w.r.t. ``y0`` and all weights (hand-written backward pass).
    """
    if act not in FUSED_ACTIVATIONS:
        raise ValueError(f"fused RK4 supports activations {FUSED_ACTIVATIONS}, not {act!r}")
    if int(substeps) != substeps or substeps < 1:
        raise ValueError(f"substeps must be a positive integer, got {substeps!r}")
    rest = list(rest)
    _check_shapes(y0, times, w0y, w0t, b0, rest)
    if rows is not None and (len(rows) != y0.shape[0]
                             or not all(1 <= int(n) <= y0.shape[1] for n in rows)):
        raise ValueError(f"rows must give 1..B = {y0.shape[1]} states for each of the "
                         f"R = {y0.shape[0]} fields, got {list(rows)}")
    if times.shape[-1] < 2:
        return y0.unsqueeze(2)
    rows = None if rows is None else tuple(int(n) for n in rows)
    return fused_rk4((stacked_sweep_forward, stacked_sweep_reverse),
                     partial(StackedMLPTape, act=act, rows=rows), y0, times.to(y0.dtype),
                     int(substeps), w0y, w0t, b0, rest)
