"""The task-order study: a tiny grid (smoke, HelloWorld, 2 tasks, orders 0 and 1, SG) gives a
figure with one column per order, table values equal to the runs' results.json, and a rerun
that trains nothing; the spread/ranking summary is checked on hand-made cells."""

from __future__ import annotations

import json
import math

import pytest

from clfd_bench.cli.main import main
from clfd_bench.leaderboard.grid import GridOptions, RunSpec
from clfd_bench.leaderboard.runner import collect
from clfd_bench.metrics.cl import cl_score, cl_stability
from clfd_bench.studies.task_order import (
    OrderCell,
    method_spread,
    order_figure,
    order_specs,
    run_order_study,
)

STUDY = dict(datasets=["helloworld"], methods=["sg"], orders=[0, 1], seeds=[0], profile="smoke",
             options=GridOptions(tasks=2, sim=False))  # fmt: skip


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("order")
    argv = ["study", "order", "--datasets", "helloworld", "--methods", "sg", "--orders", "0,1",
            "--seeds", "0", "--profile", "smoke", "--tasks", "2", "--no-sim", "--out", str(out)]
    assert main(argv) == 0
    return out


def _results(out, order: int) -> dict:
    spec = RunSpec("helloworld", "sg", "smoke", 0, order, "t", 2, False)
    return json.loads((spec.run_dir(out) / "results.json").read_text())


def test_figure_has_one_column_per_order(study):
    assert (study / "order_helloworld.png").is_file()
    records = collect(order_specs(**STUDY), study)
    fig = order_figure(records, "helloworld", ["sg"], [0, 1])
    titles = [ax.get_title() for ax in fig.axes]
    assert titles == ["order 0", "order 1"]  # no sim: one row (DTW), two columns
    ticks = [[t.get_text() for t in ax.get_xticklabels()] for ax in fig.axes]
    assert ticks == [["0\nh", "1\ne"], ["0\nl", "1\nd"]]  # each order's own tasks
    # each column draws the SG median line through both tasks
    assert all(len(ax.lines[0].get_xdata()) == 2 for ax in fig.axes)


def test_table_matches_the_runs_results(study):
    cells = json.loads((study / "order_table.json").read_text())["cells"]
    assert [(c["order"], c["method"], c["tasks"]) for c in cells] == [
        (0, "sg", ["h", "e"]), (1, "sg", ["l", "d"])]  # fmt: skip
    for cell in cells:
        res = _results(study, cell["order"])
        cl = res["cl_metrics"]
        assert cell["metrics"]["ACC"] == pytest.approx(cl["ACC"])
        assert cell["metrics"]["REM"] == pytest.approx(cl["REM"])
        # one method: FS = 1 - own size / own size = 0
        crit = {k: cl[k] for k in ("ACC", "REM", "MS", "TE", "SSS")} | {"FS": 0.0}
        assert cell["metrics"]["CL_score"] == pytest.approx(cl_score(crit))
        assert cell["metrics"]["CL_stability"] == pytest.approx(cl_stability(crit))
        assert cell["metrics"]["exec_ACC"] is None  # --no-sim
        assert cell["rank"] == 1
    md = (study / "order_table.md").read_text()
    assert "| 0 | h, e | SG | 1 |" in md and "| 1 | l, d | SG | 1 |" in md


def test_rerun_trains_nothing(study):
    spec = RunSpec("helloworld", "sg", "smoke", 0, 1, "t", 2, False)
    before = (spec.run_dir(study) / "results.json").stat().st_mtime_ns
    again = run_order_study(**STUDY, out=study)
    assert again.trained == [] and len(again.skipped) == 2 and not again.failed
    assert (spec.run_dir(study) / "results.json").stat().st_mtime_ns == before


def test_spread_and_rank_changes_on_hand_made_cells():
    def cell(order, method, score, acc, rank):
        return OrderCell("lasa", order, method, 1, 0, {"CL_score": score, "ACC": acc}, rank)

    cells = [cell(0, "hn", 0.90, 0.95, 1), cell(0, "sg", 0.80, 1.00, 2),
             cell(1, "hn", 0.70, 0.85, 2), cell(1, "sg", 0.75, 0.99, 1),
             cell(2, "hn", 0.88, math.nan, 1), cell(2, "sg", 0.79, 0.98, 2)]  # fmt: skip
    spread = {e["method"]: e for e in method_spread(cells)}
    assert spread["hn"]["CL_score_spread"] == pytest.approx(0.20)
    assert spread["hn"]["ACC_spread"] == pytest.approx(0.10)  # the NaN order is skipped
    assert spread["sg"]["ranks"] == [2, 1, 2] and spread["sg"]["rank_changes"]
    same = method_spread([cell(0, "hn", 0.9, 0.9, 1), cell(1, "hn", 0.8, 0.9, 1)])
    assert not same[0]["rank_changes"]


def test_unknown_names_fail_listing_valid_ones(tmp_path, capsys):
    assert main(["study", "order", "--datasets", "nope", "--out", str(tmp_path)]) == 2
    assert "valid: lasa, helloworld" in capsys.readouterr().err
    assert main(["study", "order", "--datasets", "helloworld", "--orders", "3",
                 "--out", str(tmp_path)]) == 2  # fmt: skip
    assert "task orders 0..2" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()
