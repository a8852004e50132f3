"""``clfd-bench bench train --runs``: runs trained in lockstep are timed together and their
throughput reported as runs x iterations per second; a bad count is refused in one line."""

from __future__ import annotations

import pytest

from clfd_bench.cli.bench_train import bench_method
from clfd_bench.cli.main import main


def test_lockstep_rows_report_each_run_and_all_runs():
    rows = bench_method("hn", "helloworld", profile="smoke", iterations=4, warmup=1,
                        tasks=(1,), runs=3)
    assert [(r["task"], r["runs"], r["part"]) for r in rows] == [(1, 3, "position")]
    row = rows[0]
    assert row["runs_it_per_s"] == pytest.approx(3 * row["it_per_s"])
    assert row["reference_it_per_s"] is None  # the original's speed is for one run


def test_a_bad_run_count_is_refused_in_one_line(capsys):
    assert main(["bench", "train", "--methods", "hn", "--datasets", "helloworld",
                 "--profile", "smoke", "--runs", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--runs 0" in err[0]
