"""Run configs from baselines/*.toml: typos raise, the paper profile is the paper's tables."""

from __future__ import annotations

import dataclasses

import pytest

from clfd_bench.harness import baselines as baselines_mod
from clfd_bench.harness.config import ConfigError, resolve_config
from clfd_bench.harness.run_config import RunConfig
from clfd_bench.methods import list_methods


@pytest.mark.parametrize("method", list_methods())
@pytest.mark.parametrize("profile", ["paper", "full", "fast", "smoke"])
@pytest.mark.parametrize("dataset", ["lasa", "helloworld", "robotasks", "robotasks9"])
def test_every_profile_resolves(method, profile, dataset):
    if profile == "paper" and method in ("si", "mas") and dataset.startswith("robotasks"):
        with pytest.raises(ConfigError, match="did not run SI and MAS on RoboTasks"):
            resolve_config(method, dataset, profile)
        return
    cfg = resolve_config(method, dataset, profile)
    parts = [name for name, _ in cfg.parts]
    assert parts == (["position", "orientation"] if dataset.startswith("robotasks")
                     else ["position"])
    assert RunConfig.from_dict(cfg.to_dict()) == cfg
    for _, part in cfg.parts:
        assert part.eval_solver is not None  # resolved


# (method, dataset, part, key, value) cells of the paper's tables tab:hparam_lasa,
# tab:hparam_hw and tab:hparam_rt, typed in from the paper.
PAPER_CELLS = [
    ("sg", "lasa", "position", "iterations", 15000),
    ("sg", "lasa", "position", "lr", 1e-4),
    ("sg", "lasa", "position", "node_hidden", (1000, 1000, 1000)),
    ("ft", "lasa", "position", "task_emb_dim", 256),
    ("si", "lasa", "position", "si_c", 0.3),
    ("si", "helloworld", "position", "si_xi", 0.3),
    ("mas", "helloworld", "position", "mas_lambda", 0.1),
    ("hn", "lasa", "position", "node_hidden", (100, 100, 100)),
    ("hn", "lasa", "position", "hnet_hidden", (200, 200, 200)),
    ("hn", "helloworld", "position", "beta", 0.005),
    ("hn", "helloworld", "position", "iterations", 40000),
    ("chn", "helloworld", "position", "chunk_dim", 8192),
    ("chn", "lasa", "position", "chunk_emb_dim", 256),
    ("rep", "robotasks", "position", "lr", 1e-5),
    ("rep", "robotasks", "position", "iterations", 50000),
    ("ft", "robotasks", "position", "task_emb_dim", 512),
    ("hn", "robotasks", "position", "beta", 0.0005),
    ("sg", "robotasks", "orientation", "node_hidden", (1500, 1500, 1500)),
    ("sg", "robotasks", "orientation", "lr", 1e-4),
    ("hn", "robotasks", "orientation", "node_hidden", (150, 150, 150)),
    ("hn", "robotasks", "orientation", "hnet_hidden", (300, 300, 300)),
    ("chn", "robotasks", "orientation", "task_emb_dim", 1024),
    ("chn", "robotasks9", "orientation", "chunk_emb_dim", 1024),
]


@pytest.mark.parametrize("method,dataset,part,key,value", PAPER_CELLS)
def test_paper_profile_is_the_papers_tables(method, dataset, part, key, value):
    cfg = resolve_config(method, dataset, "paper").part(part)
    assert getattr(cfg, key) == value


def test_paper_profile_trains_like_the_original_code():
    cfg = resolve_config("hn", "helloworld", "paper").part("position")
    assert (cfg.batch, cfg.tsub, cfg.solver, cfg.rtol, cfg.atol) == (
        "windows", 20, "dopri5", 1e-6, 1e-7)
    assert cfg.lr_schedule == "constant" and cfg.hnet_reg == "all"


@pytest.mark.parametrize("override,msg", [
    ("lrr=1e-3", "unknown key 'lrr' \\(did you mean 'lr'\\?\\)"),
    ("lr", "must look like key=value"),
    ("lr=fast", "lr must be a number"),
    ("node_hidden=[64, 6.5]", "node_hidden must be a list of integers"),
    ("solver=rk45", "solver must be one of"),
    ("beta=1.0", "'beta' is not a hyperparameter of method 'sg'"),
    ("velocity.lr=1", "part must be one of position, orientation"),
])
def test_bad_overrides_raise(override, msg):
    with pytest.raises(ConfigError, match=msg):
        resolve_config("sg", "helloworld", "fast", overrides=[override])


def test_override_applies_to_one_part():
    cfg = resolve_config("hn", "robotasks", "smoke", overrides=["orientation.iterations=7"])
    assert cfg.part("orientation").iterations == 7
    assert cfg.part("position").iterations != 7


def test_unknown_profile_dataset_and_typo_in_file(tmp_path, monkeypatch):
    with pytest.raises(ConfigError, match="unknown profile 'fsat' \\(did you mean 'fast'\\?\\)"):
        resolve_config("hn", "helloworld", "fsat")
    with pytest.raises(ConfigError, match="unknown dataset 'helloword'"):
        resolve_config("hn", "helloword", "fast")
    bad = tmp_path / "hn.toml"
    bad.write_text('method = "hn"\n[fast.defaults]\nbatch = "trajectories"\n'
                   '[fast.helloworld]\niterations = 5\nlr = 1e-3\nnode_hidden = [4]\n'
                   'task_emb_dim = 2\nhnet_hidden = [3]\nhorizon_strat = 0.5\n')
    monkeypatch.setattr(baselines_mod, "baselines_file", lambda method: bad)
    with pytest.raises(ConfigError, match="unknown key 'horizon_strat' \\(did you mean "
                                          "'horizon_start'\\?\\)"):
        resolve_config("hn", "helloworld", "fast")


def test_configs_are_frozen():
    cfg = resolve_config("hn", "helloworld", "fast")
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.seed = 3  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.part("position").lr = 1.0  # type: ignore[misc]
