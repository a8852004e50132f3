"""The inference-timing study: it times the learner's own NODE, and its table compares right."""

from __future__ import annotations

import csv
import io
import time

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from clfd_bench.cli.main import main
from clfd_bench.harness.config import resolve_config
from clfd_bench.harness.protocol import run_training
from clfd_bench.learning.mlp import split_flat
from clfd_bench.learning.odeint import SolverSpec, integrate
from clfd_bench.learning.tangent import quat_log_relative
from clfd_bench.metrics.paper_numbers import inference
from clfd_bench.studies import inference_timing as it
from clfd_bench.studies import inference_timing_measure as itm
from clfd_bench.studies import inference_timing_report as itr


def _manual_field(method, index: int, t: float, y: torch.Tensor) -> torch.Tensor:
    """The NODE of task ``index`` evaluated from the hypernetwork's flat output, by hand."""
    flat = method.hnet(method.embeddings[index])
    weights = split_flat(flat, method.node_spec.param_shapes())
    h = torch.cat([y, torch.full((y.shape[0], 1), t)], dim=1)
    for layer in range(0, len(weights), 2):
        h = h @ weights[layer].t() + weights[layer + 1]
        if layer < len(weights) - 2:
            h = F.elu(h)
    return h


@pytest.mark.parametrize("method", ["hn", "chn"])
def test_generated_node_is_the_learners_own(method):
    learner, tasks = itm.build_learner(method, "robotasks", "smoke", seed=3)
    assert learner.num_tasks == len(tasks) == 4  # the paper's number of task embeddings
    parts = itm.timed_parts(learner, tasks, source="built", index=2)
    assert [p.label for p in parts] == ["RoboTasks (pos)", "RoboTasks (ori)"]
    rng = np.random.default_rng(0)
    for tp in parts:
        field = itm.generate_node(tp.part, 2)
        y = torch.as_tensor(rng.normal(size=(5, 3)), dtype=torch.float32)
        with torch.no_grad():
            ours = field(torch.tensor(0.7), y)
            own = tp.part.method.field(2)(torch.tensor(0.7), y)
            manual = _manual_field(tp.part.method, 2, 0.7, y)
            other_task = tp.part.method.field(1)(torch.tensor(0.7), y)
        torch.testing.assert_close(ours, own)
        torch.testing.assert_close(ours, manual, rtol=1e-5, atol=1e-6)
        assert not torch.allclose(ours, other_task)  # the embedding of task 2 was used
    # the orientation start is the demo's tangent vector relative to its final quaternion
    ori = parts[1]
    task = tasks[2]
    expected = quat_log_relative(task.quaternions[0, :1], task.demo_goals[:1, 3:])
    np.testing.assert_allclose(ori.y0.numpy(), expected, rtol=1e-5, atol=1e-6)


def test_timed_integration_is_the_learners_prediction():
    learner, tasks = itm.build_learner("hn", "helloworld", "smoke", seed=1)
    assert learner.num_tasks == 7
    (tp,) = itm.timed_parts(learner, tasks, source="built", index=4)
    assert tp.times.shape == (1000,) and tp.solver.method == "rk4"
    with torch.no_grad():
        traj = integrate(itm.generate_node(tp.part, 4), tp.y0, tp.times, tp.solver)  # [1, T, 2]
    task = tasks[4]
    pred = learner.predict(4, task.demos[:1, 0], task.times)  # [1, T, 2] data units
    norm = tp.part.normalizers[4]
    np.testing.assert_allclose(norm.invert(traj.double().numpy()), pred, rtol=1e-5, atol=1e-6)
    # RK4: 4 evaluations per output interval
    field = itm.generate_node(tp.part, 4)
    assert itm.count_evaluations(field, tp.y0, tp.times, tp.solver) == 4 * 999
    two = SolverSpec("rk4", substeps=2)
    assert itm.count_evaluations(field, tp.y0, tp.times[:11], two) == 4 * 10 * 2


def test_time_call_runs_warmup_then_repeats():
    calls = []

    def fn():
        calls.append(1)
        time.sleep(0.002)

    ms = itm.time_call(fn, repeats=3, warmup=2)
    assert len(calls) == 5 and len(ms) == 3
    assert all(2.0 <= m < 500 for m in ms)
    with pytest.raises(ValueError, match="repeats must be >= 1"):
        itm.time_call(fn, repeats=0, warmup=0)


def _cell(label, method, gen, step, integ, device="cpu"):
    return {"device": device, "label": label, "method": method, "generate_ms": gen,
            "generate_hz": 1e3 / gen, "step_ms": step, "step_hz": 1e3 / step,
            "integrate_ms": integ, "integrate_hz": 1e3 / integ, "nfe": 100}


def test_comparison_table_has_the_papers_structure_and_ratios():
    paper = inference("cpu")
    # hand-made cells, given out of order: twice the paper's generation time, half its step
    cells = [
        _cell(label, m, 2 * v["generate_ms"], 0.5 * v["step_ms"], 100.0)
        for (label, m), v in reversed(list(paper.items()))
    ]
    cells.append(_cell("LASA", "HN", 1.0, 1.0, 1.0, device="cuda"))  # other device: ignored
    rows = itr.comparison_rows(cells, "cpu")
    assert [(r["dataset"], r["method"]) for r in rows] == list(paper)  # the paper's order
    assert len(rows) == 8
    for r in rows:
        assert r["ratio_generate"] == pytest.approx(2.0)
        assert r["ratio_step"] == pytest.approx(0.5)
        ref = paper[(r["dataset"], r["method"])]
        assert r["ratio_integrate"] == pytest.approx(100.0 / ref["integrate_ms"])
        assert r["paper_integrate_hz"] == ref["integrate_hz"]
    lasa_hn = rows[0]
    assert lasa_hn["generate_ms"] == pytest.approx(6.02) and lasa_hn["paper_generate_ms"] == 3.01
    # a hand-made paper table: ours/paper, missing cells give no ratio
    own = {("HelloWorld", "CHN"): {"generate_ms": 4.0, "step_ms": 0.25, "integrate_ms": 50.0}}
    rows = itr.comparison_rows([_cell("HelloWorld", "CHN", 1.0, 1.0, 200.0),
                               _cell("LASA", "HN", 1.0, 1.0, 1.0)], "cpu", paper=own)
    assert [(r["dataset"], r["method"]) for r in rows] == [("LASA", "HN"), ("HelloWorld", "CHN")]
    assert rows[0]["ratio_generate"] is None and rows[0]["paper_step_ms"] is None
    assert (rows[1]["ratio_generate"], rows[1]["ratio_step"], rows[1]["ratio_integrate"]) == (
        0.25, 4.0, 4.0)
    md = itr.to_markdown(rows, "cpu").splitlines()
    assert md[2].startswith("| Dataset | Method |") and len(md) == 6
    assert "| HelloWorld | CHN | 1.00 | 1000.00 | 4.00 |" in md[5]
    table = list(csv.DictReader(io.StringIO(itr.to_csv({"cpu": rows}))))
    assert len(table) == 2 and float(table[1]["ratio_integrate"]) == 4.0
    assert itr.ratio(3.0, 0.0) is None and itr.ratio(None, 1.0) is None


def test_run_study_on_a_trained_run_is_cached(tmp_path):
    run = tmp_path / "run"
    config = resolve_config("chn", "helloworld", "smoke", seed=0, tasks=2,
                            overrides=("iterations=5",))
    run_training(config, run, threads=1, log=None)
    out = tmp_path / "timing"
    first = it.run_study(out, runs=[run], repeats=3, warmup=1, log=None,
                         overrides=["eval_solver=dopri5"])
    assert (first.measured, first.cached) == (1, 0)
    (row,) = first.rows["cpu"]
    assert (row["dataset"], row["method"]) == ("HelloWorld", "CHN")
    assert row["paper_generate_ms"] == inference("cpu")[("HelloWorld", "CHN")]["generate_ms"]
    cell = first.cells[0]
    assert cell["solver"]["method"] == "dopri5" and cell["num_tasks"] == 2
    assert cell["nfe"] > 6 and len(cell["samples"]["generate"]) == 3
    for name in ("timing.md", "timing.csv", "timing.json", "timing_cpu.png"):
        assert (out / name).is_file()
    again = it.run_study(out, runs=[run], repeats=3, warmup=1, log=None,
                         overrides=["eval_solver=dopri5"])
    assert (again.measured, again.cached) == (0, 1)
    assert again.cells[0]["generate_ms"] == cell["generate_ms"]
    # different settings are measured anew
    third = it.run_study(out, runs=[run], repeats=2, warmup=0, log=None)
    assert third.measured == 1 and third.cells[0]["solver"]["method"] == "rk4"


def test_cli_errors_name_the_valid_choices(tmp_path, capsys):
    assert main(["study", "timing", "--methods", "sg", "--out", str(tmp_path)]) == 2
    assert "valid: hn, chn" in capsys.readouterr().err
    assert main(["study", "timing", "--datasets", "robotasks9", "--out", str(tmp_path)]) == 2
    assert "valid: lasa, helloworld, robotasks" in capsys.readouterr().err
    missing = tmp_path / "no_run"
    assert main(["study", "timing", "--run", str(missing), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "checkpoint.pt does not exist" in err and "clfd-bench train" in err
