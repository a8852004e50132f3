"""`clfd-bench bench sim` measures and reports (speed targets are not asserted: shared CI)."""

from __future__ import annotations

import argparse
import json

from clfd_bench.cli import bench_sim
from clfd_bench.execution.bench import target_for


def test_bench_sim_json(capsys):
    args = argparse.Namespace(env=["clfd/HelloWorld-r-v3"], demo=1, repeats=1, json=True)
    assert bench_sim._run(args) == 0
    out = json.loads(capsys.readouterr().out)
    (row,) = out["results"]
    assert row["env"] == "clfd/HelloWorld-r-v3" and row["success"] is True
    assert row["steps"] == 1060 and abs(row["sim_s"] - 1060 / 60) < 1e-9
    assert row["x_realtime"] > 1.0  # far slower than real time would mean something is broken
    assert row["ik_us_per_step"] > 0 and row["physics_us_per_step"] > 0
    assert "CPUs" in out["machine"]


def test_targets():
    assert target_for("clfd/Pouring-v3") == 30.0
    assert target_for("clfd/MatFolding-v3") == target_for("clfd/Scoop-v3") == 30.0
    assert target_for("clfd/LASA-Angle-v3") == 50.0
