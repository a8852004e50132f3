"""Validation at the edge: every class of bad input gets one line on stderr and exit code 2
before any work, and leaves no folder behind; the shipped configs all pass; a diverging run
ends with one line and keeps its finished tasks.

Everything runs through the real entry point (``clfd_bench.cli.main.main``) in-process. No
test here trains, except the divergence test (one smoke task of 30 iterations).
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
from pathlib import Path

import pytest
from run_checks import refused

from clfd_bench.cli.main import main
from clfd_bench.harness import baselines as baselines_mod
from clfd_bench.harness import validate
from clfd_bench.harness.config import ConfigError, resolve_config
from clfd_bench.harness.run_config import (
    DATASET_TABLES,
    PROFILES,
    RUN_RULES,
    RunConfig,
    run_rules,
)
from clfd_bench.learning.part_config import (
    COMMON_KEYS,
    PART_CONSTRAINTS,
    PART_FIELDS,
    PART_RULES,
    PartConfig,
)
from clfd_bench.methods import get_method_class, list_methods

TRAIN = ["train", "--dataset", "helloworld", "--profile", "smoke", "--no-sim", "--quiet"]
GRID = ["leaderboard", "--dataset", "helloworld", "--methods", "sg,hn", "--profile", "smoke",
        "--no-sim"]


# --------------------------------------------------------------------- config values
@pytest.mark.parametrize("args,expected", [
    # negative regularisers (HN beta, SI c, MAS lambda)
    (["--method", "hn", "--set", "beta=-5"], ["--set beta=-5", "beta", ">= 0", "got -5"]),
    (["--method", "si", "--set", "si_c=-100"], ["--set si_c=-100", ">= 0", "got -100"]),
    (["--method", "mas", "--set", "mas_lambda=-1"], ["--set mas_lambda=-1", ">= 0"]),
    (["--method", "si", "--set", "si_xi=0"], ["--set si_xi=0", "> 0"]),
    # sizes, counts, fractions, non-finite numbers
    (["--method", "sg", "--set", "points=0"], ["--set points=0", ">= 2", "got 0"]),
    (["--method", "sg", "--set", "iterations=0"], ["--set iterations=0", ">= 1"]),
    (["--method", "sg", "--set", "node_hidden=[]"], ["--set node_hidden=[]", "non-empty"]),
    (["--method", "sg", "--set", "node_hidden=[64,-1]"], ["node_hidden", "1..65536"]),
    (["--method", "hn", "--set", "task_emb_dim=0"], ["--set task_emb_dim=0", "1..65536"]),
    (["--method", "sg", "--set", "lr=inf"], ["--set lr=inf", "finite number > 0", "got inf"]),
    (["--method", "sg", "--set", "lr=nan"], ["--set lr=nan", "finite number > 0"]),
    (["--method", "sg", "--set", "lr=0"], ["--set lr=0", "> 0"]),
    (["--method", "sg", "--set", "atol=-1e-7"], ["--set atol=-1e-7", "> 0"]),
    (["--method", "sg", "--set", "horizon_start=0"], ["--set horizon_start=0", "(0, 1]"]),
    (["--method", "sg", "--set", "lr_min_factor=2"], ["--set lr_min_factor=2", "[0, 1]"]),
    # names from a fixed set
    (["--method", "sg", "--set", "solver=rk45"], ["--set solver=rk45", "one of", "rk4"]),
    (["--method", "sg", "--set", "activation=gelu"], ["--set activation=gelu", "elu"]),
    (["--method", "hn", "--set", "hnet_reg=some"], ["--set hnet_reg=some", "batched"]),
    # wrong types name --set, not the TOML file
    (["--method", "sg", "--set", "lr=fast"], ["--set lr=fast", "must be a number"]),
    (["--method", "sg", "--set", "segments=1"], ["--set segments=1", "true or false"]),
    (["--method", "sg", "--set", "iterations=1.5"], ["--set iterations=1.5", "an integer"]),
    # keys
    (["--method", "sg", "--set", "lrr=1"], ["--set lrr=1", "did you mean 'lr'"]),
    (["--method", "sg", "--set", "beta=1"], ["--set beta=1", "not a hyperparameter"]),
    (["--method", "sg", "--set", "orientation.lr=1"], ["--set orientation.lr=1", "one model"]),
    (["--method", "sg", "--set", "lr"], ["--set lr", "key=value"]),
    # values that only fail together
    (["--method", "sg", "--set", "solver=dopri5"], ["--set solver=dopri5", "segments"]),
], ids=lambda v: " ".join(v) if isinstance(v, list) and v and v[0].startswith("--") else None)
def test_bad_config_value(capsys, tmp_path, args, expected):
    refused(capsys, [*TRAIN, *args], tmp_path / "out", *expected)


@pytest.mark.parametrize("args,expected", [
    (["--tasks", "999"], ["--tasks 999", "1..7", "helloworld has 7 tasks"]),
    (["--tasks", "0"], ["--tasks 0", "1..7"]),
    (["--order", "7"], ["--order 7", "0..2"]),
    (["--order", "-1"], ["--order -1", "0..2"]),
    (["--seed", "-1"], ["--seed -1", "0.."]),
    (["--threads", "-2"], ["--threads -2", ">= 1"]),
    (["--threads", "0"], ["--threads 0", ">= 1"]),
    (["--sim-workers", "0"], ["--sim-workers 0", ">= 1"]),
    (["--threads", "two"], ["--threads", "invalid int value: 'two'"]),
    (["--node", "x"], ["--node", "invalid choice"]),
], ids=lambda v: " ".join(v) if isinstance(v, list) and v and v[0].startswith("--") else None)
def test_bad_command_line_value(capsys, tmp_path, args, expected):
    refused(capsys, [*TRAIN, "--method", "sg", *args], tmp_path / "out", *expected)


@pytest.mark.parametrize("argv,expected", [
    (["train", "--method", "sg", "--dataset", "helloworld", "--profile", "../../x"],
     ["unknown profile '../../x'", "paper, full, fast, smoke"]),
    (["train", "--method", "nope", "--dataset", "helloworld"], ["unknown CL method 'nope'"]),
    (["train", "--method", "sg", "--dataset", "helloword"], ["unknown dataset 'helloword'"]),
    (["train", "--method", "si", "--dataset", "robotasks", "--profile", "paper"],
     ["no settings for dataset 'robotasks'"]),
    (["train", "--method", "sg", "--dataset", "robotasks9", "--order", "1"],
     ["--order 1", "0..0"]),
    (["train", "--method", "sg", "--dataset", "robotasks", "--set", "orientation.lr=-1"],
     ["--set orientation.lr=-1", "orientation.lr="]),
])
def test_bad_names(capsys, tmp_path, argv, expected):
    refused(capsys, argv, tmp_path / "out", *expected)


# ----------------------------------------------------------------------- baselines TOML
@pytest.fixture
def baselines_copy(tmp_path, monkeypatch):
    """A writable copy of baselines/hn.toml that resolve_config reads instead."""
    copy = tmp_path / "hn.toml"
    shutil.copy(baselines_mod.baselines_file("hn"), copy)
    monkeypatch.setattr(baselines_mod, "baselines_file", lambda method: copy)
    return copy


def test_malformed_toml_names_file_and_line(capsys, tmp_path, baselines_copy):
    text = baselines_copy.read_text()
    baselines_copy.write_text(text.replace("[smoke.helloworld]", "[smoke.helloworld", 1))
    line = refused(capsys, [*TRAIN, "--method", "hn"], tmp_path / "out",
                    str(baselines_copy), "not valid TOML", "at line")
    number = next(i for i, t in enumerate(baselines_copy.read_text().splitlines(), 1)
                  if t.startswith("[smoke.helloworld"))
    assert f"line {number}" in line


def test_bad_value_in_toml_names_file_table_and_line(capsys, tmp_path, baselines_copy):
    lines = baselines_copy.read_text().splitlines()
    header = lines.index("[smoke.helloworld]")
    beta = next(i for i in range(header, len(lines)) if lines[i].startswith("beta ="))
    lines[beta] = "beta = -0.5"
    baselines_copy.write_text("\n".join(lines) + "\n")
    refused(capsys, [*TRAIN, "--method", "hn"], tmp_path / "out",
             f"baselines/hn.toml line {beta + 1} [smoke.helloworld]", "beta", "got -0.5",
             "--set beta=VALUE")
    # a --set of a good value fixes it
    cfg = resolve_config("hn", "helloworld", "smoke", overrides=["beta=0.01"])
    assert cfg.part("position").beta == 0.01


def test_wrong_type_in_toml_names_the_file(capsys, tmp_path, baselines_copy):
    text = baselines_copy.read_text()
    baselines_copy.write_text(text.replace('hnet_reg = "batched"', "hnet_reg = 3"))
    refused(capsys, [*TRAIN, "--method", "hn"], tmp_path / "out",
             "baselines/hn.toml line", "[smoke.defaults]", "hnet_reg must be a string")


# -------------------------------------------------------------------------------- --out
def test_out_is_a_file(capsys, tmp_path):
    out = tmp_path / "afile"
    out.write_text("not a directory")
    refused(capsys, [*TRAIN, "--method", "sg"], out, f"--out {out}", "existing file")
    assert out.read_text() == "not a directory"


def test_out_below_a_file(capsys, tmp_path):
    (tmp_path / "afile").write_text("")
    refused(capsys, [*TRAIN, "--method", "sg"], tmp_path / "afile" / "run",
             "cannot be created", "is a file")


def test_out_read_only_directory_is_refused_before_training(capsys, tmp_path, monkeypatch):
    out = tmp_path / "ro"
    out.mkdir()
    monkeypatch.setattr(validate, "_writable", lambda path: Path(path) != out)
    code = main([*TRAIN, "--method", "sg", "--out", str(out)])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and f"--out {out}" in err[0] and "write" in err[0]
    assert list(out.iterdir()) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into a read-only directory")
def test_out_read_only_directory_for_real(capsys, tmp_path):
    parent = tmp_path / "ro"
    parent.mkdir()
    parent.chmod(0o555)
    try:
        refused(capsys, [*TRAIN, "--method", "sg"], parent / "run", "not writable")
        code = main([*TRAIN, "--method", "sg", "--out", str(parent)])
        assert code == 2 and "cannot write" in capsys.readouterr().err
    finally:
        parent.chmod(0o755)


def test_out_in_an_unwritable_place(capsys):
    refused(capsys, [*TRAIN, "--method", "sg"], Path("/proc/clfd-bench-run"),
             "/proc", "not writable")


# ----------------------------------------------------------------------- dataset files
@pytest.fixture
def data_copy(tmp_path, monkeypatch):
    """CLFD_DATA_DIR pointing at a writable copy of the HelloWorld files."""
    from clfd_bench.data.sources import data_dir_override, fetch

    if data_dir_override() is None:
        fetch("robot_hello_world/processed_demos/h.npy")  # make sure the cache has them
    src = Path(fetch("robot_hello_world/processed_demos/h.npy")).parent
    root = tmp_path / "data"
    shutil.copytree(src, root / "robot_hello_world" / "processed_demos")
    for path in root.rglob("*"):
        path.chmod(0o755 if path.is_dir() else 0o644)
    monkeypatch.setenv("CLFD_DATA_DIR", str(root))
    return root / "robot_hello_world" / "processed_demos"


def test_truncated_dataset_file(capsys, tmp_path, data_copy):
    bad = data_copy / "e.npy"
    with bad.open("r+b") as fh:
        fh.truncate(500)
    refused(capsys, [*TRAIN, "--method", "sg"], tmp_path / "out",
             str(bad), "truncated or corrupt", "CLFD_DATA_DIR")


def test_missing_dataset_file(capsys, tmp_path, data_copy):
    (data_copy / "w.npy").unlink()
    refused(capsys, [*TRAIN, "--method", "sg"], tmp_path / "out", "w.npy", "CLFD_DATA_DIR")


def test_dataset_error_is_one_exception_type(data_copy):
    from clfd_bench.data import DatasetError, load_dataset

    (data_copy / "h.npy").write_bytes(b"\x93NUMPY garbage")
    with pytest.raises(DatasetError, match="h.npy"):
        load_dataset("helloworld")


# -------------------------------------------------------------------------- leaderboard
@pytest.mark.parametrize("args,expected", [
    (["--profile", "../../x"], ["unknown profile '../../x'", "paper, full, fast, smoke"]),
    (["--profile", "smoke", "--tasks", "99"], ["--tasks 99", "1..7"]),
    (["--profile", "smoke", "--seeds", "0,-1"], ["--seeds -1", "0.."]),
    (["--profile", "smoke", "--orders", "0,5"], ["--orders 5", "0..2"]),
    (["--profile", "smoke", "--workers", "0"], ["--workers 0", ">= 1"]),
    (["--profile", "smoke", "--seeds", ","], ["--seeds is empty"]),
    (["--profile", "smoke", "--methods", "sg,nope"], ["nope"]),
    (["--dataset", "nope"], ["unknown dataset 'nope'"]),
], ids=lambda v: " ".join(v) if isinstance(v, list) and v and v[0].startswith("--") else None)
def test_bad_grid_launches_nothing(capsys, tmp_path, args, expected):
    argv = [a for a in GRID if a not in ("--profile", "smoke")]
    if "--dataset" in args:
        argv = ["leaderboard", "--methods", "sg"]
    refused(capsys, [*argv, *args], tmp_path / "grid", *expected)
    assert list(tmp_path.iterdir()) == []  # nothing written anywhere, not even outside


@pytest.mark.parametrize("argv", [
    ["leaderboard", "--dataset", "lasaa"],
    ["study", "sensitivity", "--dataset", "lasaa"],
    ["study", "tasktime", "--dataset", "lasaa"],
    ["study", "order", "--datasets", "helloworld,lasaa"],
], ids=lambda v: " ".join(v[:2]))
def test_a_misspelt_dataset_gets_the_closest_name_and_launches_nothing(capsys, tmp_path, argv):
    refused(capsys, argv, tmp_path / "grid", f"clfd-bench {' '.join(argv[:-2])}: error",
            "unknown dataset 'lasaa' (did you mean 'lasa'?)", "valid: lasa, helloworld")
    assert list(tmp_path.iterdir()) == []


def test_data_command_names_the_closest_dataset(capsys):
    from clfd_bench.cli.main import main

    assert main(["data", "helloworl"]) == 2
    err = capsys.readouterr().err
    assert "clfd-bench data: error: unknown dataset 'helloworl' (did you mean 'helloworld'?)" in err


def test_grid_with_a_corrupt_dataset_launches_nothing(capsys, tmp_path, data_copy):
    (data_copy / "d.npy").write_bytes(b"")
    refused(capsys, GRID, tmp_path / "grid", "d.npy", "truncated or corrupt")


def test_grid_out_is_a_file(capsys, tmp_path):
    out = tmp_path / "afile"
    out.write_text("")
    refused(capsys, GRID, out, "existing file")


def test_valid_plan_passes_and_creates_nothing(tmp_path):
    from clfd_bench.leaderboard.grid import GridOptions, make_grid
    from clfd_bench.leaderboard.runner import validate_plan

    specs = make_grid("helloworld", list_methods(), "smoke", [0, 1], [0, 1, 2],
                      GridOptions(tasks=7))
    validate_plan(specs, tmp_path / "grid")
    assert not (tmp_path / "grid").exists()


# ----------------------------------------------------------- the rules and shipped configs
def test_every_field_has_one_rule():
    assert set(PART_RULES) == set(PART_FIELDS)
    scalar = {f.name for f in dataclasses.fields(RunConfig)} - {"parts", "overrides"}
    assert set(RUN_RULES) == scalar


def _shipped():
    for method in list_methods():
        for profile in PROFILES:
            for dataset in DATASET_TABLES:
                yield method, dataset, profile


@pytest.mark.parametrize("method,dataset,profile", list(_shipped()))
def test_shipped_configs_pass_validation(method, dataset, profile):
    """Every method x dataset x profile of baselines/ passes every range, for every order
    and task count, so the ranges never reject what ships."""
    try:
        base = resolve_config(method, dataset, profile)
    except ConfigError as exc:  # the paper did not run SI / MAS on RoboTasks
        assert "no settings for dataset" in str(exc)
        assert profile == "paper" and method in ("si", "mas")
        return
    allowed = get_method_class(method).hyperparameters | COMMON_KEYS
    for _, part in base.parts:
        values = dataclasses.asdict(part)
        for key in allowed:
            assert PART_RULES[key].check(key, values[key])[1] is None, (key, values[key])
        assert all(rule.holds(values) for rule in PART_CONSTRAINTS)
    rules = run_rules(dataset, 0)
    for order in range(int(rules["order"].hi) + 1):
        n = int(run_rules(dataset, order)["tasks"].hi)
        for tasks in (None, 1, n):
            cfg = resolve_config(method, dataset, profile, order=order, tasks=tasks, seed=4)
            assert RunConfig.from_dict(cfg.to_dict()) == cfg


def test_part_config_checks_directly_built_values():
    with pytest.raises(ConfigError, match="beta must be a finite number >= 0"):
        PartConfig(iterations=1, lr=1e-3, node_hidden=(4,), beta=-1.0)
    with pytest.raises(ConfigError, match="points must be an integer >= 2"):
        PartConfig(iterations=1, lr=1e-3, node_hidden=(4,), points=1)


def test_show_config_still_works(capsys):
    assert main(["train", "--method", "hn", "--dataset", "robotasks", "--profile", "smoke",
                 "--set", "orientation.beta=0.25", "--show-config"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["parts"]["orientation"]["beta"] == 0.25


# --------------------------------------------------------------------------- divergence
def test_divergence_is_one_line_and_keeps_finished_tasks(capsys, tmp_path, monkeypatch):
    """Task 0 trains normally, task 1's loss turns NaN: exit 1, one line naming task 1,
    the iteration and the fix; task 0's results and checkpoint stay (the run resumes)."""
    from clfd_bench.learning import objective  # the training loss integrates through it

    real, calls = objective.integrate, {"n": 0}
    iterations = resolve_config("sg", "helloworld", "smoke").part("position").iterations

    def integrate(field, y0, t, solver, *args, **kwargs):
        calls["n"] += 1
        out = real(field, y0, t, solver, *args, **kwargs)
        return out * float("nan") if calls["n"] > iterations else out

    monkeypatch.setattr(objective, "integrate", integrate)
    out = tmp_path / "run"
    code = main([*TRAIN, "--method", "sg", "--tasks", "2", "--out", str(out)])
    err = capsys.readouterr().err.splitlines()
    assert code == 1, err
    assert len(err) == 1, err
    assert "training diverged" in err[0] and "task 1" in err[0] and "iteration 0" in err[0]
    assert "lower lr" in err[0] and f"tasks 0..0 stay in {out}" in err[0]
    results = json.loads((out / "results.json").read_text())
    assert results["tasks_done"] == 1 and not results["complete"]
    assert (out / "checkpoint.pt").is_file()


@pytest.mark.parametrize("argv", [[*TRAIN, "--method", "sg", "--threads", "2"], GRID],
                         ids=["train", "leaderboard"])
def test_a_mistyped_thread_invariance_switch_launches_nothing(capsys, tmp_path, monkeypatch,
                                                              argv):
    monkeypatch.setenv("CLFD_THREAD_INVARIANT", "ture")
    refused(capsys, argv, tmp_path / "out", "CLFD_THREAD_INVARIANT='ture' is not understood",
            "set it to 0")
    assert list(tmp_path.iterdir()) == []
