"""The paper grid (counts, narrowing, errors) and the paper tables built from hand-made runs:
medians over seeds, ours − paper per cell, a missing run shown as missing (never as 0)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from clfd_bench.leaderboard.grid import GridOptions, RunSpec
from clfd_bench.metrics.cl import cl_score, cl_stability
from clfd_bench.metrics.paper_numbers import cl_table
from clfd_bench.studies.paper_grid import FULL_GRID_RUNS, GridError, grid_cost, paper_grid
from clfd_bench.studies.paper_tables import build_tables, write_outputs

# --------------------------------------------------------------------------- grid


def test_full_grid_counts_follow_the_paper():
    specs = paper_grid()
    # LASA, HelloWorld: 7 methods × NODE^T/^I; RoboTasks: 5 methods × NODE^T; 5 seeds, 3 orders
    assert FULL_GRID_RUNS == (7 * 2 + 7 * 2 + 5 * 1) * 5 * 3 == 495
    assert len(specs) == len(set(specs)) == 495
    by_ds = {d: sum(s.dataset == d for s in specs) for d in ("lasa", "helloworld", "robotasks")}
    assert by_ds == {"lasa": 210, "helloworld": 210, "robotasks": 75}
    rt = [s for s in specs if s.dataset == "robotasks"]
    assert {s.method for s in rt} == {"sg", "ft", "rep", "hn", "chn"}
    assert {s.node for s in rt} == {"t"}
    assert all(s.profile == "paper" and s.sim and s.tasks is None for s in specs)


def test_narrowing_flags():
    specs = paper_grid(datasets=["lasa", "robotasks"], methods=["si", "hn"], seeds=[0, 3],
                       orders=[0], profile="fast", options=GridOptions(tasks=2, sim=False))
    # SI only where the paper ran it (LASA); HN on both; LASA has two NODE variants
    assert len(specs) == (2 * 2 + 1) * 2
    assert {(s.dataset, s.method) for s in specs} == {("lasa", "si"), ("lasa", "hn"),
                                                      ("robotasks", "hn")}
    assert all(s.profile == "fast" and s.tasks == 2 and not s.sim and s.order == 0
               for s in specs)
    assert {s.seed for s in specs} == {0, 3}
    only_i = paper_grid(nodes=["i"], seeds=[0], orders=[1])
    assert len(only_i) == 14 and {s.dataset for s in only_i} == {"lasa", "helloworld"}


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"datasets": ["robotasks"], "methods": ["si"]}, "the paper did not run SI on robotasks"),
    ({"datasets": ["robotasks"], "nodes": ["i"]}, "did not use NODE^I"),
    ({"methods": ["ewc"]}, "unknown method ewc; valid: sg, ft, rep, si, mas, hn, chn"),
    ({"datasets": ["robotasks9"]}, "unknown dataset robotasks9; valid: lasa, helloworld"),
    ({"orders": [3]}, "unknown order for lasa 3; valid: 0, 1, 2"),
    ({"seeds": []}, "--seeds is empty"),
    ({"profile": "huge"}, "unknown profile huge; valid: paper, full, fast, smoke"),
])
def test_bad_selections_raise_with_valid_names(kwargs, message):
    with pytest.raises(GridError) as info:
        paper_grid(**kwargs)
    assert message in str(info.value)


def test_cost_counts_iterations_from_the_profile():
    rows = grid_cost(paper_grid(datasets=["helloworld", "robotasks"], methods=["hn"],
                                nodes=["t"], orders=[0]),
                     cpu_rates={("hn", "helloworld", "position"): 40.0})
    hw, rt = rows
    assert (hw.runs, hw.tasks, hw.iterations) == (5, 7, 7 * 40_000)
    assert rt.iterations == 4 * (50_000 + 50_000)  # position and orientation models
    assert hw.cpu_s == pytest.approx(7 * 40_000 / 40.0) and rt.cpu_s is None
    # GPU reference: the paper's HelloWorld HN table, mean per-task time × 7 tasks
    assert hw.gpu_s == pytest.approx(np.mean([1968, 2337, 2508, 2702, 2843, 2930, 3234]) * 7)


# --------------------------------------------------------------------------- tables


def _write_run(root, spec: RunSpec, cl_by_metric, params_by_part, times_by_part, sim=None):
    """A finished run's results.json with known CL metrics (nothing trained)."""
    from clfd_bench.execution.fingerprint import sim_fingerprint
    from clfd_bench.runs import RunDir

    run_dir = spec.run_dir(root)
    run_dir.mkdir(parents=True)
    parts = list(params_by_part)
    results = {
        "complete": True,
        "tasks": ["a", "b"],
        "tasks_done": 2,
        "train_time_s": [sum(t) for t in zip(*times_by_part.values(), strict=True)],
        "train_time_s_by_part": times_by_part,
        "num_params": [sum(p) for p in zip(*params_by_part.values(), strict=True)],
        "num_params_by_part": params_by_part,
        "errors": {"dtw": []},
        "cl_metrics": cl_by_metric["dtw"],
        "cl_metrics_by_metric": cl_by_metric,
        "success": [[[True]], [[True], [True]]] if sim is not None else None,
        "sim_cl_metrics": sim,
        # executed by this simulator (a run is done only then: clfd_bench.runs.RunDir.status)
        "sim": {"evaluated_tasks": 2, "fingerprint": sim_fingerprint()} if sim is not None
        else None,
    }
    assert parts
    RunDir(run_dir).write_training_results(results)


def _cl(acc, rem, ms=1.0, te=1.0, sss=1.0):
    return {"ACC": acc, "REM": rem, "BWT": rem - 1, "MS": ms, "SSS": sss, "TE": te}


def _spec(method, seed, dataset="helloworld", sim=True):
    return RunSpec(dataset, method, "smoke", seed, 0, "t", 2, sim)


def test_cl_table_medians_and_differences(tmp_path):
    accs = {"sg": [1.0, 0.5, 0.625], "hn": [0.25, 1.0, 0.5]}
    for method, values in accs.items():
        for seed, acc in enumerate(values):
            size = 100 if method == "sg" else 50
            _write_run(tmp_path, _spec(method, seed), {"dtw": _cl(acc, 1.0)},
                       {"position": [size, size]}, {"position": [1.0 + seed, 2.0]},
                       sim={"ACC": acc / 2, "REM": 1.0, "BWT": 0.0})
    specs = paper_grid(datasets=["helloworld"], methods=["sg", "hn"], nodes=["t"],
                       seeds=[0, 1, 2], orders=[0], profile="smoke",
                       options=GridOptions(tasks=2))
    tables, times, _ = build_tables(specs, tmp_path)
    (table,) = tables
    rows = {r.method: r for r in table.rows}
    paper = cl_table("helloworld", "t")
    assert rows["sg"].ours["ACC"] == pytest.approx(0.625)  # median, not mean
    assert rows["hn"].ours["ACC"] == pytest.approx(0.5)
    assert rows["hn"].diff("ACC") == pytest.approx(0.5 - paper["HN"]["ACC"])
    assert rows["sg"].ours["exec_ACC"] == pytest.approx(0.3125)
    # FS across the table's methods: SG is the largest (0), HN half its size (0.5)
    assert rows["sg"].ours["FS"] == pytest.approx(0.0)
    assert rows["hn"].ours["FS"] == pytest.approx(0.5)
    hn_crit = [dict(ACC=a, REM=1.0, MS=1.0, TE=1.0, FS=0.5, SSS=1.0) for a in accs["hn"]]
    assert rows["hn"].ours["CL_score"] == pytest.approx(np.median([cl_score(c) for c in hn_crit]))
    assert rows["hn"].ours["CL_stability"] == pytest.approx(
        np.median([cl_stability(c) for c in hn_crit]))
    assert rows["sg"].diff("CL_score") == pytest.approx(
        rows["sg"].ours["CL_score"] - paper["SG"]["CL_score"])
    assert (rows["sg"].runs_done, rows["sg"].runs_expected) == (3, 3)
    # training time: median over seeds per task, next to the paper's table
    (tt,) = times
    assert tt.tasks == [0, 1] and tt.ours["sg"] == [2.0, 2.0]
    assert tt.paper["hn"] == [1968.0, 2337.0]


def test_missing_runs_show_as_missing_not_zero(tmp_path):
    _write_run(tmp_path, _spec("sg", 0), {"dtw": _cl(1.0, 1.0)}, {"position": [10, 20]},
               {"position": [1.0, 1.0]}, sim={"ACC": 1.0, "REM": 1.0, "BWT": 0.0})
    specs = paper_grid(datasets=["helloworld"], methods=["sg", "chn"], nodes=["t"],
                       seeds=[0, 1], orders=[0], profile="smoke",
                       options=GridOptions(tasks=2))
    tables, _, records = build_tables(specs, tmp_path)
    rows = {r.method: r for r in tables[0].rows}
    assert (rows["sg"].runs_done, rows["sg"].runs_expected) == (1, 2)
    assert rows["chn"].runs_done == 0
    assert all(math.isnan(rows["chn"].ours[c]) for c in ("ACC", "REM", "CL_score", "exec_ACC"))
    assert math.isnan(rows["chn"].diff("ACC"))
    # FS needs every method of the table: left empty, with a note saying why
    assert math.isnan(rows["sg"].ours["FS"]) and math.isnan(rows["sg"].ours["CL_score"])
    assert any("missing: CHN" in n for n in tables[0].notes)
    assert sorted(r.status for r in records) == ["done", "missing", "missing", "missing"]
    files = write_outputs(tables, [], tmp_path, {"profile": "smoke", "seeds": [0, 1]})
    md = (tmp_path / "paper_tables.md").read_text()
    chn_line = next(line for line in md.splitlines() if line.startswith("| CHN"))
    assert "| 0/2 |" in chn_line and "— / 0.89 (—)" in chn_line and "0.00" not in chn_line
    data = json.loads((tmp_path / "paper_tables.json").read_text())
    chn = next(r for r in data["cl_tables"][0]["rows"] if r["method"] == "chn")
    assert chn["ours"]["ACC"] is None and chn["paper"]["ACC"] == 0.89
    assert any(p.name == "paper_diff.png" for p in files)


def test_robotasks_position_and_orientation_tables(tmp_path):
    for method, (pos_acc, ori_acc) in {"sg": (0.5, 1.0), "hn": (1.0, 0.25)}.items():
        _write_run(tmp_path, _spec(method, 0, "robotasks", sim=False),
                   {"dtw": _cl(pos_acc, 1.0), "quaternion": _cl(ori_acc, 0.5)},
                   {"position": [100, 200], "orientation": [100, 400]}
                   if method == "sg" else {"position": [150, 150], "orientation": [100, 100]},
                   {"position": [1.0, 1.0], "orientation": [1.0, 1.0]})
    # the grid asks for runs with simulation: the finished no-sim runs are used instead
    specs = paper_grid(datasets=["robotasks"], methods=["sg", "hn"], seeds=[0], orders=[0],
                       profile="smoke", options=GridOptions(tasks=2))
    tables, times, _ = build_tables(specs, tmp_path)
    pos, ori = tables
    assert (pos.spec.variant, ori.spec.variant) == ("position", "orientation")
    p = {r.method: r for r in pos.rows}
    o = {r.method: r for r in ori.rows}
    assert p["sg"].ours["ACC"] == 0.5 and o["sg"].ours["ACC"] == 1.0
    assert o["hn"].ours["REM"] == 0.5
    # FS from each model's own final size: position SG 200 vs HN 150; orientation 400 vs 100
    assert p["hn"].ours["FS"] == pytest.approx(0.25)
    assert o["hn"].ours["FS"] == pytest.approx(0.75)
    assert o["hn"].diff("ACC") == pytest.approx(0.25 - cl_table("robotasks", "orientation")
                                                ["HN"]["ACC"])
    assert math.isnan(p["sg"].ours["exec_ACC"])  # no simulation in these runs
    assert [t.part for t in times] == ["position", "orientation"]


def test_cli_list_and_tables(tmp_path, capsys):
    from clfd_bench.cli.main import main

    assert main(["paper", "list"]) == 0
    assert "495 runs" in capsys.readouterr().out
    assert main(["paper", "list", "--datasets", "robotasks", "--methods", "mas"]) == 2
    assert "did not run MAS" in capsys.readouterr().err
    _write_run(tmp_path, _spec("hn", 0), {"dtw": _cl(1.0, 1.0)}, {"position": [5, 5]},
               {"position": [1.0, 1.0]}, sim={"ACC": 1.0, "REM": 1.0, "BWT": 0.0})
    argv = ["--datasets", "helloworld", "--methods", "hn,sg", "--nodes", "t", "--seeds", "0",
            "--orders", "0", "--profile", "smoke", "--tasks", "2", "--out", str(tmp_path)]
    assert main(["paper", "list", "--runs", *argv]) == 0
    out = capsys.readouterr().out
    assert "done     helloworld/hn/smoke_nodet_o0_s0_k2" in out
    assert "missing  helloworld/sg/smoke_nodet_o0_s0_k2" in out
    assert main(["paper", "tables", *argv]) == 0
    assert "1 of 2 selected runs are finished" in capsys.readouterr().out
    # 2 methods x (8 CL columns + exec ACC, exec REM, exec CL_score)
    assert (tmp_path / "paper_tables.csv").read_text().count("\nhelloworld_t,") == 22
    assert main(["paper", "tables", *argv[:-1], str(tmp_path / "nope")]) == 2


def test_cli_run_trains_missing_runs_once(tmp_path, capsys):
    from clfd_bench.cli.main import main

    argv = ["paper", "run", "--datasets", "helloworld", "--methods", "sg", "--nodes", "t",
            "--seeds", "0", "--orders", "0", "--profile", "smoke", "--tasks", "1", "--no-sim",
            "--out", str(tmp_path)]
    assert main(argv) == 0
    assert "1 run: 1 trained now, 0 already done" in capsys.readouterr().out
    results = tmp_path / "runs/helloworld/sg/smoke_nodet_o0_s0_k1_nosim/results.json"
    before = results.stat().st_mtime_ns
    assert main(argv) == 0
    assert "1 run: 0 trained now, 1 already done" in capsys.readouterr().out
    assert results.stat().st_mtime_ns == before
    table = json.loads((tmp_path / "paper_tables.json").read_text())["cl_tables"][0]
    assert table["rows"][0]["runs_done"] == 1 and table["rows"][0]["ours"]["ACC"] is not None


def test_each_robotasks_table_takes_fs_from_its_own_model():
    """The position table's FS compares position models, the orientation table's orientation
    models (as the paper's tables); a leaderboard of pose runs ranks by the position model."""
    from clfd_bench.leaderboard.aggregate import _final_size
    from clfd_bench.studies.paper_tables import _view

    results = {"num_params": [40, 60], "cl_metrics_primary": "dtw",
               "num_params_by_part": {"position": [10, 20], "orientation": [30, 40]},
               "cl_metrics_by_metric": {"dtw": {}, "quaternion": {}}}
    assert _final_size(_view(results, "dtw", "position")) == 20
    assert _final_size(_view(results, "quaternion", "orientation")) == 40
    assert _final_size(results) == 20
    assert _final_size({"num_params": [5, 7]}) == 7  # planar runs: the whole model
