"""The run directory owner (`clfd_bench.runs`): status, merges, locks, leftovers of killed
writes, the Ray executor's tarballs and directory swap."""

from __future__ import annotations

import io
import tarfile

import numpy as np
import pytest

from clfd_bench.runs import LOCK_FILE, RunDir, RunFileError, RunLockedError, exclusive


def _training(tasks_done: int, complete: bool = True) -> dict:
    return {"tasks_done": tasks_done, "complete": complete, "errors": {"dtw": [[1.0]]}}


def _sim(tasks: int, fingerprint: str = "f1") -> dict:
    return {"success": [[[True]] * tasks] * tasks, "sim_accuracy": [[1.0]],
            "sim_cl_metrics": {"ACC": 1.0},
            "sim": {"evaluated_tasks": tasks, "fingerprint": fingerprint}}


def test_status_needs_every_stage_of_every_task(tmp_path):
    run = RunDir(tmp_path / "run")
    assert run.status(2, sim=True).state == "missing"
    run.write_training_results(_training(1, complete=False))
    st = run.status(2, sim=True)
    assert (st.state, st.trained, st.reason) == ("partial", 1, "trained 1/2 tasks")
    run.write_task_snapshot(b"task 1, mid-way")  # what the status says, not what it holds
    assert run.status(2, sim=True).reason == ("trained 1/2 tasks (task 1 resumes from its "
                                              "snapshot)")
    note = {"task": 1, "task_name": "e", "parts": {"position": "learned",
                                                    "orientation": "iteration 758"},
            "cpu_s": 2185.9}
    run.write_task_snapshot(b"task 1, mid-way", note)  # its note says how far it is
    assert run.status(2, sim=True).reason == (
        "trained 1/2 tasks (task 1 'e' resumes from its snapshot: position learned, "
        "orientation iteration 758, 36 min of CPU in the task)")
    run.write_task_snapshot(b"task 0, of an older run", note | {"task": 0})  # not this task's
    assert run.status(2, sim=True).reason.endswith("(task 1 resumes from its snapshot)")
    run.clear_task_snapshot()
    assert run.task_snapshot_note() is None and not (run.path / "task_snapshot.json").exists()
    run.write_training_results(_training(2))
    st = run.status(2, sim=True)
    assert st.state == "partial" and st.reason == "executed 0/2 tasks in simulation"
    assert run.status(2, sim=False).state == "done"
    run.write_sim_results(_sim(1))  # execution of a smaller matrix does not count
    assert run.status(2, sim=True).state == "partial"
    run.write_sim_results(_sim(2))
    assert run.status(2, sim=True).state == "done"
    assert run.status(2, sim=True, fingerprint="f1").state == "done"
    st = run.status(2, sim=True, fingerprint="f2")  # executed by another simulator
    assert st.state == "partial" and st.executed == 0
    assert "executed by simulator f1, but this one is f2" in st.reason  # says why, not "0/2"
    run.mark_failed({"error": "boom"})
    assert run.status(2, sim=True, fingerprint="f2").state == "failed"
    assert run.failure()["error"] == "boom"


def test_training_drops_execution_of_another_task_count_and_keeps_other_keys(tmp_path):
    run = RunDir(tmp_path)
    run.write_training_results(_training(1))
    run.write_sim_results(_sim(1))
    doc = run.load_results()
    doc["note"] = "kept"
    run.write_training_results({k: v for k, v in doc.items()
                                if k not in ("success", "sim_accuracy", "sim_cl_metrics", "sim")})
    assert run.load_results()["sim"]["evaluated_tasks"] == 1  # same task count: kept
    run.write_training_results(_training(2))
    doc = run.load_results()
    assert doc["note"] == "kept" and "success" not in doc and "sim" not in doc
    with pytest.raises(ValueError, match="not execution fields"):
        run.write_sim_results({"errors": {}})


def test_unreadable_files_say_what_to_do(tmp_path):
    run = RunDir(tmp_path)
    run.results_path.write_text("{truncated")
    with pytest.raises(RunFileError, match="clfd-bench train"):
        run.read_results()
    assert run.status(1, sim=False).state == "partial"
    run.predictions_path(0).parent.mkdir()
    run.predictions_path(0).write_bytes(b"PK\x03\x04 not a zip")
    with pytest.raises(RunFileError, match="unreadable"):
        run.load_predictions(0)
    with pytest.raises(FileNotFoundError, match="re-run `clfd-bench train`"):
        run.load_predictions(1)


def test_lock_refuses_a_second_holder_and_cleans_leftovers(tmp_path):
    run = RunDir(tmp_path / "run")
    run.path.mkdir()
    leftover = run.path / ".results.json.abc123.tmp"
    leftover.write_text("half a file")
    with run.lock("first holder"):
        assert not leftover.exists()  # a killed write's temporary file
        with pytest.raises(RunLockedError, match="first holder"):
            with exclusive(run.path, "second"):
                pass
    with run.lock("again"):  # released on exit
        pass


def test_a_lock_that_wrote_nothing_leaves_no_folder(tmp_path):
    target = tmp_path / "new" / "run"
    with pytest.raises(RuntimeError):
        with exclusive(target, "diverges at once"):
            raise RuntimeError("first task diverged")
    assert not target.exists()
    with exclusive(target, "writes"):
        (target / "results.json").write_text("{}")
    assert sorted(p.name for p in target.iterdir()) == [LOCK_FILE, "results.json"]


def test_replace_with_swaps_and_recovers_a_killed_swap(tmp_path):
    run = RunDir(tmp_path / "run")
    run.path.mkdir()
    (run.path / "old").write_text("old")
    staging = tmp_path / ".incoming"
    staging.mkdir()
    (staging / "new").write_text("new")
    run.replace_with(staging)
    assert [p.name for p in run.path.iterdir()] == ["new"] and not staging.exists()
    # A swap killed after the old version was moved aside: the next swap restores it first.
    aside = run.path.with_name(f".{run.path.name}.replaced")
    run.path.rename(aside)
    staging.mkdir()
    (staging / "newer").write_text("newer")
    run.replace_with(staging)
    assert [p.name for p in run.path.iterdir()] == ["newer"] and not aside.exists()


def _tarball(member: tarfile.TarInfo, data: bytes = b"") -> bytes:
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz") as tar:
        tar.addfile(member, io.BytesIO(data) if data else None)
    return buf.getvalue()


@pytest.mark.parametrize("kind", ["parent", "absolute", "symlink", "device"])
def test_ray_tarballs_refuse_unsafe_members(tmp_path, kind):
    from clfd_bench.leaderboard.executors import _unpack

    if kind == "parent":
        member = tarfile.TarInfo("../escaped.txt")
        member.size = 1
    elif kind == "absolute":
        member = tarfile.TarInfo(str(tmp_path / "abs.txt"))
        member.size = 1
    elif kind == "symlink":
        member = tarfile.TarInfo("link")
        member.type, member.linkname = tarfile.SYMTYPE, "/etc/passwd"
    else:
        member = tarfile.TarInfo("dev")
        member.type = tarfile.CHRTYPE
    payload = _tarball(member, b"x" if member.size else b"")
    target = tmp_path / "run"
    with pytest.raises(ValueError, match="unsafe member"):
        _unpack(payload, target)
    assert not (tmp_path / "escaped.txt").exists() and not (tmp_path / "abs.txt").exists()
    assert not any(target.iterdir())


def test_ray_tarballs_of_a_run_round_trip(tmp_path):
    from clfd_bench.leaderboard.executors import _pack, _unpack

    src = RunDir(tmp_path / "src")
    src.write_training_results(_training(1))
    src.save_predictions(0, [np.zeros((2, 3, 2))])
    _unpack(_pack(src.path), tmp_path / "dst")
    dst = RunDir(tmp_path / "dst")
    assert dst.load_results() == src.load_results()
    assert dst.load_predictions(0)[0].shape == (2, 3, 2)
