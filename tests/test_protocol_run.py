"""The sequential protocol: results.json schema, predictions, checkpoints, resume, determinism."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from clfd_bench.cli.main import main as cli_main
from clfd_bench.harness.checkpoint import decode_checkpoint
from clfd_bench.harness.config import resolve_config
from clfd_bench.harness.predict import predict
from clfd_bench.harness.protocol import RunMismatchError, run_training
from clfd_bench.runs import RunDir

pytestmark = pytest.mark.usefixtures("data_dir")


@pytest.fixture
def data_dir(monkeypatch):
    import os
    from pathlib import Path

    shared = Path(__file__).resolve().parents[2] / "shared" / "datasets"
    if "CLFD_DATA_DIR" not in os.environ and shared.is_dir():
        monkeypatch.setenv("CLFD_DATA_DIR", str(shared))


def _smoke(method="hn", dataset="helloworld", tasks=2, seed=0, overrides=()):
    return resolve_config(method, dataset, "smoke", seed=seed, tasks=tasks, overrides=overrides)


def test_results_schema_predictions_and_checkpoint(tmp_path):
    results = run_training(_smoke("rep"), tmp_path, threads=1, log=None)
    on_disk = json.loads((tmp_path / "results.json").read_text())
    assert on_disk == json.loads(json.dumps(results))
    assert results["schema_version"] == 1 and results["complete"]
    assert results["tasks"] == ["h", "e"] and results["tasks_done"] == 2
    assert results["config"]["method"] == "rep" and results["config"]["tasks"] == 2
    for key in ("train_time_s", "train_cpu_s", "num_params", "stored_samples"):
        assert len(results[key]) == 2
    # CPU seconds of this process per task: spent, and not more than 2 threads' worth
    assert all(0 < c <= 2 * w + 0.5 for c, w in zip(results["train_cpu_s"],
                                                      results["train_time_s"], strict=True))
    assert results["stored_samples"] == [8 * 1000, 2 * 8 * 1000]
    for metric in ("dtw", "frechet", "swept_area"):
        rows = results["errors"][metric]
        assert len(rows[0][0]) == 8 and rows[0][1] is None and len(rows[1][1]) == 8
    assert results["accuracy"]["dtw"][0][1] is None  # j > i
    assert set(results["cl_metrics"]) >= {"ACC", "REM", "BWT", "MS", "SSS", "TE"}
    assert results["provenance"]["dataset"]["name"] == "helloworld"
    assert "torch" in results["provenance"]["packages"]

    cpu = results["provenance"]["cpu"]
    assert cpu["torch_capability"] == torch.backends.cpu.get_cpu_capability()
    assert cpu["model"] and isinstance(cpu["kernel_env"], dict)
    assert results["provenance"]["cpu_by_task"] == [cpu, cpu]

    # predictions on disk = the model's prediction from each demo's start, data units
    from clfd_bench.data import load_dataset

    ds = load_dataset("helloworld")
    preds = RunDir(tmp_path).load_predictions(1)
    assert sorted(preds) == [0, 1]
    saved = preds[0]
    assert saved.shape == (8, 1000, 2)
    again = predict(tmp_path, 0, ds[0].demos[:, 0], ds[0].times)
    assert np.allclose(again, saved, atol=1e-12)

    # the checkpoint holds tensors and plain data only
    obj = torch.load(tmp_path / "checkpoint.pt", weights_only=True)
    assert set(obj) == {"format", "header", "tensors"}
    header, tensors = decode_checkpoint(RunDir(tmp_path).read_checkpoint())
    assert header["parts"]["position"]["num_tasks"] == 2
    assert any(k.startswith("position/memory_demos_") for k in tensors)


def test_same_command_twice_gives_identical_errors(tmp_path):
    a = run_training(_smoke("si"), tmp_path / "a", threads=1, log=None)
    b = run_training(_smoke("si"), tmp_path / "b", threads=1, log=None)
    assert a["errors"] == b["errors"]


class _Killed(Exception):
    pass


def test_killed_run_resumes_after_last_finished_task(tmp_path):
    reference = run_training(_smoke("hn", tasks=3), tmp_path / "ref", threads=1, log=None)

    def kill_after_task_0(i):
        if i == 0:
            raise _Killed

    run_dir = tmp_path / "run"
    with pytest.raises(_Killed):
        run_training(_smoke("hn", tasks=3), run_dir, threads=1, log=None,
                     after_task=kill_after_task_0)
    partial = json.loads((run_dir / "results.json").read_text())
    assert partial["tasks_done"] == 1 and not partial["complete"]
    messages: list[str] = []
    trained: list[int] = []
    resumed = run_training(_smoke("hn", tasks=3), run_dir, threads=1, log=messages.append,
                           after_task=trained.append)
    assert trained == [1, 2]  # task 0 was not trained again
    assert any("resuming" in m for m in messages)
    assert not any("another CPU" in m for m in messages)  # resumed where it started
    assert resumed["errors"] == reference["errors"]
    assert resumed["train_time_s"][0] == partial["train_time_s"][0]
    assert resumed["train_cpu_s"][0] == partial["train_cpu_s"][0]


def test_a_run_resumed_on_another_cpu_says_so_and_records_where_each_task_was_learned(
        tmp_path, monkeypatch):
    """Seeds reproduce a run on one CPU only (kernels differ in rounding), so a run resumed
    on another CPU warns and records each task's CPU; one resumed on the same CPU does not."""
    import clfd_bench.harness.protocol as protocol

    real = protocol.cpu_provenance()
    run_training(_smoke("sg", tasks=1), tmp_path, threads=1, log=None)
    messages: list[str] = []
    other = {"model": "Other CPU", "torch_capability": "AVX2",
             "kernel_env": {"ATEN_CPU_CAPABILITY": "avx2"}}
    monkeypatch.setattr(protocol, "cpu_provenance", lambda: dict(other))
    results = run_training(_smoke("sg", tasks=2), tmp_path, threads=1, log=messages.append)
    assert results["provenance"]["cpu_by_task"] == [real, other]
    assert results["provenance"]["cpu"] == other
    warning = [m for m in messages if "another CPU" in m]
    assert len(warning) == 1 and real["model"] in warning[0]
    assert f"{real['torch_capability']} kernels" in warning[0]

    messages.clear()  # resumed again on the second CPU: task 0 still comes from the first
    results = run_training(_smoke("sg", tasks=3), tmp_path, threads=1, log=messages.append)
    warning = [m for m in messages if "another CPU" in m]
    assert len(warning) == 1 and real["model"] in warning[0] and "Other CPU" not in warning[0]
    assert results["provenance"]["cpu_by_task"] == [real, other, other]


def test_results_keep_other_keys_but_drop_execution_of_a_smaller_matrix(tmp_path):
    """A resumed run that learns one more task keeps keys other tools added, but not the
    execution fields of the smaller matrix (a reader would take them for the run's); the
    same run rewritten without learning more keeps its execution fields."""
    run = RunDir(tmp_path)
    run_training(_smoke("sg", tasks=1), tmp_path, threads=1, log=None)
    results = run.load_results()
    results["note"] = "added by a user"
    results["sim_accuracy"] = [[1.0]]
    results["sim"] = {"evaluated_tasks": 1}
    run.write_training_results(results)
    same = run_training(_smoke("sg", tasks=1), tmp_path, threads=1, log=None)
    assert same["sim_accuracy"] == [[1.0]] and same["note"] == "added by a user"
    again = run_training(_smoke("sg", tasks=2), tmp_path, threads=1, log=None)
    assert again["tasks_done"] == 2 and again["note"] == "added by a user"
    assert "sim_accuracy" not in again and "sim" not in again
    assert "sim_accuracy" not in run.load_results()


def test_other_config_in_the_same_directory_is_refused(tmp_path):
    run_training(_smoke("hn", tasks=1), tmp_path, threads=1, log=None)
    with pytest.raises(RunMismatchError, match="beta: 0.005 -> 0.1"):
        run_training(_smoke("hn", tasks=1, overrides=["beta=0.1"]), tmp_path, threads=1,
                     log=None)


def test_pose_run_joins_position_and_orientation(tmp_path):
    results = run_training(_smoke("ft", dataset="robotasks", tasks=1), tmp_path, threads=1,
                           log=None)
    assert set(results["num_params_by_part"]) == {"position", "orientation"}
    assert "quaternion" in results["errors"] and "quaternion" in results["accuracy"]
    pred = RunDir(tmp_path).load_predictions(0)[0]
    assert pred.shape == (9, 1000, 7)
    assert np.allclose(np.linalg.norm(pred[..., 3:], axis=-1), 1.0)


def test_cli_train_and_show_config(tmp_path, capsys):
    assert cli_main(["train", "--method", "hn", "--dataset", "helloworld", "--profile", "paper",
                     "--show-config"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["parts"]["position"]["iterations"] == 40000
    assert cli_main(["train", "--method", "hx", "--dataset", "helloworld", "--out",
                     str(tmp_path)]) == 2
    assert "valid methods: sg, ft, rep, si, mas, hn, chn" in capsys.readouterr().err
    assert cli_main(["train", "--method", "sg", "--dataset", "helloworld", "--profile",
                     "smoke", "--tasks", "1", "--threads", "1", "--no-sim", "--out",
                     str(tmp_path)]) == 0
    assert "task 1/1 'h'" in capsys.readouterr().out
