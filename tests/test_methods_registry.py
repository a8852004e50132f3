"""The built-in CL methods: registry, model growth, stored data, regularisers, state round trip
(EWC, A-GEM and PackNet in detail: tests/test_methods_more.py)."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from clfd_bench.harness.config import PartConfig
from clfd_bench.harness.loop import train_task
from clfd_bench.learning.node import NodeSpec
from clfd_bench.learning.odeint import SolverSpec, integrate
from clfd_bench.methods import (
    METHODS,
    StepContext,
    TaskData,
    UnknownMethodError,
    get_method_class,
    list_methods,
)

torch.set_num_threads(1)

CFG = PartConfig(
    iterations=4, lr=1e-2, node_hidden=(8, 8), task_emb_dim=3, hnet_hidden=(6,), beta=0.5,
    hnet_reg="batched", chunk_emb_dim=2, chunk_dim=32, si_c=0.3, si_xi=0.3, mas_lambda=0.1,
    mas_points=20, batch="trajectories", points=8, solver="rk4",
    extras={"ewc_lambda": 10.0, "ewc_gamma": 1.0, "ewc_batches": 1, "agem_memory": 2,
            "agem_ref_tasks": 1, "packnet_prune": 0.5, "packnet_retrain": 0.25},
)
SPEC = NodeSpec(dim=2, hidden=(8, 8), time_input=True)


def _data(seed: int) -> TaskData:
    g = torch.Generator().manual_seed(seed)
    demos = torch.cumsum(torch.randn(3, 30, 2, generator=g) * 0.1, dim=1)
    return TaskData(demos, torch.linspace(0, 2, 30))


def _method(name: str):
    torch.manual_seed(0)
    return get_method_class(name)(SPEC, CFG)


def _learn(method, task: int) -> TaskData:
    data = _data(task)
    method.add_task()
    train_task(method, task, data, CFG, torch.Generator().manual_seed(task))
    return data


def test_registry_names_and_loud_failure():
    assert list_methods()[:10] == ["sg", "ft", "rep", "si", "mas", "hn", "chn", "ewc", "agem",
                                   "packnet"]
    with pytest.raises(UnknownMethodError) as err:
        get_method_class("vcl")
    assert ("unknown CL method 'vcl'; valid methods: sg, ft, rep, si, mas, hn, chn, ewc, agem, "
            "packnet") in str(err.value)


@pytest.mark.parametrize("name", list(METHODS))
def test_growth_storage_and_state_round_trip(name):
    method = _method(name)
    _learn(method, 0)
    size0 = method.num_params()
    _learn(method, 1)
    growth = method.num_params() - size0
    if name == "sg":
        assert growth == size0  # a whole new NODE per task
    else:
        assert growth == CFG.task_emb_dim  # one embedding per task
    stored = {"rep": 2 * 3 * 30, "agem": 2 * 2 * 30}  # all demos / agem_memory = 2 of 3
    assert method.stored_samples() == stored.get(name, 0)

    # a fresh instance restored from the state dict predicts the same trajectories
    state = {k: v.clone() for k, v in method.state_dict().items()}
    other = get_method_class(name)(SPEC, CFG)
    other.prepare_tasks(2, state)
    other.load_state_dict(state, strict=True)
    y0, t = _data(0).demos[:, 0], torch.linspace(0, 2, 30)
    with torch.no_grad():
        for task in (0, 1):
            a = integrate(method.field(task), y0, t, SolverSpec("rk4"))
            b = integrate(other.field(task), y0, t, SolverSpec("rk4"))
            assert torch.equal(a, b)


@pytest.mark.parametrize("name", ["si", "mas"])
def test_importance_penalty_is_zero_at_the_anchor_and_grows_away_from_it(name):
    method = _method(name)
    _learn(method, 0)
    method.add_task()
    opt = torch.optim.Adam(method.trainable(1))
    ctx = StepContext(task=1, iteration=0, optimizer=opt, generator=torch.Generator())
    assert float(method.extra_loss(ctx).detach()) == 0.0
    importance = [getattr(method, f"importance_{i}") for i in range(len(method.weights))]
    if name == "mas":  # mean absolute gradients; SI's path integral has no fixed sign
        assert all(bool((imp >= 0).all()) for imp in importance)
    assert sum(float(imp.abs().sum()) for imp in importance) > 0
    with torch.no_grad():
        for w in method.weights:
            w.add_(0.1)
    assert float(method.extra_loss(ctx).detach()) > 0.0
    assert method.extra_loss(dataclasses.replace(ctx, task=0)) is None


@pytest.mark.parametrize("name", ["hn", "chn"])
def test_hypernetwork_regulariser_only_after_the_first_task(name):
    method = _method(name)
    data = _data(0)
    method.add_task()
    method.on_task_start(0, data)
    opt = torch.optim.Adam(method.trainable(0))
    assert method.extra_loss(StepContext(0, 0, opt, torch.Generator())) is None
    method.on_task_end(0, data)
    method.add_task()
    method.on_task_start(1, _data(1))
    opt = torch.optim.Adam(method.trainable(1))
    y0, t = data.demos[:, 0], data.times
    loss = integrate(method.field(1), y0, t, SolverSpec("rk4")).pow(2).mean()
    loss.backward()
    reg = method.extra_loss(StepContext(1, 0, opt, torch.Generator()))
    # the look-ahead step moves the outputs for task 0 away from their targets: reg > 0
    assert reg is not None and float(reg.detach()) > 0


def test_replay_draws_every_seen_task():
    method = _method("rep")
    _learn(method, 0)
    _learn(method, 1)
    gen = torch.Generator().manual_seed(0)
    picks = {method.pick_task(2, gen) for _ in range(100)}
    assert picks == {0, 1, 2}
    assert torch.equal(method.replay_data(0).demos, _data(0).demos)


def test_importance_methods_count_their_penalty_state_in_the_model_size():
    """FS as in the paper: SI keeps weights + importance + anchor + path integral + previous
    weights (5x the NODE; the paper's HelloWorld FS 0.19 implies 5.0x), MAS weights +
    importance + anchor (3x). FT keeps the NODE alone."""
    sizes = {}
    for name in ("ft", "si", "mas"):
        method = _method(name)
        _learn(method, 0)
        sizes[name] = method.num_params()
    node = sizes["ft"] - CFG.task_emb_dim  # the NODE's weights, without task 0's embedding
    assert sizes["si"] == sizes["ft"] + 4 * node
    assert sizes["mas"] == sizes["ft"] + 2 * node
