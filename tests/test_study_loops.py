"""The loop study's premise, checked: HelloWorld's 'e', 'r' and 'd' demos cross themselves,
a NODE^I (no time input) started on them never does, a NODE^T can; and the study's rows are
read from a run's diagonal."""

from __future__ import annotations

import numpy as np
import torch

from clfd_bench.learning.node import NodeSpec
from clfd_bench.learning.odeint import SolverSpec, integrate
from clfd_bench.metrics.trajectory import self_crossings


def test_loop_letters_cross_themselves_and_the_others_do_not():
    from clfd_bench.data import load_dataset

    ds = load_dataset("helloworld", order=0)
    med = {}
    for task in ds.tasks:
        demos = np.asarray(task.positions)
        extent = float(np.linalg.norm(np.ptp(demos.reshape(-1, 2), axis=0)))
        med[task.name] = float(np.median([self_crossings(d, 0.005 * extent) for d in demos]))
    assert {n for n, c in med.items() if c >= 1} == {"e", "r", "d"}  # the paper's loop letters


def test_a_time_invariant_planar_node_never_crosses_itself():
    """NODE^I fields through our integrator: random strong ones from many starts, and one set
    by hand to spiral (it turns around its goal several times) never cross themselves."""
    torch.set_num_threads(1)
    gen = torch.Generator().manual_seed(1)
    y0 = torch.randn(16, 2, generator=gen, dtype=torch.float64)
    t = torch.linspace(0, 10, 300, dtype=torch.float64)
    solver = SolverSpec("rk4", substeps=2)
    spec = NodeSpec(2, (32, 32), time_input=False)
    w = [x * 3 for x in spec.init_weights(gen, torch.float64)]
    with torch.no_grad():
        paths = integrate(spec.field(w), y0, t, solver).numpy()
    assert [self_crossings(p) for p in paths] == [0] * 16
    # One ELU layer kept in its linear part (|y| < 10): f(y) = A y, a stable focus.
    spiral = NodeSpec(2, (2,), time_input=False)
    a = torch.tensor([[-0.15, -2.0], [2.0, -0.15]], dtype=torch.float64)
    b0 = torch.full((2,), 10.0, dtype=torch.float64)
    w = [torch.eye(2, dtype=torch.float64), b0, a, -a @ b0]
    with torch.no_grad():
        paths = integrate(spiral.field(w), y0, t, solver).numpy()
    heading = np.unwrap(np.arctan2(*np.diff(paths, axis=1).transpose(2, 0, 1)[::-1]), axis=1)
    assert np.ptp(heading, axis=1).min() > 4 * np.pi  # two turns at least, every start
    assert [self_crossings(p) for p in paths] == [0] * 16


def test_cli_reads_each_runs_diagonal_and_refuses_non_planar_data(tmp_path, capsys):
    import json

    from clfd_bench.cli.main import main

    argv = ["study", "loops", "--dataset", "helloworld", "--methods", "sg", "--profile",
            "smoke", "--tasks", "2", "--no-sim", "--workers", "1", "--out", str(tmp_path)]
    assert main(argv) == 0
    rows = json.loads((tmp_path / "loops.json").read_text())["rows"]
    assert {(r["task"], r["node"]) for r in rows} == {("h", "t"), ("e", "t"), ("h", "i"),
                                                      ("e", "i")}
    e_i = next(r for r in rows if r["task"] == "e" and r["node"] == "i")
    assert e_i["demo_crossings"] == 1 and e_i["pred_crossings"] == 0
    assert e_i["exec_pass"] is None  # no simulation: never a made-up number
    results = json.loads((tmp_path / "runs/helloworld/sg/smoke_nodei_o0_s0_k2_nosim"
                          / "results.json").read_text())
    assert e_i["dtw_pass"] == results["accuracy"]["dtw"][1][1]
    md = (tmp_path / "loops.md").read_text()
    assert "| SG | e | 1 |" in md and (tmp_path / "loops.png").stat().st_size > 0
    capsys.readouterr()
    assert main([*argv[:3], "robotasks", *argv[4:]]) == 2
    assert "crossings are counted in the plane" in capsys.readouterr().err
