"""Hypernetworks: shape checks, batched evaluation, the look-ahead step, gradient check."""

from __future__ import annotations

import pytest
import torch

from clfd_bench.learning.hnet_reg import adam_lookahead, output_regularizer
from clfd_bench.learning.hypernet import ChunkedHyperNetwork, HyperNetwork
from clfd_bench.learning.mlp import num_weights
from clfd_bench.learning.node import NodeSpec, VectorField
from clfd_bench.learning.odeint import SolverSpec, integrate

torch.set_num_threads(1)
SPEC = NodeSpec(dim=2, hidden=(6, 6), time_input=True)


def _hnets(dtype=torch.float32):
    torch.manual_seed(0)
    hn = HyperNetwork(SPEC.param_shapes(), emb_dim=3, hidden=(5, 4)).to(dtype)
    chn = ChunkedHyperNetwork(SPEC.param_shapes(), emb_dim=3, hidden=(5,), chunk_emb_dim=2,
                              chunk_dim=16).to(dtype)
    return hn, chn


def test_output_size_matches_target_network():
    hn, chn = _hnets()
    p = num_weights(SPEC.param_shapes())
    e = torch.randn(3)
    assert hn(e).shape == (p,) and chn(e).shape == (p,)
    assert chn.num_chunks == -(-p // 16)
    weights = hn.target_weights(e)
    assert [tuple(w.shape) for w in weights] == SPEC.param_shapes()
    VectorField(SPEC, chn.target_weights(e))  # accepted by the target network


@pytest.mark.parametrize("shapes,msg", [
    ([], "at least one target tensor"),
    ([(4, 3), (4, 0)], "target tensor 1 has shape \\(4, 0\\)"),
    ([(4, 3), ()], "target tensor 1 has shape \\(\\)"),
])
def test_construction_rejects_impossible_target_shapes(shapes, msg):
    with pytest.raises(ValueError, match=msg):
        HyperNetwork(shapes, emb_dim=2, hidden=(3,))
    with pytest.raises(ValueError, match=msg):
        ChunkedHyperNetwork(shapes, emb_dim=2, hidden=(3,), chunk_emb_dim=2, chunk_dim=4)


def test_batched_forward_equals_one_by_one():
    for net in _hnets():
        embs = torch.randn(4, 3)
        batched = net(embs)
        for i in range(4):
            assert torch.allclose(batched[i], net(embs[i]), atol=1e-6)


@pytest.mark.parametrize("which", [0, 1])
def test_regulariser_modes_agree(which):
    """'batched' is the paper's loop ('all') in one pass: same value and gradient."""
    net = _hnets(torch.float64)[which]
    embs = torch.randn(3, 3, dtype=torch.float64)
    targets = net(embs).detach() + 0.1 * torch.randn(3, net.num_outputs, dtype=torch.float64)
    delta = [1e-3 * torch.randn_like(p) for p in net.regularized]
    values, grads = [], []
    for mode in ("all", "batched", "sampled"):
        r = output_regularizer(net, embs, targets, delta, mode=mode, samples=5)
        values.append(r.detach())
        grads.append(torch.autograd.grad(r, net.regularized))
    for v, g in zip(values[1:], grads[1:], strict=True):
        assert torch.allclose(v, values[0], rtol=1e-12)
        for a, b in zip(g, grads[0], strict=True):
            assert torch.allclose(a, b, atol=1e-12)


def test_sampled_regulariser_uses_the_requested_number_of_tasks():
    net = _hnets(torch.float64)[0]
    embs = torch.randn(5, 3, dtype=torch.float64)
    targets = net(embs).detach()
    targets[3] += 1.0  # only task 3 is off its target, by 1 in every output
    gen = torch.Generator().manual_seed(0)
    with torch.no_grad():
        values = [float(output_regularizer(net, embs, targets, None, "sampled", 1, gen))
                  for _ in range(40)]
    hits = [v for v in values if abs(v - net.num_outputs) < 1e-6]
    assert all(abs(v) < 1e-12 for v in values if v not in hits)
    assert 0 < len(hits) < 40  # task 3 is drawn sometimes, never two tasks at once


def test_sampled_regulariser_is_the_follow_ups_stochastic_one():
    """clfd-snode's calc_fix_target_reg_stochastic: ``num_regs`` distinct earlier tasks per
    step, the sum divided by how many were drawn; all of them when there are fewer."""
    from itertools import combinations

    net = _hnets(torch.float64)[0]
    embs = torch.randn(5, 3, dtype=torch.float64)
    offsets = torch.tensor([0.5, 1.0, 2.0, 3.0, 5.0], dtype=torch.float64)
    targets = net(embs).detach() + offsets[:, None]  # task i off by offsets[i] everywhere
    per_task = net.num_outputs * offsets**2  # its squared distance
    pairs = {round(float(per_task[list(c)].mean()), 9): c for c in combinations(range(5), 2)}
    gen = torch.Generator().manual_seed(1)
    with torch.no_grad():
        drawn = {round(float(output_regularizer(net, embs, targets, None, "sampled", 2, gen)), 9)
                 for _ in range(200)}
        every = float(output_regularizer(net, embs, targets, None, "sampled", 7, gen))
    assert drawn <= set(pairs)  # always two distinct tasks, divided by 2 (not by 5)
    assert len(drawn) == len(pairs)  # every pair is drawn
    assert every == pytest.approx(float(per_task.mean()), rel=1e-12)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_lookahead_is_the_step_adam_takes(dtype):
    """float32: the compiled pass; float64: the same formula in torch. Both against the step
    torch's Adam then takes, from its first step (no state yet) on."""
    torch.manual_seed(0)
    params = [torch.nn.Parameter(torch.randn(20, 3, dtype=dtype)),
              torch.nn.Parameter(torch.randn(7, dtype=dtype))]
    opt = torch.optim.Adam(params, lr=0.01)
    buffers = [torch.full_like(p, float("nan")) for p in params]
    for _ in range(4):
        for p in params:
            p.grad = torch.randn_like(p) * 10.0 ** float(torch.randint(-4, 2, ()))
        predicted = adam_lookahead(opt, params, out=buffers)
        assert all(a is b for a, b in zip(predicted, buffers, strict=True))
        fresh = adam_lookahead(opt, params)
        before = [p.detach().clone() for p in params]
        opt.step()
        taken = [p.detach() - b for p, b in zip(params, before, strict=True)]
        for a, b, c in zip(predicted, taken, fresh, strict=True):
            assert torch.equal(a, c)
            assert torch.allclose(a, b, atol=1e-7, rtol=1e-4)
    params[1].grad = None
    assert adam_lookahead(opt, params, out=buffers)[1].eq(0).all()


def _trajectory_of(net, spec, y0, t):
    """(embedding, output-layer weights) -> RK4 trajectory of the generated NODE."""

    def traj(e, w):
        params = list(net.regularized)
        params[-2] = w
        delta = [q - p for q, p in zip(params, net.regularized, strict=True)]
        weights = net.target_weights(e, delta)
        return integrate(VectorField(spec, weights), y0, t, SolverSpec("rk4", substeps=2))

    return traj


def test_gradcheck_through_hypernetwork_and_target_node():
    """float64 gradcheck: embedding / hypernetwork weights -> NODE weights -> RK4 trajectory."""
    torch.manual_seed(0)
    spec = NodeSpec(dim=2, hidden=(4, 4), time_input=True)
    for net in (
        HyperNetwork(spec.param_shapes(), emb_dim=3, hidden=(4,)).double(),
        ChunkedHyperNetwork(spec.param_shapes(), emb_dim=3, hidden=(4,), chunk_emb_dim=2,
                            chunk_dim=8).double(),
    ):
        y0 = torch.randn(3, 2, dtype=torch.float64)
        t = torch.linspace(0, 1, 5, dtype=torch.float64)
        emb = torch.randn(3, dtype=torch.float64, requires_grad=True)
        w0 = net.regularized[-2].detach().clone().requires_grad_(True)  # output layer
        assert torch.autograd.gradcheck(_trajectory_of(net, spec, y0, t), (emb, w0),
                                        eps=1e-6, atol=1e-5)
