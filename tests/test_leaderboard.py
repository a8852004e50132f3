"""The leaderboard grid: local and Ray executors agree, resuming trains nothing twice,
a crashing run is reported and does not stop the grid, tables and figures are written."""

from __future__ import annotations

import json
import sys

import pytest

from clfd_bench.leaderboard.grid import GridOptions, RunSpec
from clfd_bench.leaderboard.runner import run_leaderboard

GRID = dict(dataset="helloworld", methods=["sg", "hn"], profile="smoke", seeds=[0], orders=[0])


def _options(**where) -> GridOptions:
    return GridOptions(tasks=2, sim=True, **where)

# Wall-clock columns differ between any two runs; everything else must be identical.
CLOCK_KEYS = {"TE", "CL_score", "CL_stability", "exec_CL_score", "train_time_s", "train_cpu_s"}


def _table(out):
    rows = json.loads((out / "leaderboard.json").read_text())["rows"]
    return {
        row["method"]: {k: v["values"] for k, v in row["metrics"].items() if k not in CLOCK_KEYS}
        for row in rows
    }


def _run_errors(out, spec: RunSpec):
    results = json.loads((spec.run_dir(out) / "results.json").read_text())
    return results["errors"], results.get("success")


@pytest.fixture(scope="module")
def local_grid(tmp_path_factory):
    out = tmp_path_factory.mktemp("local")
    result = run_leaderboard(**GRID, out=out, options=_options(executor="local", workers=2))
    return out, result


def test_local_grid_writes_tables_and_figures(local_grid):
    out, result = local_grid
    assert len(result.trained) == 2 and not result.failed
    for name in ("leaderboard.md", "leaderboard.csv", "leaderboard.json", "error_vs_task.png",
                 "error_boxes.png", "cl_radar.png", "success_vs_task.png"):
        assert (out / name).is_file(), name
    md = (out / "leaderboard.md").read_text()
    main_table = md.split("## Executions that failed")[0]
    assert main_table.count("| SG |") == 1 and main_table.count("| HN |") == 1
    assert "## Executions that failed, by kind" in md  # the grid ran with simulation
    for spec in result.specs:  # each run's worker: the library's entry point, output logged
        log = (spec.run_dir(out) / "train.log").read_text()
        assert "-m clfd_bench.harness.worker {" in log and "clfd_bench.cli" not in log
        assert "executed in simulation after task 1" in log and "done: " in log
    table = _table(out)
    assert set(table) == {"sg", "hn"}
    assert table["sg"]["ACC"] and table["hn"]["exec_ACC"]


def test_rerun_trains_nothing_twice(local_grid):
    out, _ = local_grid
    spec = RunSpec("helloworld", "sg", "smoke", 0, 0, "t", 2, True)
    before = spec.run_dir(out).joinpath("results.json").stat().st_mtime_ns
    again = run_leaderboard(**GRID, out=out, options=_options(executor="local", workers=2))
    assert again.trained == [] and len(again.skipped) == 2
    assert spec.run_dir(out).joinpath("results.json").stat().st_mtime_ns == before


def test_half_finished_grid_resumes_without_retraining(tmp_path):
    """A grid killed after one task of one run: the next call finishes that run from its
    checkpoint (task 0 is not trained again) and trains the missing run."""
    from clfd_bench.cli.main import main

    hn = RunSpec("helloworld", "hn", "smoke", 0, 0, "t", 2, True)
    assert main(["train", "--method", "hn", "--dataset", "helloworld", "--profile", "smoke",
                 "--tasks", "1", "--quiet", "--out", str(hn.run_dir(tmp_path))]) == 0
    first = json.loads((hn.run_dir(tmp_path) / "results.json").read_text())
    assert len(first["train_time_s"]) == 1
    result = run_leaderboard(**GRID, out=tmp_path, options=_options(executor="local", workers=1))
    assert sorted(s.method for s in result.trained) == ["hn", "sg"] and not result.failed
    final = json.loads((hn.run_dir(tmp_path) / "results.json").read_text())
    assert final["complete"] and len(final["train_time_s"]) == 2
    assert final["train_time_s"][0] == first["train_time_s"][0]  # task 0 not retrained
    assert final["errors"]["dtw"][0][0] == first["errors"]["dtw"][0][0]
    log = (hn.run_dir(tmp_path) / "train.log").read_text()
    assert "resuming" in log


def test_crashing_run_is_reported_and_grid_goes_on(tmp_path, monkeypatch):
    original = RunSpec.worker_argv

    def argv(self, root):
        if self.method == "hn":
            return [sys.executable, "-c", "raise SystemExit('boom: injected failure')"]
        return original(self, root)

    monkeypatch.setattr(RunSpec, "worker_argv", argv)
    result = run_leaderboard(**GRID, out=tmp_path, options=_options(executor="local", workers=1))
    assert [o.spec.method for o in result.failed] == ["hn"]
    assert "boom: injected failure" in result.failed[0].error
    md = (tmp_path / "leaderboard.md").read_text()
    assert "failed" in md and "boom: injected failure" in md
    table = _table(tmp_path)
    assert table["sg"]["ACC"]  # the other run finished and is in the table


def test_ray_executor_gives_identical_tables(local_grid, tmp_path):
    pytest.importorskip("ray", reason="Ray is the optional extra clfd-bench[dist]")
    out, _ = local_grid
    result = run_leaderboard(**GRID, out=tmp_path, options=_options(executor="ray"))
    assert len(result.trained) == 2 and not result.failed
    assert _table(tmp_path) == _table(out)
    for spec in result.specs:
        assert _run_errors(tmp_path, spec) == _run_errors(out, spec)


def test_overrides_name_the_run_and_reach_training(tmp_path):
    """A hyperparameter variant gets its own run directory and its ``--set`` reaches the config."""
    from clfd_bench.harness.config import resolve_config

    plain = RunSpec("helloworld", "hn", "smoke", 0)
    variant = RunSpec("helloworld", "hn", "smoke", 0, overrides=[("beta", "0.0042")])
    assert variant.run_dir(tmp_path) != plain.run_dir(tmp_path)
    assert variant.name.endswith("_beta=0.0042")
    assert RunSpec(**json.loads(json.dumps(variant.to_dict()))) == variant  # Ray/failed.json
    sets = list(variant.job(tmp_path).train.overrides)
    assert sets == ["beta=0.0042"]
    config = resolve_config("hn", "helloworld", "smoke", overrides=sets)
    assert config.to_dict()["parts"]["position"]["beta"] == pytest.approx(0.0042)
    with pytest.raises(ValueError, match="directory name"):
        RunSpec("helloworld", "hn", "smoke", 0, overrides=[("beta", "1/2")])


def test_success_figure_skips_tasks_without_an_env(tmp_path):
    """RoboTasks9 runs execute only the tasks that have a scene; the others' cells are None
    (clfd_bench.execution.scoring.sim_fields) and the figure is drawn over the executed ones."""
    from clfd_bench.leaderboard.aggregate import RunRecord
    from clfd_bench.leaderboard.plots import plot_success_vs_task

    success = [[[True, False], None, None], [[True, True], None, None],
               [[False, False], None, [True, True]]]
    results = {"tasks": ["a", "b", "c"], "success": success}
    spec = RunSpec("robotasks9", "sg", "smoke", 0, 0, "t", 3, True)
    path = plot_success_vs_task([RunRecord(spec, "done", results)], ["sg"], tmp_path, "t")
    assert path is not None and path.stat().st_size > 0
