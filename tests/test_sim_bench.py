"""`clfd-bench bench sim` measures and reports (speed targets are not asserted: shared CI)."""

from __future__ import annotations

import argparse
import json

import pytest

from clfd_bench.cli import bench_sim
from clfd_bench.execution.bench import RATIO_TARGET


def test_bench_sim_json(capsys):
    args = argparse.Namespace(env=["clfd/HelloWorld-r-v3"], demo=1, repeats=1, json=True)
    assert bench_sim._run(args) == 0
    out = json.loads(capsys.readouterr().out)
    (row,) = out["results"]
    assert row["env"] == "clfd/HelloWorld-r-v3" and row["success"] is True
    assert row["steps"] == 1060 and abs(row["sim_s"] - 1060 / 60) < 1e-9
    assert row["x_realtime"] > 1.0  # far slower than real time would mean something is broken
    assert row["ik_us"] > 0 and row["physics_us"] > 0
    # the parts add up to the step, and the ratio is the step over physics + IK
    assert abs(row["physics_us"] + row["ik_us"] + row["rest_us"] - row["step_us"]) < 1e-6
    assert abs(row["ratio"] - row["step_us"] / (row["physics_us"] + row["ik_us"])) < 1e-9
    assert row["ratio_target"] == RATIO_TARGET == 1.4
    assert row["meets_target"] == (row["ratio"] <= 1.4)
    assert "CPUs" in out["machine"]


def test_an_unknown_env_id_is_refused_before_anything_runs(capsys):
    args = argparse.Namespace(env=["clfd/HelloWorld-r-v3", "clfd/Scop-v3"], demo=0, repeats=1,
                              json=False)
    with pytest.raises(SystemExit, match=r"'clfd/Scop-v3' \(did you mean 'clfd/Scoop-v3'\?\)"):
        bench_sim._run(args)
    assert capsys.readouterr().out == ""  # not even the table's header
