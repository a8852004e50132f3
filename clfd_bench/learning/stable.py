"""The stable NODE (sNODE): a vector field that is globally asymptotically stable at the
origin by construction (Kolter & Manek 2019, "Learning stable deep dynamics models"; used as
the target network of Auddy et al.'s follow-up, "Scalable and efficient continual learning
from demonstration via a hypernetwork-generated stable dynamics model").

The field is a nominal MLP ``f_hat`` projected so that a learned Lyapunov function ``V``
decreases along it at rate ``alpha``::

    f(z) = f_hat(z) - grad V(z) * relu(<grad V(z), f_hat(z)> + alpha V(z)) / |grad V(z)|^2

so ``dV/dt = <grad V, f> <= -alpha V`` everywhere. ``V`` is positive definite with its only
minimum at the origin::

    V(z) = rehu_1(g(z) - g(0)) + eps |z|^2

with ``g`` an input-convex network (ICNN): hidden layers ``s_i = rehu_d(W_i z + b_i +
softplus(U_i) s_{i-1} / width_i)`` (the passthrough divided by the layer's output width, as
the released code does), output ``g = W_k z + b_k + softplus(U_k) s_{k-1}``. ``rehu_d`` is the
rectified Huber unit (0 below 0, ``u^2 / 2d`` up to ``d``, ``u - d/2`` above). The learner
translates each task so that its goal is the origin, so every prediction converges to the
goal from any start.

``grad V`` is computed in closed form (a backward sweep through the ICNN written with torch
operations), so the field evaluates under ``torch.no_grad()`` and training needs first-order
autograd only (the released code calls ``torch.autograd.grad(create_graph=True)``; same
values).

Inputs: the state ``y``, plus the time as a last coordinate with ``clock = True`` (the
follow-up's released commands, ``--explicit_time 1``: ``f_hat`` and ``V`` see ``[y, t]``, the
nominal field is padded with ``dt/dt = 1`` and the projected time component is dropped). The
clock voids the guarantee (``V``'s minimum is at ``y = 0, t = 0`` and the real clock does not
follow the projection), which is why the ``fast`` profile runs without it. A task embedding
(task-conditioned methods) is a constant input to both networks, folded into their first
biases as :class:`~clfd_bench.learning.node.VectorField` does.

Weight layout (the order a hypernetwork emits them in): the ``f_hat`` MLP ``[W0, b0, ...,
WL, bL]`` (:func:`~clfd_bench.learning.mlp.mlp_param_shapes`), then the ICNN, layer by layer:
``W0, b0`` and for every later layer ``W_i, b_i, U_i``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import Tensor

from clfd_bench.learning.mlp import activation, mlp_forward, mlp_param_shapes
from clfd_bench.learning.node import check_field_inputs

__all__ = [
    "StableField", "StableSpec", "field_state", "lyapunov", "project", "rehu", "rehu_grad",
    "v_and_grad",
]


def rehu(u: Tensor, d: float) -> Tensor:
    """Rectified Huber unit: 0 for ``u <= 0``, ``u^2 / (2d)`` for ``0 < u < d``, ``u - d/2``
    above; continuously differentiable."""
    return rehu_and_grad(u, d)[0]


def rehu_grad(u: Tensor, d: float) -> Tensor:
    """Derivative of :func:`rehu`: ``clamp(u, 0, d) / d`` (0, ``u / d``, 1)."""
    return u.clamp(0.0, d) * (1.0 / d)


def rehu_and_grad(u: Tensor, d: float) -> tuple[Tensor, Tensor]:
    """:func:`rehu` and :func:`rehu_grad` from one clamp, in four operations: the slope
    ``s = c / d`` and the value ``s (u - c / 2)`` with ``c = clamp(u, 0, d)`` (0 below 0,
    ``u^2 / 2d`` up to ``d``, ``u - d/2`` above)."""
    c = u.clamp(0.0, d)
    slope = c * (1.0 / d)
    return slope * torch.add(u, c, alpha=-0.5), slope


@dataclass(frozen=True)
class StableSpec:
    """Architecture of a stable NODE.

    Attributes:
        dim: D, the state dimension.
        hidden: hidden widths of the nominal field ``f_hat``.
        lyap_hidden: hidden widths of the ICNN ``g`` of the Lyapunov function (the follow-up:
            ``(100, 100)``).
        clock: the follow-up's time input (see the module docstring; voids the guarantee).
        cond_dim: size of a task embedding given as an extra input (0: none).
        activation: hidden activation of ``f_hat`` (the follow-up: ``relu``).
        alpha: decay rate of ``V`` along the field (the follow-up: 0.5).
        eps: weight of the quadratic floor ``eps |z|^2`` of ``V`` (the follow-up: 1e-4).
        rehu_d: the ICNN's ReHU width (the follow-up: 0.01).
        tangent: measure ``V`` from the ICNN's tangent plane at the origin,
            ``rehu_1(g(z) - g(0) - grad g(0) . z) + eps |z|^2``, instead of the follow-up's
            ``rehu_1(g(z) - g(0)) + eps |z|^2``. A convex ``g`` lies above its tangent plane,
            so the ReHU term is zero only where ``g`` is affine along the way from the origin
            (the cell around it where no ReHU unit bends); with the follow-up's form it is
            zero wherever ``g`` dips below ``g(0)``, a far larger region (on random weights,
            16-39 % of states against 1-2 %), in which ``V`` is the tiny quadratic floor alone
            and whose edge makes the field stiff (predictions stall on it:
            docs/studies/start.md).
    """

    dim: int
    hidden: tuple[int, ...]
    lyap_hidden: tuple[int, ...] = (100, 100)
    clock: bool = False
    cond_dim: int = 0
    activation: str = "relu"
    alpha: float = 0.5
    eps: float = 1e-4
    rehu_d: float = 0.01
    tangent: bool = False

    def __post_init__(self) -> None:
        activation(self.activation)  # validates the name
        if self.dim < 1 or self.cond_dim < 0 or not self.hidden or not self.lyap_hidden:
            raise ValueError(f"invalid StableSpec {self}: dim >= 1, cond_dim >= 0, hidden and "
                             "lyap_hidden non-empty")
        if self.alpha <= 0 or self.eps <= 0 or self.rehu_d <= 0:
            raise ValueError(f"invalid StableSpec {self}: alpha, eps and rehu_d must be > 0")

    @property
    def time_input(self) -> bool:
        """Whether the field reads the time (the clock)."""
        return self.clock

    @property
    def n_state(self) -> int:
        """Width of the space ``V`` lives in: ``dim`` (+1 with the clock)."""
        return self.dim + int(self.clock)

    @property
    def n_in(self) -> int:
        """Input width of both networks: ``cond_dim + n_state``."""
        return self.cond_dim + self.n_state

    def fhat_shapes(self) -> list[tuple[int, ...]]:
        """Shapes of the nominal field's weights."""
        return mlp_param_shapes(self.n_in, self.hidden, self.dim)

    def icnn_shapes(self) -> list[tuple[int, ...]]:
        """Shapes of the ICNN's weights: ``W0, b0`` then ``W_i, b_i, U_i`` per later layer."""
        sizes = [*self.lyap_hidden, 1]
        shapes: list[tuple[int, ...]] = [(sizes[0], self.n_in), (sizes[0],)]
        for prev, size in zip(sizes[:-1], sizes[1:], strict=True):
            shapes += [(size, self.n_in), (size,), (size, prev)]
        return shapes

    def param_shapes(self) -> list[tuple[int, ...]]:
        """Shapes of all weights: ``f_hat``'s, then the ICNN's."""
        return self.fhat_shapes() + self.icnn_shapes()

    def init_weights(self, generator: torch.Generator | None = None,
                     dtype: torch.dtype = torch.float32) -> list[Tensor]:
        """Fresh weights as ``torch.nn.Linear`` initialises (the released code's choice for
        both networks): every matrix ``U(+-1/sqrt(fan_in))``, every bias
        ``U(+-1/sqrt(fan_in of its layer's W))``."""
        out: list[Tensor] = []
        fan_in = 1
        for shape in self.param_shapes():
            if len(shape) == 2:  # every bias directly follows its layer's W
                fan_in = shape[1]
            bound = 1.0 / math.sqrt(fan_in)
            out.append((torch.rand(shape, generator=generator, dtype=dtype) * 2 - 1) * bound)
        return out

    def field(self, weights: Sequence[Tensor], cond: Tensor | None = None) -> StableField:
        """The vector field with these weights (``param_shapes()``) and task embedding."""
        return StableField(self, weights, cond)


class Icnn:
    """The ICNN ``g`` and its input gradient, for a batch, with the embedding folded in."""

    def __init__(self, spec: StableSpec, weights: Sequence[Tensor], cond: Tensor | None):
        c = spec.cond_dim
        self.w: list[Tensor] = []  # [h_i, n_state] the state columns of W_i
        self.b: list[Tensor] = []  # [h_i] biases with the embedding's part folded in
        self.u: list[Tensor] = []  # [h_i, h_{i-1}] softplus(U_i) / h_i
        self.rehu_d = spec.rehu_d
        k = 0
        for i in range(len(spec.lyap_hidden) + 1):
            w, b = weights[k], weights[k + 1]
            k += 2
            if i > 0:
                u = weights[k]
                k += 1
                scale = 1.0 if i == len(spec.lyap_hidden) else 1.0 / u.shape[0]
                self.u.append(F.softplus(u) * scale)
            self.w.append(w[:, c:])
            self.b.append(b if cond is None else b + w[:, :c] @ cond)

    def value(self, z: Tensor) -> Tensor:
        """``g(z): [B]`` for ``z: [B, n_state]``."""
        pre = torch.addmm(self.b[0], z, self.w[0].t())
        for i in range(1, len(self.w)):
            pre = torch.addmm(self.b[i], z, self.w[i].t()) + rehu(pre, self.rehu_d) @ self.u[
                i - 1].t()
        return pre[:, 0]

    @classmethod
    def from_parts(cls, w: Sequence[Tensor], b: Sequence[Tensor], u: Sequence[Tensor],
                   rehu_d: float) -> Icnn:
        """An ICNN from its derived tensors (state columns, folded biases, passthroughs)."""
        icnn = cls.__new__(cls)
        icnn.w, icnn.b, icnn.u, icnn.rehu_d = list(w), list(b), list(u), rehu_d
        return icnn

    def value_and_grad(self, z: Tensor, record: dict | None = None) -> tuple[Tensor, Tensor]:
        """``g(z): [B]`` and ``dg/dz: [B, n_state]`` for ``z: [B, n_state]``.

        ``record`` (a dict) receives what a reverse pass needs: the pre-activations ``p``,
        the activations ``acts`` and slopes ``s`` of the hidden layers, and the gradient
        recursion's ``q_i = dg/dp_i`` and ``tq_i = q_i @ Ubar_i`` (``q_k = 1`` is None,
        ``tq_k`` the output passthrough row)."""
        d = self.rehu_d
        p = [torch.addmm(self.b[0], z, self.w[0].t())]
        slopes, acts = [], []  # rehu'(p_i), rehu(p_i) of every hidden layer
        for i in range(1, len(self.w)):
            act, slope = rehu_and_grad(p[-1], d)
            acts.append(act)
            slopes.append(slope)
            p.append(torch.addmm(self.b[i], z, self.w[i].t()) + act @ self.u[i - 1].t())
        # backward sweep: q_k = dg/dp_k = 1, q_{i-1} = (q_i @ Ubar_i) * rehu'(p_{i-1})
        k = len(self.w) - 1
        q: list[Tensor | None] = [None] * (k + 1)
        tq: list[Tensor | None] = [None] * (k + 1)
        tq[k] = self.u[-1][0]  # [h_{k-1}] (the output layer has width 1)
        q[k - 1] = slopes[-1] * tq[k]
        grad = self.w[-1][0].expand_as(z)
        for i in range(k - 1, 0, -1):
            grad = torch.addmm(grad, q[i], self.w[i])
            tq[i] = q[i] @ self.u[i - 1]
            q[i - 1] = tq[i] * slopes[i - 1]
        grad = torch.addmm(grad, q[0], self.w[0])
        if record is not None:
            record.update(p=p, acts=acts, s=slopes, q=q, tq=tq)
        return p[-1][:, 0], grad


def field_state(t: Tensor | float, y: Tensor, clock: bool) -> Tensor:
    """The state ``V`` and ``f_hat`` read: ``y: [B, D]``, with the clock ``[y, t]: [B, D + 1]``
    (``t`` a float, a one-element tensor, or ``[B, 1]`` per-sample times; also under vmap)."""
    if not clock:
        return y
    if isinstance(t, Tensor):
        tt = t.to(y.dtype) if t.dim() == 2 else t.to(y.dtype).reshape(1, 1).expand(
            y.shape[0], 1)
    else:
        tt = torch.full((y.shape[0], 1), float(t), dtype=y.dtype, device=y.device)
    return torch.cat([y, tt], dim=1)


def lyapunov(spec: StableSpec, weights: Sequence[Tensor], z: Tensor,
             cond: Tensor | None = None) -> tuple[Tensor, Tensor]:
    """``V(z): [B]`` and ``grad V(z): [B, n_state]`` for ``z: [B, n_state]`` (the state, and
    the time last with the clock). ``V(0) = 0``, ``V(z) >= eps |z|^2``."""
    icnn = Icnn(spec, weights[len(spec.fhat_shapes()):], cond)
    return _lyapunov(spec, icnn, _origin(icnn, spec), z)


def _origin(icnn: Icnn, spec: StableSpec) -> tuple[Tensor, Tensor | None]:
    """V's reference: ``g(0): [1]`` and, with ``spec.tangent``, ``grad g(0): [n_state]``
    (else None); differentiable, so V(0) = 0 for every value of the weights."""
    w = icnn.w[0]
    zero = torch.zeros(1, spec.n_state, dtype=w.dtype, device=w.device)
    if not spec.tangent:
        return icnn.value(zero), None
    g0, dg0 = icnn.value_and_grad(zero)
    return g0, dg0[0]


def _lyapunov(spec: StableSpec, icnn: Icnn, origin: tuple[Tensor, Tensor | None],
              z: Tensor) -> tuple[Tensor, Tensor]:
    g, dg = icnn.value_and_grad(z)
    return v_and_grad(g, origin[0], dg, z, spec.eps, dg0=origin[1])


def v_and_grad(g: Tensor, g0: Tensor, dg: Tensor, z: Tensor, eps: float,
               record: dict | None = None,
               dg0: Tensor | None = None) -> tuple[Tensor, Tensor]:
    """``V = rehu_1(uu) + eps |z|^2: [B]`` and ``grad V = rehu_1'(uu) (dg - dg0) + 2 eps z:
    [B, n]`` from the ICNN's value ``g: [B]`` and gradient ``dg: [B, n]``, with ``uu = g - g0``
    or, given ``dg0 = grad g(0): [n]`` (``StableSpec.tangent``), ``uu = g - g0 - z . dg0``;
    ``record`` receives ``uu``, ``r = rehu_1'(uu)`` and ``grad = dg - dg0``."""
    if dg0 is None:
        u = g - g0
    else:
        u = g - g0 - z @ dg0
        dg = dg - dg0
    outer, slope = rehu_and_grad(u, 1.0)
    v = outer + eps * (z * z).sum(dim=1)
    dv = slope.unsqueeze(1) * dg + (2.0 * eps) * z
    if record is not None:
        record.update(uu=u, r=slope, grad=dg)
    return v, dv


def project(fx: Tensor, v: Tensor, dv: Tensor, alpha: float,
            record: dict | None = None) -> Tensor:
    """``f = fx - dv relu(<dv, fx> + alpha v) / |dv|^2: [B, n]`` (the module docstring);
    ``record`` receives ``m``, ``n2`` (floored), ``n2_ok`` (not floored) and ``coef``."""
    m = (dv * fx).sum(dim=1) + alpha * v
    # |grad V|^2 is 0 only at the origin, where the push is 0 too: the floor avoids 0/0
    tiny = torch.finfo(dv.dtype).tiny
    n2_raw = (dv * dv).sum(dim=1)
    n2 = n2_raw.clamp_min(tiny)
    coef = F.relu(m) / n2
    if record is not None:
        record.update(m=m, n2=n2, n2_ok=n2_raw >= tiny, coef=coef, dv=dv, fx=fx)
    return fx - dv * coef.unsqueeze(1)


class StableField:
    """``dy/dt = f(t, y)`` of a stable NODE, weights given explicitly.

    Args:
        spec: the architecture.
        weights: matching ``spec.param_shapes()`` (may carry gradients).
        cond: ``[cond_dim]`` task embedding when ``spec.cond_dim > 0``.

    Call as ``field(t, y)`` with ``t`` a scalar (or ``[B, 1]`` per-sample times) and
    ``y: [B, dim]``; returns ``[B, dim]``.
    """

    def __init__(self, spec: StableSpec, weights: Sequence[Tensor], cond: Tensor | None = None):
        check_field_inputs("stable NODE", spec, weights, cond)
        self.spec = spec
        n_fhat = len(spec.fhat_shapes())
        fhat = list(weights[:n_fhat])
        c = spec.cond_dim
        self._act = activation(spec.activation)
        self._w0 = fhat[0][:, c:].t()  # [n_state, H]
        d = spec.dim
        self._w0y = fhat[0][:, c : c + d]  # [H, D] and [H]: the state and time columns
        self._w0t = fhat[0][:, c + d] if spec.clock else None
        self._b0 = fhat[1] if cond is None else fhat[1] + fhat[0][:, :c] @ cond
        self._rest = fhat[2:]
        self._icnn = Icnn(spec, weights[n_fhat:], cond)
        self._origin = _origin(self._icnn, spec)  # once per set of weights

    def tape_tensors(self) -> tuple[tuple[Tensor | None, ...], int, int]:
        """What the fused solvers (:mod:`~clfd_bench.learning.stable_fused`) work on:
        ``((w0y, w0t, b0, *rest, *A_i, *c_i, *Ubar_i, g0[, dg0]), len(rest), number of ICNN
        layers)``: the nominal field's first layer split into state ``[H, D]`` and time
        ``[H]`` (None without the clock) columns with the embedding folded into ``b0``, its
        later layers, and the ICNN's state columns, biases, passthroughs, ``g(0)`` and, with
        ``spec.tangent``, ``grad g(0)``."""
        icnn = self._icnn
        g0, dg0 = self._origin
        tensors = (self._w0y, self._w0t, self._b0, *self._rest, *icnn.w, *icnn.b, *icnn.u, g0,
                   *(() if dg0 is None else (dg0,)))
        return tensors, len(self._rest), len(icnn.w)

    def _state(self, t: Tensor | float, y: Tensor) -> Tensor:
        return field_state(t, y, self.spec.clock)

    def nominal(self, t: Tensor | float, y: Tensor) -> Tensor:
        """``f_hat(z)`` padded with ``dt/dt = 1`` under the clock: ``[B, n_state]``."""
        return self._nominal(self._state(t, y))

    def _nominal(self, z: Tensor) -> Tensor:
        fx = mlp_forward(self._act(torch.addmm(self._b0, z, self._w0)), self._rest, self._act)
        if self.spec.clock:
            fx = torch.cat([fx, torch.ones_like(fx[:, :1])], dim=1)
        return fx

    def lyapunov(self, t: Tensor | float, y: Tensor) -> tuple[Tensor, Tensor]:
        """``V`` and ``grad V`` at ``[y, t]`` (``[y]`` without the clock): ``[B]``, ``[B, n]``."""
        return _lyapunov(self.spec, self._icnn, self._origin, self._state(t, y))

    def __call__(self, t: Tensor | float, y: Tensor) -> Tensor:
        z = self._state(t, y)  # once: the nominal field and V read the same [y, t]
        v, dv = _lyapunov(self.spec, self._icnn, self._origin, z)
        return project(self._nominal(z), v, dv, self.spec.alpha)[:, : self.spec.dim]
