"""rk4_mlp_stacked: R independent MLP fields in one RK4 sweep equal R calls of rk4_mlp."""

from __future__ import annotations

import itertools

import pytest
import torch

from clfd_bench.learning.fused_mlp import MLPTape
from clfd_bench.learning.rk4_fused import rk4_mlp
from clfd_bench.learning.rk4_stacked import StackedMLPTape, rk4_mlp_stacked

torch.set_num_threads(1)

# Tolerance: max |stacked - per-row| <= REL_TOL * max |per-row| (per output / per gradient
# tensor). Observed on the development machine (float32, torch 2.13 CPU, 1 thread) over the
# whole grid below: forward 1.41e-7, gradients 2.94e-7 (relative). The hidden (32, 32, 32)
# cases were bit-identical there and only the (16, 16) ones differed (bmm vs mm summation
# order), but that is a property of the BLAS kernels, not of this code, so they share the
# tolerance rather than asserting equality.
REL_TOL = 1e-6

R, B, K = 3, 7, 40
GRID = list(itertools.product(
    (2, 3),  # D
    ((32, 32, 32), (16, 16)),  # hidden
    (True, False),  # time input (w0t)
    ("elu", "tanh", "relu"),  # activation
    (1, 2),  # substeps
))


def _make(r: int, b: int, d: int, k: int, hidden, time: bool, seed: int = 0,
          dtype=torch.float32):
    """Random stacked weights (nn.Linear-like scale), states, per-sample times and targets."""
    g = torch.Generator().manual_seed(seed)

    def uniform(*shape, fan_in):
        return (torch.rand(*shape, generator=g, dtype=dtype) * 2 - 1) / fan_in**0.5

    y0 = torch.randn(r, b, d, generator=g, dtype=dtype)
    dt = torch.rand(r, b, k - 1, generator=g, dtype=dtype) * 0.05 + 0.01
    t0 = torch.rand(r, b, 1, generator=g, dtype=dtype)
    times = torch.cat([t0, t0 + dt.cumsum(-1)], -1)  # [R, B, K], increasing, per sample
    fan = d + int(time)
    w0y = uniform(r, hidden[0], d, fan_in=fan)
    w0t = uniform(r, hidden[0], fan_in=fan) if time else None
    b0 = uniform(r, hidden[0], fan_in=fan)
    rest, prev = [], hidden[0]
    for width in [*hidden[1:], d]:
        rest += [uniform(r, width, prev, fan_in=prev), uniform(r, width, fan_in=prev)]
        prev = width
    target = torch.randn(r, b, k, d, generator=g, dtype=dtype)
    return y0, times, w0y, w0t, b0, rest, target


def _params(y0, w0y, w0t, b0, rest) -> list[torch.Tensor]:
    return [y0, w0y, b0, *rest] + ([] if w0t is None else [w0t])


def _row(r, y0, times, w0y, w0t, b0, rest):
    return y0[r], times[r], w0y[r], None if w0t is None else w0t[r], b0[r], [w[r] for w in rest]


def _stacked_loss_grads(y0, times, w0y, w0t, b0, rest, target, act, substeps):
    params = [p.detach().requires_grad_(True) for p in _params(y0, w0y, w0t, b0, rest)]
    y0, w0y, b0, *tail = params
    rest, w0t = (tail[:-1], tail[-1]) if w0t is not None else (tail, None)
    out = rk4_mlp_stacked(y0, times, w0y, w0t, b0, rest, act, substeps)
    loss = ((out - target) ** 2).mean((1, 2, 3)).sum()
    return out.detach(), torch.autograd.grad(loss, params)


def _per_row_loss_grads(y0, times, w0y, w0t, b0, rest, target, act, substeps):
    params = [p.detach().requires_grad_(True) for p in _params(y0, w0y, w0t, b0, rest)]
    y0, w0y, b0, *tail = params
    rest, w0t = (tail[:-1], tail[-1]) if w0t is not None else (tail, None)
    outs = [rk4_mlp(*_row(r, y0, times, w0y, w0t, b0, rest), act, substeps)
            for r in range(y0.shape[0])]
    loss = sum(((o - target[r]) ** 2).mean() for r, o in enumerate(outs))
    return torch.stack(outs).detach(), torch.autograd.grad(loss, params)


def _assert_close(got: torch.Tensor, ref: torch.Tensor, what: str) -> None:
    assert got.shape == ref.shape, what
    err = (got - ref).abs().max().item()
    scale = ref.abs().max().item()
    assert err <= REL_TOL * scale, f"{what}: max |diff| {err:.3g} > {REL_TOL} * {scale:.3g}"


@pytest.mark.parametrize("d, hidden, time, act, substeps", GRID)
def test_forward_rows_equal_rk4_mlp(d, hidden, time, act, substeps):
    y0, times, w0y, w0t, b0, rest, _ = _make(R, B, d, K, hidden, time)
    out = rk4_mlp_stacked(y0, times, w0y, w0t, b0, rest, act, substeps)  # no grad: plain sweep
    assert out.shape == (R, B, K, d)
    for r in range(R):
        ref = rk4_mlp(*_row(r, y0, times, w0y, w0t, b0, rest), act, substeps)
        _assert_close(out[r], ref, f"row {r}")


@pytest.mark.parametrize("d, hidden, time, act, substeps", GRID)
def test_gradients_equal_sum_of_per_row_gradients(d, hidden, time, act, substeps):
    args = _make(R, B, d, K, hidden, time)
    out, grads = _stacked_loss_grads(*args, act, substeps)
    ref_out, ref_grads = _per_row_loss_grads(*args, act, substeps)
    # the recording forward (autograd.Function) computes exactly what the plain sweep does
    assert torch.equal(out, rk4_mlp_stacked(*args[:6], act, substeps))
    _assert_close(out, ref_out, "output")
    names = ["y0", "w0y", "b0", *[f"rest[{i}]" for i in range(len(args[5]))]]
    names += ["w0t"] if time else []
    assert len(grads) == len(names)
    for name, got, ref in zip(names, grads, ref_grads, strict=True):
        _assert_close(got, ref, f"grad {name}")


@pytest.mark.parametrize("hidden, time", [((32, 32, 32), True), ((16, 16), False)])
def test_single_run_equals_rk4_mlp(hidden, time):
    # observed: 0 for (32, 32, 32), max |diff| 1.2e-7 (forward) / 6e-8 (gradients) for (16, 16)
    args = _make(1, B, 2, K, hidden, time, seed=1)
    out, grads = _stacked_loss_grads(*args, "elu", 2)
    ref_out, ref_grads = _per_row_loss_grads(*args, "elu", 2)
    _assert_close(out, ref_out, "output")
    for i, (got, ref) in enumerate(zip(grads, ref_grads, strict=True)):
        _assert_close(got, ref, f"grad {i}")


def test_rows_are_independent():
    y0, times, w0y, w0t, b0, rest, target = _make(R, B, 2, K, (16, 16), True, seed=2)
    out, grads = _stacked_loss_grads(y0, times, w0y, w0t, b0, rest, target, "tanh", 1)
    g = torch.Generator().manual_seed(3)

    def bump(p):
        p = p.clone()
        p[1] += 0.3 * torch.randn(p[1].shape, generator=g)
        return p

    y0b, w0yb, w0tb, b0b = bump(y0), bump(w0y), bump(w0t), bump(b0)
    restb = [bump(p) for p in rest]
    out2, grads2 = _stacked_loss_grads(y0b, times, w0yb, w0tb, b0b, restb, target, "tanh", 1)
    assert not torch.equal(out[1], out2[1])
    for r in (0, 2):
        assert torch.equal(out[r], out2[r])
        for i, (a, b) in enumerate(zip(grads, grads2, strict=True)):
            assert torch.equal(a[r], b[r]), f"grad {i} row {r}"


def test_tape_rows_equal_mlp_tape():
    y0, times, w0y, w0t, b0, rest, _ = _make(R, B, 3, 3, (16, 8), True, seed=4)
    g = torch.Generator().manual_seed(5)
    stacked = StackedMLPTape(w0y, w0t, b0, rest, "elu", record=True)
    us = [torch.randn(R, B, 3, generator=g) for _ in range(3)]
    ts = [torch.rand(R, B, 1, generator=g) for _ in range(3)]
    outs = [stacked(t, u) for t, u in zip(ts, us, strict=True)]
    stacked.start_reverse()
    gs = [torch.randn(R, B, 3, generator=g) for _ in range(3)]
    ubars = [stacked.vjp(gs[e], e) for e in (2, 0, 1)]
    sgrads = stacked.weight_grads()
    assert stacked.num_evals == 3
    for r in range(R):
        _, _, w, wt, b, rs = _row(r, y0, times, w0y, w0t, b0, rest)
        tape = MLPTape(w, wt, b, rs, "elu", record=True)
        for t, u, out in zip(ts, us, outs, strict=True):
            _assert_close(out[r], tape(t[r], u[r]), "f(t, u)")
        tape.start_reverse()
        for e, ubar in zip((2, 0, 1), ubars, strict=True):
            _assert_close(ubar[r], tape.vjp(gs[e][r], e), "vjp")
        ref_w0y, ref_w0t, ref_b0, ref_rest = tape.weight_grads()
        for got, ref in zip([sgrads[0], sgrads[1], sgrads[2], *sgrads[3]],
                            [ref_w0y, ref_w0t, ref_b0, *ref_rest], strict=True):
            _assert_close(got[r], ref, "weight grad")


def test_weights_only_and_single_time():
    y0, times, w0y, w0t, b0, rest, _ = _make(2, 3, 2, 5, (8,), False, seed=6)
    w0y.requires_grad_(True)
    out = rk4_mlp_stacked(y0, times, w0y, w0t, b0, rest)
    (gw,) = torch.autograd.grad(out.square().sum(), [w0y])
    assert gw.shape == w0y.shape and gw.abs().max() > 0
    one = rk4_mlp_stacked(y0, times[:, :, :1], w0y, w0t, b0, rest)
    assert one.shape == (2, 3, 1, 2) and torch.equal(one[:, :, 0], y0)


def _bad(case: str):
    y0, times, w0y, w0t, b0, rest, _ = _make(2, 3, 2, 4, (5, 4), True, seed=7)
    kwargs = {"act": "elu", "substeps": 1}
    rest = list(rest)
    if case == "y0 2-D":
        y0 = y0[0]
    elif case == "times R":
        times = times[:1]
    elif case == "times B":
        times = times[:, :2]
    elif case == "times 2-D":
        times = times[0]
    elif case == "w0y R":
        w0y = w0y[:1]
    elif case == "w0y D":
        w0y = torch.cat([w0y, w0y], 2)
    elif case == "b0 H":
        b0 = b0[:, :4]
    elif case == "w0t H":
        w0t = w0t[:, :4]
    elif case == "w0t R":
        w0t = w0t[:1]
    elif case == "W1 in":
        rest[0] = rest[0][:, :, :4]
    elif case == "W1 R":
        rest[0] = rest[0][:1]
    elif case == "b1 out":
        rest[1] = rest[1][:, :3]
    elif case == "out != D":
        rest[2], rest[3] = rest[2][:, :1], rest[3][:, :1]
    elif case == "odd rest":
        rest = rest[:-1]
    elif case == "activation":
        kwargs["act"] = "gelu"
    elif case == "substeps":
        kwargs["substeps"] = 0
    return (y0, times, w0y, w0t, b0, rest), kwargs


@pytest.mark.parametrize("case, match", [
    ("y0 2-D", "y0 must be"), ("times R", "times must be"), ("times B", "times must be"),
    ("times 2-D", "times must be"), ("w0y R", "w0y must be"), ("w0y D", "w0y must be"),
    ("b0 H", "b0 must be"), ("w0t H", "w0t must be"), ("w0t R", "w0t must be"),
    ("W1 in", "W1 must be"), ("W1 R", "W1 must be"), ("b1 out", "b1 must be"),
    ("out != D", "last layer must output D"), ("odd rest", "rest must be"),
    ("activation", "supports activations"), ("substeps", "substeps must be"),
])
def test_bad_shapes_raise(case, match):
    args, kwargs = _bad(case)
    with pytest.raises(ValueError, match=match):
        rk4_mlp_stacked(*args, **kwargs)


@pytest.mark.parametrize("time, act", [(True, "elu"), (False, "tanh")])
def test_gradcheck_float64(time, act):
    y0, times, w0y, w0t, b0, rest, _ = _make(2, 2, 2, 3, (3,), time, seed=8,
                                             dtype=torch.float64)
    params = [p.requires_grad_(True) for p in _params(y0, w0y, w0t, b0, rest)]
    n_rest = len(rest)

    def fn(*p):
        w0t_ = p[3 + n_rest] if time else None
        return rk4_mlp_stacked(p[0], times, p[1], w0t_, p[2], p[3:3 + n_rest], act, 2)

    assert torch.autograd.gradcheck(fn, params)


@pytest.mark.parametrize("time", [True, False])
def test_shared_times_take_the_float_branch_of_rk4_mlp(time):
    """``[K]`` times shared by every sample: row r equals rk4_mlp with those ``[K]`` times
    (Python-float steps), bit for bit where the batched products equal the single ones
    (widths of 32, batches of 8 on this machine), and is differentiable."""
    y0, _, w0y, w0t, b0, rest, target = _make(R, 8, 2, K, (32, 32, 32), time, seed=7)
    shared = torch.linspace(0.0, 2.0, K)
    params = [p.detach().requires_grad_(True) for p in _params(y0, w0y, w0t, b0, rest)]
    y0s, w0ys, b0s, *tail = params
    rests, w0ts = (tail[:-1], tail[-1]) if time else (tail, None)
    out = rk4_mlp_stacked(y0s, shared, w0ys, w0ts, b0s, rests, "elu", 2)
    grads = torch.autograd.grad(((out - target) ** 2).mean((1, 2, 3)).sum(), params)
    for r in range(R):
        leaves = [p.detach()[r].requires_grad_(True) for p in params]
        y0r, w0yr, b0r, *tailr = leaves
        restr, w0tr = (tailr[:-1], tailr[-1]) if time else (tailr, None)
        ref = rk4_mlp(y0r, shared, w0yr, w0tr, b0r, restr, "elu", 2)
        ref_grads = torch.autograd.grad(((ref - target[r]) ** 2).mean(), leaves)
        _assert_close(out[r].detach(), ref.detach(), f"row {r}")
        for i, (got, want) in enumerate(zip(grads, ref_grads, strict=True)):
            _assert_close(got[r], want, f"row {r} grad {i}")


def test_padded_rows_carry_no_gradient_and_leave_the_real_rows_alone():
    """Field r using its first rows[r] states: its outputs and weight gradients are those of
    rk4_mlp on those states alone, whatever the padding holds."""
    rows = [8, 5, 7]
    y0, times, w0y, w0t, b0, rest, target = _make(R, 8, 3, 12, (32, 32), True, seed=8)
    params = [p.detach().requires_grad_(True) for p in (w0y, w0t, b0, *rest)]
    w0ys, w0ts, b0s, *rests = params
    out = rk4_mlp_stacked(y0, times, w0ys, w0ts, b0s, rests, "tanh", 1, rows=rows)
    loss = sum(((out[r, :n] - target[r, :n]) ** 2).mean() for r, n in enumerate(rows))
    grads = torch.autograd.grad(loss, params)
    for r, n in enumerate(rows):
        leaves = [p.detach()[r].requires_grad_(True) for p in params]
        w0yr, w0tr, b0r, *restr = leaves
        ref = rk4_mlp(y0[r, :n], times[r, :n], w0yr, w0tr, b0r, restr, "tanh", 1)
        ref_grads = torch.autograd.grad(((ref - target[r, :n]) ** 2).mean(), leaves)
        _assert_close(out[r, :n].detach(), ref.detach(), f"row {r}")
        for i, (got, want) in enumerate(zip(grads, ref_grads, strict=True)):
            _assert_close(got[r], want, f"row {r} grad {i}")
    with pytest.raises(ValueError, match="rows must give"):
        rk4_mlp_stacked(y0, times, w0y, w0t, b0, rest, "tanh", 1, rows=[8, 9, 1])
