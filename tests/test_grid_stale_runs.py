"""A grid never drops a run in silence: a run whose executions were made by a simulator that
has changed since (its files were edited while the grid ran) is a failure of the grid, with
the reason, and the exit code says so; the next call re-executes it."""

from __future__ import annotations

import json

from clfd_bench.cli.main import main
from clfd_bench.execution.fingerprint import sim_fingerprint
from clfd_bench.leaderboard.grid import RunSpec

ARGS = ["leaderboard", "--dataset", "helloworld", "--methods", "sg", "--profile", "smoke",
        "--seeds", "0", "--tasks", "1", "--workers", "1"]
SPEC = RunSpec("helloworld", "sg", "smoke", 0, 0, "t", 1, True)
EDITED = "feedfacefeedface"


class _EditedSimulator:
    """The parent process's view after a simulator file was edited mid-grid: the grid's
    workers (child processes) executed with the files as they were, the grid reads them now."""

    def __call__(self) -> str:
        return EDITED

    def cache_clear(self) -> None:
        pass


def test_runs_executed_by_a_changed_simulator_fail_the_grid_then_resume(
        tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("clfd_bench.execution.fingerprint.sim_fingerprint", _EditedSimulator())
    code = main([*ARGS, "--out", str(tmp_path)])
    captured = capsys.readouterr()
    assert code == 1
    assert f"FAILED {SPEC.name}: ended but does not count: executed by simulator" in captured.err
    assert f"but this one is {EDITED}" in captured.err
    assert json.loads((tmp_path / "leaderboard.json").read_text())["meta"]["runs"] == {
        SPEC.name: "failed"}
    failed_runs = (tmp_path / "leaderboard.md").read_text().split("## Failed runs")[1]
    assert "ended but does not count: executed by simulator" in failed_runs

    # The run as an older simulator version left it; the grid, with the simulator as it is
    # on disk, executes its predictions again and does not train it again.
    monkeypatch.undo()
    results = SPEC.run_dir(tmp_path) / "results.json"
    doc = json.loads(results.read_text())
    doc["sim"]["fingerprint"] = "0123456789abcdef"
    results.write_text(json.dumps(doc))
    trained = doc["train_time_s"]
    code = main([*ARGS, "--out", str(tmp_path)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "1 run: 0 trained now, 1 executed again (trained before), 0 already done" in (
        captured.out + captured.err)
    done = json.loads(results.read_text())
    assert done["sim"]["fingerprint"] == sim_fingerprint()
    assert done["train_time_s"] == trained


def test_collect_reads_the_simulator_files_again(tmp_path, monkeypatch):
    """The fingerprint is cached per process; collecting a grid's runs hashes the simulator's
    files again, so a file edited after the first status check is seen."""
    from clfd_bench.leaderboard.runner import collect
    from clfd_bench.runs import RunDir

    source = tmp_path / "sim_source.py"
    source.write_text("version 1")
    monkeypatch.setattr("clfd_bench.execution.fingerprint._sim_files",
                        lambda: iter([("sim_source.py", source)]))
    sim_fingerprint.cache_clear()
    try:
        grid = tmp_path / "grid"
        run = RunDir(SPEC.run_dir(grid))
        run.write_training_results({"tasks_done": 1, "complete": True,
                                    "errors": {"dtw": [[1.0]]}})
        run.write_sim_results({"success": [[[True]]], "sim_accuracy": [[1.0]],
                               "sim_cl_metrics": {"ACC": 1.0},
                               "sim": {"evaluated_tasks": 1, "fingerprint": sim_fingerprint()}})
        assert collect([SPEC], grid)[0].status == "done"
        source.write_text("version 2")  # edited while the grid ran
        record = collect([SPEC], grid)[0]
        assert record.status == "partial"
        assert "executed by simulator" in record.error and "files changed since" in record.error
    finally:
        sim_fingerprint.cache_clear()
