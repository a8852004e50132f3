"""NODE vector fields and ODE integration: closed-form solutions, fused RK4 vs autograd."""

from __future__ import annotations

import math

import pytest
import torch

from clfd_bench.learning.mlp import init_mlp_weights, mlp_forward
from clfd_bench.learning.node import NodeSpec, VectorField
from clfd_bench.learning.odeint import SolverSpec, integrate

torch.set_num_threads(1)


def _weights(spec: NodeSpec, seed: int = 0) -> list[torch.nn.Parameter]:
    gen = torch.Generator().manual_seed(seed)
    return [torch.nn.Parameter(w.double()) for w in init_mlp_weights(spec.param_shapes(), gen)]


def test_field_equals_mlp_on_concatenated_input():
    """Folding the embedding and time into the first-layer bias is the same affine map."""
    spec = NodeSpec(dim=2, hidden=(7, 5), time_input=True, cond_dim=3)
    w = _weights(spec)
    emb = torch.randn(3, dtype=torch.float64)
    y = torch.randn(4, 2, dtype=torch.float64)
    t = 0.7
    x = torch.cat([emb.expand(4, 3), y, torch.full((4, 1), t, dtype=torch.float64)], dim=1)
    expected = mlp_forward(x, w, torch.nn.functional.elu)
    assert torch.allclose(VectorField(spec, w, emb)(t, y), expected, atol=1e-12)


def test_field_checks_weight_shapes_and_embedding():
    spec = NodeSpec(dim=2, hidden=(4,), time_input=False)
    w = _weights(spec)
    with pytest.raises(ValueError, match="weights have shapes"):
        VectorField(spec, w[:-1])
    with pytest.raises(ValueError, match="needs no task embedding"):
        VectorField(spec, w, torch.zeros(3))


@pytest.mark.parametrize("method,kwargs,tol", [
    ("rk4", {"substeps": 4}, 2e-5),
    ("dopri5", {"rtol": 1e-9, "atol": 1e-10}, 1e-7),
    ("midpoint", {"substeps": 50}, 1e-3),
])
def test_solvers_match_closed_form_rotation(method, kwargs, tol):
    """dy/dt = A y with A a rotation generator: y(t) = R(t) y0."""
    a = torch.tensor([[0.0, -1.0], [1.0, 0.0]], dtype=torch.float64)
    y0 = torch.tensor([[1.0, 0.0], [0.0, 2.0]], dtype=torch.float64)
    t = torch.linspace(0, math.pi, 9, dtype=torch.float64)
    out = integrate(lambda _t, y: y @ a.t(), y0, t, SolverSpec(method, **kwargs))
    c, s = torch.cos(t), torch.sin(t)
    exact = torch.stack([
        torch.stack([c * y0[i, 0] - s * y0[i, 1], s * y0[i, 0] + c * y0[i, 1]], -1)
        for i in range(2)
    ])
    assert out.shape == (2, 9, 2)
    assert (out - exact).abs().max() < tol


@pytest.mark.parametrize("time_input", [True, False])
@pytest.mark.parametrize("per_sample_times", [False, True])
def test_fused_rk4_equals_autograd_rk4(time_input, per_sample_times):
    """The fused forward/backward gives autograd's values and gradients (float64)."""
    spec = NodeSpec(dim=3, hidden=(6, 5, 4), time_input=time_input, cond_dim=2)
    w = _weights(spec, seed=1)
    emb = torch.nn.Parameter(torch.randn(2, dtype=torch.float64))
    y0 = torch.randn(4, 3, dtype=torch.float64, requires_grad=True)
    t = torch.linspace(0.0, 1.5, 6, dtype=torch.float64)
    if per_sample_times:
        t = t + torch.rand(4, 1, dtype=torch.float64)
    target = torch.randn(4, 6, 3, dtype=torch.float64)
    solver = SolverSpec("rk4", substeps=2)
    results = []
    for fused in (True, False):
        if per_sample_times and not fused:  # reference: one sample at a time
            out = torch.cat([
                integrate(VectorField(spec, w, emb), y0[i : i + 1], t[i], solver, fused=False)
                for i in range(4)
            ])
        else:
            out = integrate(VectorField(spec, w, emb), y0, t, solver, fused=fused)
        loss = (out - target).pow(2).sum()
        results.append((out.detach(), torch.autograd.grad(loss, [*w, emb, y0])))
    (out_f, g_f), (out_a, g_a) = results
    assert torch.allclose(out_f, out_a, atol=1e-13)
    for a, b in zip(g_f, g_a, strict=True):
        assert torch.allclose(a, b, atol=1e-11, rtol=1e-10)


def test_integrate_without_grad_matches_fused_values():
    spec = NodeSpec(dim=2, hidden=(8, 8), time_input=True)
    w = _weights(spec, seed=2)
    y0 = torch.randn(3, 2, dtype=torch.float64)
    t = torch.linspace(0, 2, 11, dtype=torch.float64)
    with torch.no_grad():
        a = integrate(VectorField(spec, w), y0, t, SolverSpec("rk4"))
    b = integrate(VectorField(spec, w), y0, t, SolverSpec("rk4"), fused=False)
    assert torch.allclose(a, b.detach(), atol=1e-13)


def test_unknown_solver_lists_valid_ones():
    with pytest.raises(ValueError, match="valid: dopri5"):
        SolverSpec("rk45")


def test_fused_dopri5_is_torchdiffeqs_dopri5():
    """Same steps and values as torchdiffeq; same gradients once its first step size is a
    constant too (torchdiffeq otherwise keeps a graph from that step size to the slope)."""
    import torchdiffeq

    from clfd_bench.learning.dopri5_fused import initial_step

    spec = NodeSpec(dim=2, hidden=(12, 12, 12), time_input=True, cond_dim=2)
    w = [torch.nn.Parameter(3 * p) for p in _weights(spec, seed=3)]
    emb = torch.nn.Parameter(torch.randn(2, dtype=torch.float64))
    y0 = torch.randn(5, 2, dtype=torch.float64, requires_grad=True)
    t = torch.linspace(0.3, 2.3, 12, dtype=torch.float64)
    target = torch.randn(5, 12, 2, dtype=torch.float64)
    fused = integrate(VectorField(spec, w, emb), y0, t, SolverSpec("dopri5"))
    with torch.no_grad():
        h = initial_step(VectorField(spec, w, emb), float(t[0]), y0, 1e-6, 1e-7)
    ref = torchdiffeq.odeint(VectorField(spec, w, emb), y0, t, method="dopri5", rtol=1e-6,
                             atol=1e-7, options={"first_step": h}).transpose(0, 1)
    assert (fused - ref).abs().max() < 1e-7
    g_fused = torch.autograd.grad((fused - target).pow(2).sum(), [*w, emb, y0])
    g_ref = torch.autograd.grad((ref - target).pow(2).sum(), [*w, emb, y0])
    for a, b in zip(g_fused, g_ref, strict=True):
        assert torch.allclose(a, b, rtol=1e-6, atol=1e-9)
    plain = integrate(VectorField(spec, w, emb), y0, t, SolverSpec("dopri5", backend="autograd"))
    assert (fused - plain).abs().max() < 1e-7  # torchdiffeq picking its own first step
