"""eval/full_keep.py: the `full` runs outlive their machine as archives without checkpoints.
A finished run is archived and restored file for file (its checkpoint left out) and counts as
done again; an unfinished one is not kept; a tampered archive is refused and restores
nothing; an existing run directory is never replaced; a kept run another simulator executed
is executed again on restore (without a checkpoint the grid would train it from the start)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from clfd_bench import pretrained
from clfd_bench.harness.checkpoint import decode_checkpoint, encode_checkpoint
from clfd_bench.pretrained import PretrainedError
from clfd_bench.runs import RunDir, find_runs

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def keep_mod(eval_script):
    return eval_script("full_keep")


@pytest.fixture()
def out(tmp_path, keep_mod, monkeypatch) -> Path:
    """OUT with two runs of the shipped bundle laid out as eval/full_runs.sh does: HN's (done
    under the bundle's own simulator, which stands in for the current one) and SG's with
    its results marked unfinished."""
    bundle = pretrained.get("helloworld-fast", tmp_path / "bundle")
    runs = {r.path.parent.name: r for r in find_runs(bundle)}
    out = tmp_path / "out"
    for method in ("hn", "sg"):
        src = runs[method].path
        shutil.copytree(src, out / "helloworld" / src.relative_to(bundle))
    sg = RunDir(next(p for p in find_runs(out) if p.path.parent.name == "sg").path)
    results = json.loads(sg.results_path.read_text())
    results["complete"] = False
    sg.results_path.write_text(json.dumps(results))
    fingerprint = runs["hn"].read_results()["sim"]["fingerprint"]
    monkeypatch.setattr(keep_mod, "sim_fingerprint", lambda: fingerprint)
    return out


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in folder.rglob("*") if p.is_file() and not p.name.startswith(".")}


def test_finished_runs_come_back_without_their_checkpoint(out, keep_mod, tmp_path):
    keep = tmp_path / "keep"
    keep.mkdir()
    assert keep_mod.save(out, keep) == 1  # HN's; SG's is unfinished
    manifest = json.loads((keep / "MANIFEST.json").read_text())
    (key,) = manifest
    assert "/hn/" in key and key.startswith("helloworld/runs/helloworld/")
    assert keep_mod.save(out, keep) == 0  # already kept

    fresh = tmp_path / "fresh"
    assert keep_mod.restore(keep, fresh, refresh=_no_refresh) == 1
    before, after = _files(out / key), _files(fresh / key)
    assert "checkpoint.pt" in before and "checkpoint.pt" not in after
    before.pop("checkpoint.pt")
    assert after == before  # every other file, byte for byte
    run = RunDir(fresh / key)
    tasks = run.read_results()["tasks_done"]
    assert tasks == 7
    assert run.status(tasks, sim=True, fingerprint=keep_mod.sim_fingerprint()).state == "done"
    assert keep_mod.restore(keep, fresh, refresh=_no_refresh) == 0  # left as it is


def _no_refresh(path):
    raise AssertionError(f"{path} was executed by this simulator: nothing to execute again")


def test_a_run_of_another_simulator_is_executed_again_not_trained(out, keep_mod, tmp_path,
                                                                  monkeypatch):
    keep = tmp_path / "keep"
    keep.mkdir()
    keep_mod.save(out, keep)
    (key,) = json.loads((keep / "MANIFEST.json").read_text())
    monkeypatch.setattr(keep_mod, "sim_fingerprint", lambda: "another-simulator")
    refreshed = []
    fresh = tmp_path / "fresh"
    assert keep_mod.restore(keep, fresh, refresh=refreshed.append) == 1
    assert refreshed == [fresh / key]
    keep_mod.restore(keep, fresh, refresh=refreshed.append)  # still stale: again, not skipped
    assert refreshed == [fresh / key, fresh / key]
    assert keep_mod.save(fresh, keep) == 0  # not executed by this simulator: kept as it was


def test_a_kept_run_executed_again_is_archived_again(out, keep_mod, tmp_path, monkeypatch):
    """Restored under another simulator and executed again, the run is archived again with
    that simulator's results, so the next restore executes nothing; its training is as kept."""
    keep = tmp_path / "keep"
    keep.mkdir()
    keep_mod.save(out, keep)
    (key,) = manifest = json.loads((keep / "MANIFEST.json").read_text())
    monkeypatch.setattr(keep_mod, "sim_fingerprint", lambda: "another-simulator")

    def executed_again(path: Path) -> None:  # what evaluate_run leaves: this simulator's mark
        results = json.loads((path / "results.json").read_text())
        results["sim"]["fingerprint"] = "another-simulator"
        (path / "results.json").write_text(json.dumps(results))

    fresh = tmp_path / "fresh"
    keep_mod.restore(keep, fresh, refresh=executed_again)
    assert keep_mod.save(fresh, keep) == 1
    again = json.loads((keep / "MANIFEST.json").read_text())[key]
    assert again["simulator"] == "another-simulator" != manifest[key]["simulator"]
    assert (again["tasks"], again["train_cpu_s"]) == (manifest[key]["tasks"],
                                                       manifest[key]["train_cpu_s"])
    refreshed = []
    keep_mod.restore(keep, tmp_path / "third", refresh=refreshed.append)
    assert refreshed == []
    assert keep_mod.save(fresh, keep) == 0  # current: nothing to do


def test_a_tampered_archive_restores_nothing(out, keep_mod, tmp_path):
    keep = tmp_path / "keep"
    keep.mkdir()
    keep_mod.save(out, keep)
    (key,) = json.loads((keep / "MANIFEST.json").read_text())
    archive = keep / f"{key}.tar.xz"
    archive.write_bytes(archive.read_bytes()[:-10])
    fresh = tmp_path / "fresh"
    with pytest.raises(PretrainedError, match="git checkout"):
        keep_mod.restore(keep, fresh, refresh=_no_refresh)
    assert not (fresh / key).exists()


def test_every_kept_run_of_the_repository_is_in_it():
    """Each run docs/studies/full-runs/MANIFEST.json names has its archive in the checkout,
    with the recorded sha256 (a fresh clone restores them all; a .gitignore rule once kept
    the archives out of the repository while the manifest named them)."""
    import hashlib

    keep = ROOT / "docs" / "studies" / "full-runs"
    manifest = json.loads((keep / "MANIFEST.json").read_text(encoding="utf-8"))
    assert manifest, "no kept run named"
    for key, entry in manifest.items():
        archive = keep / f"{key}.tar.xz"
        assert archive.is_file(), f"{archive} is named in MANIFEST.json but not in the checkout"
        assert hashlib.sha256(archive.read_bytes()).hexdigest() == entry["sha256"], key


def test_an_unfinished_run_is_kept_with_its_checkpoint_until_it_finishes(out, keep_mod,
                                                                         tmp_path):
    """--partial: SG's unfinished run comes back with its checkpoint, byte for byte (what its
    resume reads), is not executed on restore (the grid resumes it), is not archived twice at
    the same task, and once finished is archived again without the checkpoint."""
    keep = tmp_path / "keep"
    keep.mkdir()
    assert keep_mod.save(out, keep, partial=True) == 2  # HN's finished run, SG's unfinished
    manifest = json.loads((keep / "MANIFEST.json").read_text())
    (sg_key,) = [k for k in manifest if "/sg/" in k]
    assert manifest[sg_key]["partial"] is True and manifest[sg_key]["tasks"] == 7
    assert "partial" not in next(v for k, v in manifest.items() if k != sg_key)
    assert keep_mod.save(out, keep, partial=True) == 0  # nothing learned since

    fresh = tmp_path / "fresh"
    assert keep_mod.restore(keep, fresh, refresh=_no_refresh) == 2
    assert _files(fresh / sg_key) == _files(out / sg_key)  # checkpoint.pt included
    run = RunDir(fresh / sg_key)
    assert run.status(7, sim=True, fingerprint=keep_mod.sim_fingerprint()).state == "partial"
    keep_mod.restore(keep, fresh, refresh=_no_refresh)  # present: left alone, not executed

    results = json.loads(run.results_path.read_text())  # the resumed run finishes
    results["complete"] = True
    run.results_path.write_text(json.dumps(results))
    assert keep_mod.save(fresh, keep) == 1
    done = json.loads((keep / "MANIFEST.json").read_text())[sg_key]
    assert "partial" not in done
    third = tmp_path / "third"
    keep_mod.restore(keep, third, refresh=_no_refresh)
    assert "checkpoint.pt" not in _files(third / sg_key)


def test_a_checkpoint_over_the_cap_is_not_kept(out, keep_mod, tmp_path, capsys):
    keep = tmp_path / "keep"
    keep.mkdir()
    assert keep_mod.save(out, keep, partial=True, max_mb=0.001) == 1  # HN's finished run only
    assert not any("/sg/" in k for k in json.loads((keep / "MANIFEST.json").read_text()))
    assert "> --max-mb 0.001" in capsys.readouterr().out


def _one_task_behind(checkpoint: Path) -> None:
    """Rewrites ``checkpoint`` as if it were written one task before its results (the state
    a run's files are in for an instant: its checkpoint and results.json are two writes)."""
    header, tensors = decode_checkpoint(checkpoint.read_bytes())
    header["state"]["train_time_s"] = header["state"]["train_time_s"][:-1]
    checkpoint.write_bytes(encode_checkpoint(header, tensors))


def test_a_training_run_caught_between_two_writes_is_copied_again(out, keep_mod, tmp_path,
                                                                  monkeypatch):
    """--partial on a run that is training: a copy whose checkpoint and results.json describe
    different tasks is not archived; the run is copied again and the agreeing copy kept."""
    keep = tmp_path / "keep"
    keep.mkdir()
    copies = []

    def racing_copy(source, staging, left_out):
        keep_mod.shutil.copytree(source, staging,
                                 ignore=keep_mod.shutil.ignore_patterns(*left_out))
        if "/sg/" in source.as_posix():
            copies.append(source)
            if len(copies) == 1:
                _one_task_behind(staging / "checkpoint.pt")

    monkeypatch.setattr(keep_mod, "_copy_run", racing_copy)
    assert keep_mod.save(out, keep, partial=True) == 2
    assert len(copies) == 2  # SG's disagreeing copy, then the one kept
    (sg_key,) = [k for k in json.loads((keep / "MANIFEST.json").read_text()) if "/sg/" in k]
    fresh = tmp_path / "fresh"
    keep_mod.restore(keep, fresh, refresh=_no_refresh)
    assert _files(fresh / sg_key) == _files(out / sg_key)


def test_a_run_whose_files_never_agree_is_not_kept(out, keep_mod, tmp_path, capsys):
    keep = tmp_path / "keep"
    keep.mkdir()
    (sg,) = [r for r in find_runs(out) if r.path.parent.name == "sg"]
    _one_task_behind(sg.checkpoint_path)
    assert keep_mod.save(out, keep, partial=True) == 1  # HN's finished run only
    assert not any("/sg/" in k for k in json.loads((keep / "MANIFEST.json").read_text()))
    assert "not kept this time" in capsys.readouterr().out
