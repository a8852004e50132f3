"""Integrating a NODE: ``y(t) = y0 + int f(tau, y(tau)) dtau`` at given output times.

Two families of solvers behind one function, :func:`integrate`:

* adaptive solvers (``dopri5``, ``dopri8``, ``bosh3``, ``adaptive_heun``) run through
  ``torchdiffeq.odeint`` with the given ``rtol``/``atol``. The paper's original code used
  ``dopri5`` with ``rtol=1e-6, atol=1e-7``; the ``paper`` profiles do the same.
* fixed-grid solvers (``rk4``, ``midpoint``, ``euler``) take ``substeps`` equal steps between
  consecutive output times. They are a plain batched loop over the grid (classic RK4 tableau)
  with Python-float step sizes: far less overhead per step than a general solver, and the
  cost is known in advance. The ``fast`` profiles use ``rk4``.

With the default ``backend="fused"``, ``rk4`` and ``dopri5`` through a NODE
:class:`~clfd_bench.learning.node.VectorField` run the fused solvers
(:mod:`~clfd_bench.learning.rk4_fused`, :mod:`~clfd_bench.learning.dopri5_fused`): the same
algorithms without autograd's per-operation overhead, with a hand-written reverse sweep;
``rk4`` and ``euler`` through a stable NODE :class:`~clfd_bench.learning.stable.StableField`
run :mod:`~clfd_bench.learning.stable_fused` (the same idea).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch
from torch import Tensor

from clfd_bench.learning.dopri5_fused import dopri5_mlp
from clfd_bench.learning.fused_mlp import FUSED_ACTIVATIONS
from clfd_bench.learning.node import VectorField
from clfd_bench.learning.rk4_fused import rk4_mlp
from clfd_bench.learning.stable import StableField
from clfd_bench.learning.stable_fused import FUSED_SOLVERS as STABLE_FUSED_SOLVERS
from clfd_bench.learning.stable_fused import integrate_stable

__all__ = ["ADAPTIVE_SOLVERS", "FIXED_SOLVERS", "SolverSpec", "integrate"]

Field = Callable[[Tensor | float, Tensor], Tensor]

ADAPTIVE_SOLVERS = ("dopri5", "dopri8", "bosh3", "adaptive_heun")
"""Adaptive-step solvers, delegated to ``torchdiffeq.odeint``."""

FIXED_SOLVERS = ("rk4", "midpoint", "euler")
"""Fixed-grid solvers, run by this module."""

BACKENDS = ("fused", "autograd")
"""How solutions are differentiated (see :class:`SolverSpec`)."""


@dataclass(frozen=True)
class SolverSpec:
    """How to integrate.

    Attributes:
        method: one of :data:`ADAPTIVE_SOLVERS` or :data:`FIXED_SOLVERS`.
        rtol, atol: tolerances of adaptive solvers.
        substeps: steps per output interval for fixed-grid solvers.
        backend: ``fused`` -- ``rk4`` and ``dopri5`` through a NODE
            :class:`~clfd_bench.learning.node.VectorField` run the fused solvers
            (:mod:`~clfd_bench.learning.rk4_fused`, :mod:`~clfd_bench.learning.dopri5_fused`;
            same values, gradients by a hand-written reverse sweep); ``autograd`` --
            ``torchdiffeq.odeint`` / the plain loop, differentiated by autograd.
    """

    method: str = "dopri5"
    rtol: float = 1e-6
    atol: float = 1e-7
    substeps: int = 1
    backend: str = "fused"

    def __post_init__(self) -> None:
        if self.method not in ADAPTIVE_SOLVERS + FIXED_SOLVERS:
            raise ValueError(
                f"unknown ODE solver {self.method!r}; valid: "
                f"{', '.join(ADAPTIVE_SOLVERS + FIXED_SOLVERS)}"
            )
        if self.substeps < 1:
            raise ValueError(f"substeps must be >= 1, got {self.substeps}")
        if self.backend not in BACKENDS:
            raise ValueError(
                f"unknown solver backend {self.backend!r}; valid: {', '.join(BACKENDS)}"
            )
        if self.rtol <= 0 or self.atol <= 0:
            raise ValueError(f"rtol and atol must be positive, got {self.rtol}, {self.atol}")


def integrate(
    field: Field, y0: Tensor, t: Tensor, solver: SolverSpec, fused: bool | None = None
) -> Tensor:
    """Solve the initial value problem at the output times.

    Args:
        field: ``f(t, y)``, ``y: [N, D] -> [N, D]``.
        y0: ``[N, D]`` initial states (at ``t[0]``).
        t: ``[T]`` strictly increasing output times (``[N, T]`` per-sample times: with a
            fixed-grid solver; the field is then called with ``[N, 1]`` times).
        solver: the solver and its settings.
        fused: override ``solver.backend`` (True: ``fused``, False: ``autograd``).

    Returns:
        ``[N, T, D]`` states at the output times (``[:, 0]`` is ``y0``).
    """
    if y0.dim() != 2:
        raise ValueError(f"y0 must be [N, D], got shape {tuple(y0.shape)}")
    if t.dim() not in (1, 2) or t.shape[-1] < 1 or (t.dim() == 2 and t.shape[0] != y0.shape[0]):
        raise ValueError(f"t must be [T] or [N, T] with T >= 1, got shape {tuple(t.shape)}")
    if t.shape[-1] == 1:
        return y0.unsqueeze(1)
    if fused is None:
        fused = solver.backend == "fused"
    if (
        fused
        and isinstance(field, VectorField)
        and field.spec.activation in FUSED_ACTIVATIONS
    ):
        if solver.method == "rk4":
            return rk4_mlp(y0, t, field.w0y, field.w0t, field.bias, field.rest,
                           field.spec.activation, solver.substeps)
        if solver.method == "dopri5" and t.dim() == 1:
            return dopri5_mlp(y0, t, field.w0y, field.w0t, field.bias, field.rest,
                              field.spec.activation, solver.rtol, solver.atol)
    if (
        fused
        and isinstance(field, StableField)
        and field.spec.activation in FUSED_ACTIVATIONS
        and solver.method in STABLE_FUSED_SOLVERS
    ):
        return integrate_stable(field, y0, t, solver.method, solver.substeps)
    if t.dim() == 2:
        if solver.method not in FIXED_SOLVERS:
            raise ValueError(f"per-sample times [N, T] need a fixed-grid solver "
                             f"({', '.join(FIXED_SOLVERS)}), got {solver.method!r}")
        return _per_sample_grid(field, y0, t.to(y0.dtype), solver)
    if solver.method in ADAPTIVE_SOLVERS:
        from torchdiffeq import odeint

        out = odeint(
            field, y0, t.to(y0.dtype), method=solver.method, rtol=solver.rtol, atol=solver.atol
        )
        return out.transpose(0, 1)
    step = _STEPS[solver.method]
    times = t.tolist()
    y = y0
    states = [y0]
    n = solver.substeps
    for k in range(len(times) - 1):
        t0 = times[k]
        h = (times[k + 1] - t0) / n
        for s in range(n):
            y = step(field, t0 + s * h, y, h)
        states.append(y)
    return torch.stack(states, dim=1)


def _per_sample_grid(field: Field, y0: Tensor, t: Tensor, solver: SolverSpec) -> Tensor:
    """The fixed-grid loop with each sample on its own time grid ``t: [N, T]``: step sizes
    ``[N, 1]``, the field called with ``[N, 1]`` times."""
    tableau = _TABLEAUX[solver.method]
    n = solver.substeps
    y, states = y0, [y0]
    for k in range(t.shape[1] - 1):
        t0 = t[:, k : k + 1]
        h = (t[:, k + 1 : k + 2] - t0) / n
        for s in range(n):
            y = tableau(field, t0 + s * h, y, h)
        states.append(y)
    return torch.stack(states, dim=1)


def _rk4_tensor(f: Field, t: Tensor, y: Tensor, h: Tensor) -> Tensor:
    half = 0.5 * h
    k1 = f(t, y)
    k2 = f(t + half, y + k1 * half)
    k3 = f(t + half, y + k2 * half)
    k4 = f(t + h, y + k3 * h)
    return y + (k1 + 2.0 * (k2 + k3) + k4) * (h / 6.0)


def _midpoint_tensor(f: Field, t: Tensor, y: Tensor, h: Tensor) -> Tensor:
    return y + f(t + 0.5 * h, y + f(t, y) * (0.5 * h)) * h


def _euler_tensor(f: Field, t: Tensor, y: Tensor, h: Tensor) -> Tensor:
    return y + f(t, y) * h


_TABLEAUX = {"rk4": _rk4_tensor, "midpoint": _midpoint_tensor, "euler": _euler_tensor}
"""The fixed-grid steps with per-sample ``[N, 1]`` times and step sizes."""


def _rk4(f: Field, t: float, y: Tensor, h: float) -> Tensor:
    half = 0.5 * h
    k1 = f(t, y)
    k2 = f(t + half, torch.add(y, k1, alpha=half))
    k3 = f(t + half, torch.add(y, k2, alpha=half))
    k4 = f(t + h, torch.add(y, k3, alpha=h))
    return y + (k1 + 2.0 * (k2 + k3) + k4) * (h / 6.0)


def _midpoint(f: Field, t: float, y: Tensor, h: float) -> Tensor:
    k1 = f(t, y)
    return torch.add(y, f(t + 0.5 * h, torch.add(y, k1, alpha=0.5 * h)), alpha=h)


def _euler(f: Field, t: float, y: Tensor, h: float) -> Tensor:
    return torch.add(y, f(t, y), alpha=h)


_STEPS = {"rk4": _rk4, "midpoint": _midpoint, "euler": _euler}
