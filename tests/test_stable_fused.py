"""The fused stable-NODE solvers (hand-written backward) against autograd through the same
steps, in float64: outputs and the gradients of every raw weight, the initial states and the
task embedding, with the clock, an embedding, 2- and 3-layer ICNNs, every fused activation,
RK4 and Euler, shared and per-sample grids."""

from __future__ import annotations

import pytest
import torch

from clfd_bench.learning.odeint import SolverSpec, integrate
from clfd_bench.learning.stable import StableSpec
from clfd_bench.learning.stable_fused import integrate_stable

CASES = [  # clock, cond_dim, lyap_hidden, activation, solver, substeps, per-sample times,
    #         V from g's tangent plane at the goal
    (False, 0, (8, 8), "relu", "rk4", 1, False, False),
    (True, 3, (6, 5, 4), "relu", "rk4", 1, False, False),
    (False, 3, (8, 8), "elu", "rk4", 2, True, False),
    (True, 0, (6, 5, 4), "tanh", "rk4", 1, True, False),
    (True, 3, (8, 8), "tanh", "euler", 2, True, False),
    (False, 0, (6, 5, 4), "relu", "euler", 1, False, False),
    (False, 0, (8, 8), "relu", "rk4", 1, False, True),
    (True, 3, (6, 5, 4), "tanh", "rk4", 2, True, True),
    (False, 3, (8, 8), "elu", "euler", 1, True, True),
]


def _problem(clock, cond_dim, lyap, act, per_sample, seed=0, tangent=False):
    torch.manual_seed(seed)
    spec = StableSpec(2, (16, 16), lyap, clock=clock, cond_dim=cond_dim, activation=act,
                      alpha=0.3, eps=1e-3, rehu_d=0.05, tangent=tangent)
    gen = torch.Generator().manual_seed(seed + 1)
    # 2.5x the initial scale: the projection is active on part of the states (checked)
    weights = [(w * 2.5).requires_grad_() for w in spec.init_weights(gen, torch.float64)]
    cond = torch.randn(cond_dim, dtype=torch.float64, requires_grad=True) if cond_dim else None
    y0 = (2 * torch.randn(5, 2, dtype=torch.float64)).requires_grad_()
    t = torch.linspace(0.0, 1.5, 7, dtype=torch.float64)
    if per_sample:
        t = t.unsqueeze(0) * torch.linspace(0.5, 1.5, 5, dtype=torch.float64).unsqueeze(1)
    return spec, weights, cond, y0, t


@pytest.mark.parametrize("case", CASES, ids=lambda c: "-".join(map(str, c)))
def test_fused_equals_autograd(case):
    clock, cond_dim, lyap, act, solver, substeps, per_sample, tangent = case
    spec, weights, cond, y0, t = _problem(clock, cond_dim, lyap, act, per_sample,
                                          tangent=tangent)
    inputs = [y0, *weights] + ([cond] if cond is not None else [])
    probe = torch.randn(5, 7, 2, dtype=torch.float64)
    results = []
    for fused in (True, False):
        out = integrate(spec.field(weights, cond), y0, t,
                        SolverSpec(solver, substeps=substeps, backend="autograd"), fused=fused)
        assert ("FusedStable" in out.grad_fn.name()) == fused
        grads = torch.autograd.grad((out * probe).sum(), inputs)
        results.append((out.detach(), grads))
    (out_f, grads_f), (out_a, grads_a) = results
    torch.testing.assert_close(out_f, out_a, rtol=0, atol=1e-12)
    # One scale for all gradients: a tensor whose gradient cancels to round-off (a layer
    # saturated on every state) is compared at the scale of the others.
    scale = max(float(g.abs().max()) for g in grads_a)
    for g_f, g_a in zip(grads_f, grads_a, strict=True):
        torch.testing.assert_close(g_f, g_a, rtol=0, atol=1e-11 * scale)
    # The projection was active on part of the states (where it is not, f = f_hat).
    field = spec.field([w.detach() for w in weights], None if cond is None else cond.detach())
    tt = t.expand(5, 7) if t.dim() == 1 else t
    states, times = out_a.reshape(-1, 2), tt.reshape(-1, 1)
    v, dv = field.lyapunov(times, states)
    m = (dv * field.nominal(times, states)).sum(1) + spec.alpha * v
    assert float((m > 0).double().mean()) > 0.1


def test_no_grad_path_and_the_integrate_dispatch():
    spec, weights, cond, y0, t = _problem(True, 3, (8, 8), "relu", False)
    field = spec.field(weights, cond)
    with_grad = integrate_stable(field, y0, t, "rk4", 2)
    with torch.no_grad():
        plain = integrate_stable(field, y0, t, "rk4", 2)
        dispatched = integrate(field, y0, t, SolverSpec("rk4", substeps=2))  # fused default
    assert torch.equal(plain, with_grad.detach()) and torch.equal(plain, dispatched)
    with pytest.raises(ValueError, match="fused stable solvers"):
        integrate_stable(field, y0, t, "midpoint")
