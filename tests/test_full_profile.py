"""The ``full`` profile: the paper's networks field by field (so the paper's FS), its own
training schedule, and the paper's iterations as the stop rule's cap."""

from __future__ import annotations

import dataclasses

import pytest

from clfd_bench.harness.config import resolve_config
from clfd_bench.learning.part_config import PartConfig
from clfd_bench.methods import list_methods

TRAINING_KEYS = frozenset({
    "lr", "lr_schedule", "lr_min_factor", "lr_warmup", "stop_window", "stop_rel",
    "stop_decays", "batch", "tsub", "points", "horizon_start", "horizon_ramp", "segments",
    "solver", "rtol", "atol", "substeps", "solver_backend", "eval_solver", "eval_rtol",
    "eval_atol", "eval_substeps", "hnet_reg", "hnet_reg_samples",
})
"""What full may choose differently from paper: how a model is trained, never what it is."""

NETWORK_KEYS = tuple(f.name for f in dataclasses.fields(PartConfig)
                     if f.name not in TRAINING_KEYS)


def _network(cfg: PartConfig) -> dict:
    return {key: getattr(cfg, key) for key in NETWORK_KEYS}


def test_training_keys_are_fields():
    names = {f.name for f in dataclasses.fields(PartConfig)}
    assert TRAINING_KEYS <= names  # a renamed key would silently widen the comparison
    assert {"node_hidden", "hnet_hidden", "chunk_dim", "beta", "iterations",
            "extras"} <= set(NETWORK_KEYS)


@pytest.mark.parametrize("method", list_methods())
@pytest.mark.parametrize("dataset", ["lasa", "helloworld", "robotasks", "robotasks9"])
@pytest.mark.parametrize("node", ["t", "s"])
def test_full_has_the_papers_networks(method, dataset, node):
    robo = dataset.startswith("robotasks")
    # the paper ran no SI/MAS on RoboTasks: full uses FT's RoboTasks networks there
    ref_method = "ft" if robo and method in ("si", "mas") else method
    paper = resolve_config(ref_method, dataset, "paper", node=node)
    full = resolve_config(method, dataset, "full", node=node)
    assert [n for n, _ in full.parts] == [n for n, _ in paper.parts]
    for (part, p), (_, f) in zip(paper.parts, full.parts, strict=True):
        if ref_method != method:
            own = {"si": ("si_c", "si_xi"), "mas": ("mas_lambda",)}[method]
            hw = resolve_config(method, "helloworld", "paper", node=node).part("position")
            p = dataclasses.replace(
                p, importance_merge=hw.importance_merge,
                **{k: getattr(hw, k) for k in own})
        assert _network(f) == _network(p), (part, {
            k: (getattr(p, k), getattr(f, k)) for k in NETWORK_KEYS
            if getattr(p, k) != getattr(f, k)})
        # the paper's iterations, as the stop rule's cap (PackNet: no stop rule, it retrains
        # in the last share of its iterations)
        assert f.iterations == p.iterations
        assert (f.stop_window > 0) == (method != "packnet")
        assert f.batch == "trajectories" and f.solver == "rk4"
