"""Method plugins (docs/methods.md): a class outside clfd-bench, named on the command line,
through an entry point or a file path, is checked before use, gets its own hyperparameters
from its own TOML, and trains, resumes after SIGKILL, executes in simulation and appears in a
leaderboard like a built-in method. The worked example is docs/examples/clfd_l2 (L2 anchor
penalty), used here from a copy outside the repository."""

from __future__ import annotations

import json
import os
import shutil
import sys
import textwrap
from pathlib import Path

import pytest
from run_checks import RUN_TIMING, cli, comparable, finish, kill_when

from clfd_bench.harness.config import ConfigError, resolve_config
from clfd_bench.harness.run_config import RunConfig
from clfd_bench.methods import (
    MethodClassError,
    UnknownMethodError,
    get_method_class,
    list_methods,
)

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "clfd_l2"


@pytest.fixture()
def plugin_dir(tmp_path, monkeypatch) -> Path:
    """A copy of the example plugin package outside the repository, importable."""
    root = tmp_path / "plugins"
    shutil.copytree(EXAMPLE, root, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    monkeypatch.syspath_prepend(str(root))
    for name in [m for m in sys.modules if m == "clfd_l2" or m.startswith("clfd_l2.")]:
        monkeypatch.delitem(sys.modules, name)
    return root


def _write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))
    return path


# -- naming a method ----------------------------------------------------------------------


def test_import_spec_file_spec_and_entry_point_find_the_class(plugin_dir, tmp_path,
                                                              monkeypatch):
    by_module = get_method_class("clfd_l2:L2Anchor")
    assert by_module.name == "l2" and by_module.__module__ == "clfd_l2"
    by_file = get_method_class(f"{plugin_dir}/clfd_l2/__init__.py:L2Anchor")
    assert by_file.name == "l2"
    # an installed distribution declaring the entry point (what pip install writes)
    site = tmp_path / "site"
    _write(site / "clfd_l2_demo-0.1.dist-info" / "METADATA",
           "Metadata-Version: 2.1\nName: clfd-l2-demo\nVersion: 0.1\n")
    _write(site / "clfd_l2_demo-0.1.dist-info" / "entry_points.txt",
           "[clfd_bench.methods]\nl2demo = clfd_l2:L2Anchor\n")
    monkeypatch.syspath_prepend(str(site))
    assert "l2demo" in list_methods()
    assert get_method_class("l2demo") is by_module
    assert list_methods()[:7] == ["sg", "ft", "rep", "si", "mas", "hn", "chn"]


def test_unknown_names_say_what_is_valid(plugin_dir):
    with pytest.raises(UnknownMethodError, match="unknown CL method 'l3'; valid methods: sg, "
                                                 "ft, .*package.module:ClassName"):
        get_method_class("l3")
    with pytest.raises(UnknownMethodError, match="cannot import 'no_such_pkg'.*PYTHONPATH"):
        get_method_class("no_such_pkg.mod:Cls")
    with pytest.raises(UnknownMethodError, match="has no 'L2'; Method subclasses in it: "
                                                 "L2Anchor"):
        get_method_class("clfd_l2:L2")
    with pytest.raises(UnknownMethodError, match="no file"):
        get_method_class("/nonexistent/m.py:Cls")


def test_a_class_missing_parts_of_the_interface_is_refused_naming_all(tmp_path):
    path = _write(tmp_path / "broken.py", """
        import torch
        from clfd_bench.methods import Method, Rule

        class NotAMethod:
            name = "x"

        class Broken(Method):
            hyperparameters = frozenset({"task_emb_dim", "l2_strength"})
            own_hyperparameters = {"lr": Rule("float")}

        class NoName(Method):
            def field(self, task): ...
            def trainable(self, task): ...
            name = "hn"
    """)
    with pytest.raises(MethodClassError, match="not a subclass of clfd_bench.methods.Method"):
        get_method_class(f"{path}:NotAMethod")
    with pytest.raises(MethodClassError) as err:
        get_method_class(f"{path}:Broken")
    text = str(err.value)
    for missing in ("name = '...'", "field(self, task), trainable(self, task)",
                    "l2_strength are not", "lr are", "docs/methods.md"):
        assert missing in text, text
    with pytest.raises(MethodClassError, match="a name other than the built-in method 'hn'"):
        get_method_class(f"{path}:NoName")
    bad = _write(tmp_path / "raising.py", "raise RuntimeError('boom at import')\n")
    with pytest.raises(MethodClassError, match="raised RuntimeError: boom at import"):
        get_method_class(f"{bad}:X")


# -- hyperparameters ------------------------------------------------------------------------


def test_own_hyperparameters_resolve_check_and_round_trip(plugin_dir, tmp_path):
    config = resolve_config("clfd_l2:L2Anchor", "helloworld", "fast",
                            overrides=["l2_lambda=0.25"])
    part = config.part("position")
    assert part.extra("l2_lambda") == 0.25
    assert part.task_emb_dim == 32 and part.iterations == 400  # FT's values in l2.toml
    saved = json.loads(json.dumps(config.to_dict()))
    assert saved["parts"]["position"]["extras"] == {"l2_lambda": 0.25}
    assert RunConfig.from_dict(saved) == config
    with pytest.raises(KeyError, match="no own hyperparameter 'l2_lamda'"):
        part.extra("l2_lamda")
    with pytest.raises(ConfigError, match=r"--set l2_lambda=-1: l2_lambda must be a finite "
                                          r"number >= 0 \(weight of the anchor penalty\)"):
        resolve_config("clfd_l2:L2Anchor", "helloworld", "fast", overrides=["l2_lambda=-1"])
    with pytest.raises(ConfigError, match="unknown key 'l2_lamda' \\(did you mean "
                                          "'l2_lambda'\\?\\)"):
        resolve_config("clfd_l2:L2Anchor", "helloworld", "fast", overrides=["l2_lamda=1"])
    # a config of its own: a missing own key and a bad value name the file and the fix
    own = _write(tmp_path / "mine.toml", """
        method = "l2"
        [fast.helloworld]
        iterations = 5
        lr = 1e-3
        node_hidden = [8]
        task_emb_dim = 2
    """)
    with pytest.raises(ConfigError, match=f"{own} \\[fast.helloworld\\]: missing 'l2_lambda'"):
        resolve_config("clfd_l2:L2Anchor", "helloworld", "fast", config_file=own)
    own.write_text(own.read_text() + "l2_lambda = 'strong'\n")
    with pytest.raises(ConfigError, match=f"{own} line 8 \\[fast.helloworld\\]: l2_lambda "
                                          "must be a number"):
        resolve_config("clfd_l2:L2Anchor", "helloworld", "fast", config_file=own)
    with pytest.raises(ConfigError, match="no hyperparameter file for method 'ft'.*--config"):
        resolve_config("ft", "helloworld", "fast", config_file=tmp_path / "none.toml")


# -- the whole life of a plugin run ------------------------------------------------------


def _cli(args: list[str], pythonpath: Path):
    """The CLI with ``pythonpath`` in front of ``PYTHONPATH`` (the plugin is found there)."""
    return cli(*args, env={"PYTHONPATH": os.pathsep.join(
        [str(pythonpath), os.environ.get("PYTHONPATH", "")])})


_IGNORED = RUN_TIMING | {"provenance"}  # two run directories: their own paths and times


def test_plugin_trains_resumes_after_sigkill_executes_and_is_ranked(tmp_path):
    root = tmp_path / "outside"
    shutil.copytree(EXAMPLE, root, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    train = ["train", "--method", "clfd_l2:L2Anchor", "--dataset", "helloworld",
             "--profile", "smoke", "--tasks", "2", "--quiet"]
    # the reference run is trained where the grid below keeps this run: the grid counts it
    board = tmp_path / "board"
    ref_dir = board / "runs" / "helloworld" / "l2" / "smoke_nodet_o0_s0_k2"
    finish(_cli([*train, "--out", str(ref_dir)], root))
    killed = tmp_path / "killed"
    proc = _cli([*train, "--out", str(killed)], root)
    kill_when(proc, (killed / "predictions" / "after_task_0.npz").exists)
    finish(_cli([*train, "--out", str(killed)], root))
    ref = json.loads((ref_dir / "results.json").read_text())
    again = json.loads((killed / "results.json").read_text())
    assert ref["complete"] and ref["config"]["method"] == "clfd_l2:L2Anchor"
    assert ref["config"]["parts"]["position"]["extras"] == {"l2_lambda": 1.0}
    assert comparable(again, _IGNORED) == comparable(ref, _IGNORED)
    # executed in simulation: a success matrix over both tasks, seen tasks filled
    assert len(ref["success"]) == 2 and all(ref["success"][1][j] for j in range(2))
    assert ref["sim_cl_metrics"]["ACC"] is not None

    out = finish(_cli(["leaderboard", "--dataset", "helloworld", "--methods",
                      "ft,clfd_l2:L2Anchor", "--profile", "smoke", "--tasks", "2",
                      "--workers", "1", "--out", str(board)], root))
    table = json.loads((board / "leaderboard.json").read_text())
    assert {r["method"] for r in table["rows"]} == {"ft", "clfd_l2:L2Anchor"}, out
    assert all(r["runs_ok"] == 1 for r in table["rows"])
    assert (board / "runs" / "helloworld" / "l2").is_dir()  # the class's name as folder
    assert "CLFD_L2:L2ANCHOR" in (board / "leaderboard.md").read_text().upper()
    # the run `train` made is the grid's, not trained again
    assert json.loads((ref_dir / "results.json").read_text())["train_time_s"] == ref["train_time_s"]


def test_l2_forgets_less_than_ft_and_pays_in_plasticity(plugin_dir, tmp_path):
    """HelloWorld's first two letters (fast profile, 200 iterations, seed 0): the anchor
    penalty keeps letter h far better than FT after e is learned (measured mean DTW 29 vs
    126), at the price of learning e worse (40 vs 9; l2.toml has the sweep)."""
    from clfd_bench.harness.protocol import run_training

    errors = {}
    for method in ("ft", "clfd_l2:L2Anchor"):
        config = resolve_config(method, "helloworld", "fast", tasks=2,
                                overrides=["iterations=200"])
        results = run_training(config, tmp_path / method.split(":")[0], threads=1, log=None)
        dtw = results["errors"]["dtw"]
        errors[method] = [sum(cell) / len(cell) for cell in (dtw[1][0], dtw[1][1])]
    ft, l2 = errors["ft"], errors["clfd_l2:L2Anchor"]
    assert l2[0] < 0.5 * ft[0], errors  # letter h after e: remembered
    assert l2[1] > 2.0 * ft[1], errors  # letter e: learned worse than by FT


def test_leaderboard_config_names_a_methods_own_file(plugin_dir, tmp_path, monkeypatch):
    """``--config METHOD=PATH`` reaches the grid's training runs (their saved config) and a
    file for a method not in the grid is refused before any work."""
    from clfd_bench.harness.validate import InputError
    from clfd_bench.leaderboard.grid import GridOptions
    from clfd_bench.leaderboard.runner import run_leaderboard

    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(plugin_dir),
                                                      os.environ.get("PYTHONPATH", "")]))
    own = tmp_path / "l2_strong.toml"
    own.write_text((plugin_dir / "clfd_l2" / "l2.toml").read_text().replace(
        "[smoke.defaults]\nl2_lambda = 1.0", "[smoke.defaults]\nl2_lambda = 7.5"))
    method = "clfd_l2:L2Anchor"
    kwargs = dict(dataset="helloworld", methods=[method], profile="smoke", seeds=[0],
                  orders=[0], options=GridOptions(tasks=1, sim=False, workers=1))
    with pytest.raises(InputError, match="--config ft=...: 'ft' is not in --methods"):
        run_leaderboard(out=tmp_path / "bad", configs={"ft": str(own)}, **kwargs)
    assert not (tmp_path / "bad").exists()
    result = run_leaderboard(out=tmp_path / "board", configs={method: str(own)}, **kwargs)
    assert not result.failed
    saved = json.loads((result.specs[0].run_dir(tmp_path / "board") / "results.json")
                       .read_text())
    assert saved["config"]["parts"]["position"]["extras"] == {"l2_lambda": 7.5}
