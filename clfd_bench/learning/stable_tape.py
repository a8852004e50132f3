"""The stable NODE's field evaluated without autograd, with a hand-written reverse pass.

The counterpart of :class:`~clfd_bench.learning.fused_mlp.MLPTape` for
:class:`~clfd_bench.learning.stable.StableField`, so the fused solvers
(:mod:`~clfd_bench.learning.stable_fused`) integrate an sNODE with one autograd node per
integration instead of ~60 per field evaluation. Each evaluation records what its reverse
pass needs; :meth:`StableTape.vjp` back-propagates an output gradient to the evaluation's
input state and records the weight gradients, which :meth:`StableTape.weight_grads` sums
over all evaluations in one matrix product per weight at the end.

The tape works on the field's *derived* tensors (the nominal field's first layer split into
state and time parts with the task embedding folded into its bias, the ICNN's state columns
``A_i``, biases ``c_i`` and passthroughs ``Ubar_i = softplus(U_i) / width``, and ``g(0)``);
autograd carries their gradients on to the raw weights and the embedding.

The reverse pass (per evaluation; ``z`` the state, with the clock ``[y, t]``; the ICNN's
pre-activations ``p_i = A_i z + c_i + Ubar_i rehu_d(p_{i-1})``, ``g = p_k``; its input
gradient ``grad g = sum_i A_i^T q_i`` with ``q_k = 1`` and ``q_{i-1} = (Ubar_i^T q_i) *
rehu_d'(p_{i-1})``; ``V = rehu_1(g - g(0)) + eps |z|^2``, ``dV = rehu_1'(.) grad g + 2 eps z``;
``f = f_hat - dV relu(m) / |dV|^2`` with ``m = <dV, f_hat> + alpha V``; with
``StableSpec.tangent`` the ReHU's argument is ``g - g(0) - z . grad g(0)`` and ``grad g`` in
``dV`` becomes ``grad g - grad g(0)``, ``grad g(0)`` one more input) follows these
definitions backwards: the projection, then ``dV``'s two terms, then the ICNN's gradient
recursion (which reaches the pre-activations through ``rehu_d''``), then its value path.
``tests/test_stable_fused.py`` checks every gradient against autograd in float64.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import Tensor

from clfd_bench.learning.fused_mlp import MLPTape
from clfd_bench.learning.stable import Icnn, field_state, project, v_and_grad

__all__ = ["StableTape"]


class StableTape:
    """Evaluations of one stable NODE field, recorded for a later reverse pass.

    Args:
        fhat: ``(w0y [H, D], w0t [H] or None, b0 [H], [W1, b1, ...])``, the nominal field.
        icnn_a: ``[h_i, n]`` the ICNN's state columns, one per layer (``n = D`` or ``D + 1``
            with the clock).
        icnn_c: ``[h_i]`` their biases (the embedding folded in).
        icnn_u: ``[h_i, h_{i-1}]`` the passthroughs ``Ubar_i`` of layers 1..k.
        g0: ``[]`` the ICNN's value at the origin.
        dg0: ``[n]`` its gradient there when ``V`` is measured from the tangent plane
            (:attr:`~clfd_bench.learning.stable.StableSpec.tangent`), else None.
        act: the nominal field's activation (one of the fused MLP's).
        dim, clock, alpha, eps, rehu_d: as :class:`~clfd_bench.learning.stable.StableSpec`.
        record: keep what :meth:`vjp` needs.
    """

    def __init__(self, fhat: tuple[Tensor, Tensor | None, Tensor, Sequence[Tensor]],
                 icnn_a: Sequence[Tensor], icnn_c: Sequence[Tensor],
                 icnn_u: Sequence[Tensor], g0: Tensor, act: str, dim: int, clock: bool,
                 alpha: float, eps: float, rehu_d: float, record: bool,
                 dg0: Tensor | None = None):
        w0y, w0t, b0, rest = fhat
        self.mlp = MLPTape(w0y, w0t, b0, rest, act, record)
        self.icnn = Icnn.from_parts(icnn_a, icnn_c, icnn_u, rehu_d)
        self.a, self.c, self.u = self.icnn.w, self.icnn.b, self.icnn.u
        self._a_t = [a.t() for a in self.a]
        self._u_t = [u.t() for u in self.u]
        self.g0, self.dg0 = g0, dg0
        self.dim, self.clock = dim, clock
        self.alpha, self.eps, self.d = alpha, eps, rehu_d
        self.record = record
        self.w0t = None  # the solvers precompute no first-layer biases for this tape
        self.evals: list[dict[str, Tensor | list[Tensor]]] = []
        self.start_reverse()

    # forward ------------------------------------------------------------------------------

    def __call__(self, t: float | Tensor, y: Tensor, bias: Tensor | None = None,
                 record: bool = True) -> Tensor:
        """``f(t, y)`` for ``y: [B, D]`` (``bias`` is unused: no precomputed biases). The
        same functions as :class:`~clfd_bench.learning.stable.StableField` compute it."""
        keep = self.record and record
        rec: dict | None = {} if keep else None
        fx = self.mlp(t, y, record=keep)  # [B, D]
        if self.clock:
            fx = torch.cat([fx, torch.ones_like(fx[:, :1])], dim=1)
        z = field_state(t, y, self.clock)
        g, grad = self.icnn.value_and_grad(z, rec)
        v, dv = v_and_grad(g, self.g0, grad, z, self.eps, rec, self.dg0)
        out = project(fx, v, dv, self.alpha, rec)
        if rec is not None:
            rec["z"] = z
            self.evals.append(rec)
        return out[:, : self.dim]

    # reverse ------------------------------------------------------------------------------

    @property
    def num_evals(self) -> int:
        """Evaluations recorded so far (the index of the next one)."""
        return len(self.evals)

    def discard_from(self, index: int) -> None:
        """Forget evaluations ``index, index + 1, ...`` (a rejected adaptive step)."""
        del self.evals[index:]
        self.mlp.discard_from(index)

    def start_reverse(self) -> None:
        """Clear the recorded gradients (a reverse pass may run more than once)."""
        self.mlp.start_reverse()
        k = len(self.a)
        self._a_pairs: list[list[tuple[Tensor, Tensor]]] = [[] for _ in range(k)]
        self._u_pairs: list[list[tuple[Tensor, Tensor]]] = [[] for _ in range(k - 1)]
        self._c_grads: list[list[Tensor]] = [[] for _ in range(k)]
        self._g0_grad: list[Tensor] = []
        self._dg0_grad: list[Tensor] = []

    def vjp(self, gbar: Tensor, e: int) -> Tensor:
        """``J_e^T gbar``: the gradient w.r.t. evaluation ``e``'s input state ``[B, D]`` for
        the output gradient ``gbar: [B, D]``; records the weight gradients."""
        r = self.evals[e]
        z, dv, fx, coef = r["z"], r["dv"], r["fx"], r["coef"]
        fbar = gbar if not self.clock else F.pad(gbar, (0, 1))
        # f = fx - coef * dv
        fx_bar = fbar
        coef_bar = -(fbar * dv).sum(dim=1)
        dv_bar = fbar * (-coef).unsqueeze(1)
        # coef = relu(m) / n2
        n2 = r["n2"]
        m_bar = (coef_bar / n2) * (r["m"] > 0)
        n2_bar = -coef_bar * coef / n2 * r["n2_ok"]
        dv_bar = dv_bar + (2.0 * n2_bar).unsqueeze(1) * dv + m_bar.unsqueeze(1) * fx
        fx_bar = fx_bar + m_bar.unsqueeze(1) * dv
        v_bar = self.alpha * m_bar
        # V = rehu_1(uu) + eps |z|^2 ;  dv = r * grad + 2 eps z  (r = rehu_1'(uu))
        z_bar = (2.0 * self.eps) * (v_bar.unsqueeze(1) * z + dv_bar)
        uu = r["uu"]
        u_bar = v_bar * r["r"] + (dv_bar * r["grad"]).sum(dim=1) * ((uu > 0) & (uu < 1.0))
        w = r["r"].unsqueeze(1) * dv_bar  # gradient w.r.t. grad g: [B, n]
        self._g0_grad.append(-u_bar.sum())
        if self.dg0 is not None:  # uu = g - g0 - z . dg0, dv = r (grad g - dg0) + 2 eps z
            z_bar = z_bar - u_bar.unsqueeze(1) * self.dg0
            self._dg0_grad.append(-(u_bar.unsqueeze(1) * z).sum(0) - w.sum(0))
        # grad g = sum_i A_i^T q_i, q_{i-1} = tq_i * s_{i-1}, tq_i = q_i @ Ubar_i
        p, s, q, tq, acts = r["p"], r["s"], r["q"], r["tq"], r["acts"]
        k = len(self.a) - 1
        d = self.d
        p_bar: list[Tensor | None] = [None] * (k + 1)
        q = [*q[:k], torch.ones_like(z[:, :1])]  # q_k = dg/dg = 1: [B, 1]
        q_bar = w @ self._a_t[0]  # [B, h_0]
        for i in range(k + 1):
            self._a_pairs[i].append((q[i], w))
        for i in range(1, k + 1):
            tq_bar = q_bar * s[i - 1]
            s_bar = q_bar * tq[i]
            self._u_pairs[i - 1].append((q[i], tq_bar))
            pc = p[i - 1]
            p_bar[i - 1] = s_bar * ((pc > 0) & (pc < d)) * (1.0 / d)
            if i < k:  # q_k = 1 is a constant
                q_bar = w @ self._a_t[i] + tq_bar @ self._u_t[i - 1]
        # the value path: p_k gets u_bar (g = p_k), then back through the layers
        pk = u_bar.unsqueeze(1)
        for i in range(k, 0, -1):
            self._a_pairs[i].append((pk, z))
            self._c_grads[i].append(pk.sum(0))
            self._u_pairs[i - 1].append((pk, acts[i - 1]))
            z_bar = torch.addmm(z_bar, pk, self.a[i])
            pk = p_bar[i - 1] + (pk @ self.u[i - 1]) * s[i - 1]
        self._a_pairs[0].append((pk, z))
        self._c_grads[0].append(pk.sum(0))
        z_bar = torch.addmm(z_bar, pk, self.a[0])
        y_bar = self.mlp.vjp(fx_bar[:, : self.dim], e)
        return y_bar + z_bar[:, : self.dim]

    def weight_grads(self) -> tuple[tuple[Tensor, Tensor | None, Tensor, list[Tensor]],
                                    list[Tensor], list[Tensor], list[Tensor], Tensor]:
        """``(f_hat's (dW0y, dw0t, db0, [dW1, db1, ...]), [dA_i], [dc_i], [dUbar_i], dg0)``
        summed over every :meth:`vjp` call."""
        fhat = self.mlp.weight_grads()

        def pairs_sum(pairs: list[tuple[Tensor, Tensor]], like: Tensor) -> Tensor:
            if not pairs:
                return torch.zeros_like(like)
            left = torch.cat([a for a, _ in pairs], 0)
            right = torch.cat([b for _, b in pairs], 0)
            return left.t() @ right

        da = [pairs_sum(pl, a) for pl, a in zip(self._a_pairs, self.a, strict=True)]
        du = [pairs_sum(pl, u) for pl, u in zip(self._u_pairs, self.u, strict=True)]
        dc = [torch.stack(g).sum(0) if g else torch.zeros_like(c)
              for g, c in zip(self._c_grads, self.c, strict=True)]
        dg0 = torch.stack(self._g0_grad).sum() if self._g0_grad else torch.zeros_like(self.g0)
        return fhat, da, dc, du, dg0

    def tangent_grad(self) -> Tensor | None:
        """The gradient w.r.t. ``dg0`` summed over every :meth:`vjp` call (None without it)."""
        if self.dg0 is None:
            return None
        if not self._dg0_grad:
            return torch.zeros_like(self.dg0)
        return torch.stack(self._dg0_grad).sum(0)
