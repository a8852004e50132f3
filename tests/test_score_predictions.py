"""``clfd-bench score``: predictions made elsewhere are scored with the numbers a run trained
here gets (the demos score ACC 1, another task's demos ACC 0, a trained run's own predictions
its own matrices and metrics), bad files get one line and exit code 2 with nothing written,
and a scored run takes its place in a leaderboard with the criteria it cannot know left
empty. HelloWorld, 2-3 tasks; one test executes in simulation.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from run_checks import refused

import clfd_bench
from clfd_bench.cli.main import main
from clfd_bench.data import load_dataset
from clfd_bench.runs import RunDir

DATASET = "helloworld"
FIELDS = ("num_params", "num_params_by_part", "train_time_s", "train_time_s_by_part",
          "stored_samples")
SCORE = ["score", "--dataset", DATASET, "--no-sim"]
# The grid of the leaderboard test; its FT run is also the trained run re-scored below.
GRID = ["leaderboard", "--dataset", DATASET, "--methods", "ft", "--profile", "smoke",
        "--tasks", "2", "--no-sim", "--workers", "1"]


@pytest.fixture(scope="module")
def ds():
    return load_dataset(DATASET, order=0)


def _write(folder: Path, ds, m: int, source=lambda j: j, meta: dict | None = None) -> Path:
    """``after_task_<i>.npz`` for ``m`` tasks: task ``j``'s predictions are the demos of task
    ``source(j)``."""
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(m):
        np.savez(folder / f"after_task_{i}.npz",
                 **{f"task_{j}": ds[source(j)].demos for j in range(i + 1)})
    if meta is not None:
        (folder / "meta.json").write_text(json.dumps(meta))
    return folder


def _results(run: Path) -> dict:
    return json.loads((run / "results.json").read_text())


def test_demos_as_predictions_score_perfectly(ds, tmp_path, capsys):
    preds = _write(tmp_path / "demos", ds, 3)
    out = tmp_path / "run"
    assert main([*SCORE, str(preds), "--out", str(out), "--method-name", "demos"]) == 0
    printed = capsys.readouterr().out
    assert "ACC 1.000, REM 1.000" in printed and "MS —" in printed
    res = _results(out)
    assert res["complete"] and res["tasks_done"] == 3 and res["tasks"] == ["h", "e", "l"]
    assert res["accuracy"]["dtw"] == [[1.0, None, None], [1.0, 1.0, None], [1.0, 1.0, 1.0]]
    cl = res["cl_metrics"]
    assert (cl["ACC"], cl["REM"], cl["BWT"]) == (1.0, 1.0, 0.0)
    # What needs model size, training time or stored samples is empty, and says so.
    assert cl["MS"] is None and cl["TE"] is None and cl["SSS"] is None
    assert res["not_provided"]["criteria"] == ["MS", "FS", "TE", "SSS", "CL_score",
                                               "CL_stability"]
    assert res["num_params"] is None and res["checkpoint"] is None
    assert all(e == 0.0 for row in res["errors"]["dtw"] for cell in row if cell for e in cell)
    assert res["config"]["method"] == "demos" and res["config"]["profile"] == "external"
    # Provenance: the source and the sha256 of every file read.
    ext = res["provenance"]["external"]
    assert ext["source"] == str(preds.absolute())
    for name, sha in ext["files"].items():
        assert sha == hashlib.sha256((preds / name).read_bytes()).hexdigest()
    assert sorted(ext["files"]) == [f"after_task_{i}.npz" for i in range(3)]
    # The run directory holds the predictions as a trained run does.
    assert RunDir(out).load_predictions(2)[1].tolist() == ds[1].demos.tolist()
    assert RunDir(out).status(3, sim=False).state == "done"

    # The one-.npz layout (and the Python API) gives the same numbers.
    single = tmp_path / "all.npz"
    np.savez(single, **{f"after_task_{i}/task_{j}": ds[j].demos
                        for i in range(3) for j in range(i + 1)},
             num_params=np.array([100, 100, 100]), stored_samples=np.zeros(3))
    again = clfd_bench.score_predictions(single, DATASET, out=tmp_path / "run_npz", sim=False)
    assert again["errors"] == res["errors"] and again["accuracy"] == res["accuracy"]
    assert again["cl_metrics"]["MS"] == 1.0 and again["cl_metrics"]["SSS"] == 1.0
    assert again["cl_metrics"]["TE"] is None
    assert again["not_provided"] == {"fields": ["train_time_s"],
                                     "criteria": ["TE", "CL_score", "CL_stability"]}


def test_demos_as_predictions_execute_as_demo_replays(ds, tmp_path):
    """In simulation the demos given as predictions succeed as demo replays do (every demo
    of every letter: the 'demo' family must succeed, docs/execution.md)."""
    from clfd_bench.execution.fingerprint import sim_fingerprint

    preds = _write(tmp_path / "demos", ds, 2)
    res = clfd_bench.score_predictions(preds, DATASET, tasks=2, out=tmp_path / "run")
    assert res["success"][0] == [[True] * 8, None]
    assert res["success"][1] == [[True] * 8, [True] * 8]
    assert res["sim_cl_metrics"] == {"ACC": 1.0, "REM": 1.0, "BWT": 0.0}
    assert res["sim"]["rollouts_executed"] == 16  # h after task 0 and 1 is one rollout each
    assert RunDir(tmp_path / "run").status(2, sim=True, fingerprint=sim_fingerprint()
                                           ).state == "done"


def test_other_tasks_demos_score_zero(ds, tmp_path):
    preds = _write(tmp_path / "other", ds, 3, source=lambda j: (j + 1) % 3)
    res = clfd_bench.score_predictions(preds, DATASET, out=tmp_path / "run", sim=False)
    assert res["cl_metrics"]["ACC"] == 0.0
    assert res["accuracy"]["dtw"] == [[0.0, None, None], [0.0, 0.0, None], [0.0, 0.0, 0.0]]


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    """A one-run smoke grid (FT, 2 tasks, no simulation): its leaderboard folder and run."""
    out = tmp_path_factory.mktemp("grid")
    assert main([*GRID, "--out", str(out)]) == 0
    run = out / "runs" / DATASET / "ft" / "smoke_nodet_o0_s0_k2_nosim"
    assert _results(run)["complete"]
    return out, run


def test_rescoring_a_trained_run_reproduces_it(grid, tmp_path):
    _, run = grid
    trained = _results(run)
    preds = tmp_path / "preds"
    shutil.copytree(run / "predictions", preds)
    # Without the optional fields: the same errors and accuracy, MS/TE/SSS empty.
    bare = clfd_bench.score_predictions(preds, DATASET, out=tmp_path / "bare", sim=False)
    for key in ("tasks", "units", "metrics", "thresholds", "total_samples", "errors",
                "accuracy", "cl_metrics_primary", "predictions"):
        assert bare[key] == trained[key], key
    for key in ("ACC", "REM", "BWT"):
        assert bare["cl_metrics"][key] == trained["cl_metrics"][key]
    assert {k: bare["cl_metrics"][k] for k in ("MS", "TE", "SSS")} == dict.fromkeys(
        ("MS", "TE", "SSS"))
    # With them (the keys of the run's results.json, in meta.json): identical CL metrics.
    (preds / "meta.json").write_text(json.dumps({k: trained[k] for k in FIELDS}))
    full = clfd_bench.score_predictions(preds, DATASET, out=tmp_path / "full", sim=False)
    for key in ("errors", "accuracy", "cl_metrics", "cl_metrics_by_metric", *FIELDS):
        assert full[key] == trained[key], key
    assert full["not_provided"] == {"fields": [], "criteria": []}


BAD = {
    # name: (task_1's array after task 1, texts the line must hold)
    "missing key": (None, ["after_task_1.npz", "missing key 'task_1'", "'h', 'e'",
                           "[8, 1000, 2]"]),
    "wrong shape": (lambda e: e[:, ::2], ["after_task_1.npz", "'task_1'", "[8, 500, 2]",
                                          "expected [8, 1000, 2]"]),
    "wrong number of demos": (lambda e: e[:7], ["after_task_1.npz", "[7, 1000, 2]",
                                                "has 8 demos, the file 7 predictions"]),
    "non-numeric": (lambda e: e.astype(str), ["after_task_1.npz", "'task_1'",
                                              "not real numbers"]),
    "wrong dimension": (lambda e: np.zeros((8, 1000, 7)), ["[8, 1000, 7]", "D = 7",
                                                           "is --dataset right?"]),
    "millimetres": (lambda e: e * 1000, ["'task_1'", "1e+03x the size", "other units?"]),
    "shrunk": (lambda e: e * 0.003, ["'task_1'", "0.003x the size", "do not start at"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_files_get_one_line_and_nothing_is_written(ds, tmp_path, capsys, case):
    change, expected = BAD[case]
    preds = _write(tmp_path / "preds", ds, 2)
    arrays = {"task_0": ds[0].demos}
    if change is not None:
        arrays["task_1"] = change(ds[1].demos)
    np.savez(preds / "after_task_1.npz", **arrays)
    refused(capsys, [*SCORE, str(preds)], tmp_path / "out", *expected,
             "docs/predictions.md")


def test_other_bad_inputs_get_one_line(ds, tmp_path, capsys):
    preds = _write(tmp_path / "preds", ds, 3)
    (preds / "after_task_1.npz").unlink()
    refused(capsys, [*SCORE, str(preds)], tmp_path / "out", "after_task_1.npz", "missing",
             "--tasks K")
    preds = _write(tmp_path / "preds2", ds, 2, meta={"num_param": [1, 2]})
    refused(capsys, [*SCORE, str(preds)], tmp_path / "out", "meta.json",
             "unknown field 'num_param'", "num_params")
    (preds / "meta.json").write_text(json.dumps({"train_time_s": [1.0, -2.0]}))
    refused(capsys, [*SCORE, str(preds)], tmp_path / "out", "'train_time_s'", "[1.0, -2.0]")
    (preds / "meta.json").unlink()
    np.savez(preds / "after_task_0.npz", task_0=ds[0].demos, times=ds[0].times)
    refused(capsys, [*SCORE, str(preds)], tmp_path / "out", "unknown key 'times'")
    (preds / "after_task_0.npz").write_bytes(b"not a zip")
    refused(capsys, [*SCORE, str(preds)], tmp_path / "out", "after_task_0.npz",
             "not a readable .npz")
    refused(capsys, [*SCORE, str(tmp_path / "nothing")], tmp_path / "out", "not found")


def test_out_holding_another_run_is_refused_and_kept(ds, tmp_path, capsys):
    preds = _write(tmp_path / "preds", ds, 2)
    out = tmp_path / "run"
    assert main([*SCORE, str(preds), "--out", str(out)]) == 0
    before = (out / "results.json").read_bytes()
    assert main([*SCORE, str(preds), "--out", str(out)]) == 0  # the same scoring again
    np.savez(preds / "after_task_1.npz", task_0=ds[1].demos, task_1=ds[1].demos)
    capsys.readouterr()
    assert main([*SCORE, str(preds), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds predictions scored with other files" in err
    assert json.loads((out / "results.json").read_bytes())["errors"] == json.loads(before)[
        "errors"]


def test_nan_predictions_count_as_diverged_failures(ds, tmp_path, capsys):
    """A NaN/inf prediction is scored as a training run scores a diverged one: its errors are
    None and it is inaccurate (documented choice; not an error)."""
    preds = _write(tmp_path / "preds", ds, 2)
    h = ds[0].demos.copy()
    h[3, 500, 1] = np.nan
    np.savez(preds / "after_task_1.npz", task_0=h, task_1=ds[1].demos)
    out = tmp_path / "run"
    assert main([*SCORE, str(preds), "--out", str(out)]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "after_task_1.npz task_0" in err[0] and "demos [3]" in err[0]
    res = _results(out)
    assert res["errors"]["dtw"][1][0][3] is None
    assert res["accuracy"]["dtw"][1] == [7 / 8, 1.0]
    assert res["provenance"]["external"]["nonfinite"] == [
        {"file": "after_task_1.npz", "key": "task_0", "demos": [3]}]


def test_scored_run_joins_a_leaderboard(grid, ds, tmp_path, capsys):
    out, _ = grid
    scored = tmp_path / "mine"
    assert main([*SCORE, str(_write(tmp_path / "preds", ds, 2)), "--out", str(scored),
                 "--method-name", "mine"]) == 0
    assert main([*GRID, "--out", str(out), "--include", str(scored)]) == 0
    board = json.loads((out / "leaderboard.json").read_text())
    rows = {row["method"]: row for row in board["rows"]}
    assert set(rows) == {"ft", "mine"}
    mine = rows["mine"]["metrics"]
    assert mine["ACC"]["median"] == 1.0 and mine["REM"]["median"] == 1.0
    for key in ("MS", "TE", "FS", "SSS", "CL_score", "train_time_s", "train_cpu_s",
                "final_params"):
        assert mine[key]["median"] is None and mine[key]["values"] == [], key
        assert key in rows["mine"]["not_provided"]
    assert rows["ft"]["metrics"]["FS"]["median"] is not None  # FS of the runs that know it
    assert rows["ft"]["metrics"]["CL_score"]["median"] is not None
    assert board["meta"]["included"] == [{"path": str(scored), "method": "mine",
                                          "external": True}]
    md = (out / "leaderboard.md").read_text()
    line = next(x for x in md.splitlines() if x.startswith("| ") and "| MINE |" in x)
    # CL_score, CL_stab, MS, TE, FS, SSS, exec CL_score, train s, train CPU s, params
    assert line.count("—") == 10
    capsys.readouterr()
    # A label that is also a grid method is refused before any work.
    ft_run = out / "runs" / DATASET / "ft" / "smoke_nodet_o0_s0_k2_nosim"
    assert main([*GRID, "--out", str(tmp_path / "lb2"), "--include", str(ft_run)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "also in --methods" in err
    assert not (tmp_path / "lb2").exists()
