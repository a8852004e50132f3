"""Pretrained bundles: the shipped archive extracts into a results folder that loads like one
trained here (every method's run, tensors-only checkpoints, predictions), ``clfd-bench video``
renders from it without training; a tampered archive, an unknown name, an occupied output
folder and an archive with a member outside its folder are refused with a message saying what
to do, and leave nothing behind; the archive a folder makes is the same bytes every time."""

from __future__ import annotations

import io
import os
import shutil
import tarfile
from pathlib import Path

import imageio.v3 as iio
import pytest

from clfd_bench import pretrained
from clfd_bench.cli.main import main
from clfd_bench.execution.fingerprint import sim_fingerprint
from clfd_bench.execution.saved_run import load_run
from clfd_bench.harness.checkpoint import decode_checkpoint
from clfd_bench.io import sha256_file
from clfd_bench.pretrained import Bundle, PretrainedError
from clfd_bench.runs import RunDir, find_runs

NAME = "helloworld-fast"


@pytest.fixture(scope="module")
def hw(tmp_path_factory) -> Path:
    """The shipped HelloWorld bundle, extracted once."""
    return pretrained.get(NAME, tmp_path_factory.mktemp("pt") / "hw")


def _tiny(tmp_path: Path, members: dict[str, bytes] | None = None,
          name: str = "tiny", raw: bytes | None = None, monkeypatch=None) -> Bundle:
    """A registered bundle of a small archive in a stand-in package folder."""
    folder = tmp_path / "pkg"
    folder.mkdir(exist_ok=True)
    archive = folder / f"{name}.tar.xz"
    if raw is None:
        buf = io.BytesIO()
        with tarfile.open(fileobj=buf, mode="w:xz") as tar:
            for member, data in (members or {"leaderboard.md": b"# board\n"}).items():
                info = tarfile.TarInfo(member)
                info.size = len(data)
                tar.addfile(info, io.BytesIO(data))
        raw = buf.getvalue()
    archive.write_bytes(raw)
    bundle = Bundle(name=name, file=archive.name, sha256=sha256_file(archive),
                    description="test", dataset="helloworld", profile="smoke", methods=("sg",),
                    made_with_version="0", size=len(raw))
    monkeypatch.setitem(pretrained.BUNDLES, name, bundle)
    monkeypatch.setattr(pretrained, "resource_path", lambda _folder, file: folder / file)
    return bundle


def test_registered_archive_is_packaged_and_pinned():
    bundle = pretrained.lookup(NAME)
    path = pretrained.archive_path(bundle)
    assert path.is_file() and path.stat().st_size == bundle.size
    assert sha256_file(path) == bundle.sha256
    # Lossless float64 predictions after every task are most of it (they barely compress);
    # a guard against shipping more than the results folder (videos, logs of other runs).
    assert bundle.size < 25e6


def test_get_gives_a_results_folder_that_loads_like_a_trained_one(hw):
    for name in ("leaderboard.md", "leaderboard.csv", "leaderboard.json"):
        assert (hw / name).is_file()
    runs = {load_run(r.path).method: r for r in find_runs(hw)}
    assert sorted(runs) == sorted(pretrained.lookup(NAME).methods)
    for method, run in runs.items():
        saved = load_run(run.path)
        assert saved.dataset == "helloworld" and saved.complete, method
        assert len(run.load_predictions(saved.num_learned - 1)) == saved.num_learned
        header, tensors = decode_checkpoint(run.read_checkpoint(), str(run.checkpoint_path))
        assert tensors and header  # tensors and a JSON header: loaded weights_only
        assert (run.read_results() or {}).get("success") is not None  # executed
    assert not list(hw.parent.glob(".*"))  # no staging folder left


def test_video_renders_from_the_bundle_without_training(hw, tmp_path, capsys):
    run = pretrained.method_runs(hw)["hn"]
    code = main(["video", str(run), "--task", "h", "--out", str(tmp_path), "--fps", "4",
                 "--size", "128x72"])
    assert code == 0, capsys.readouterr().err
    (path,) = capsys.readouterr().out.split()
    # Named after the method too: every method's run folder is called fast_nodet_o0_s0.
    assert Path(path).name == "hn_fast_nodet_o0_s0_task0_h_demo0.mp4"
    assert iio.imread(path).shape[1:] == (72, 128, 3)


def test_stale_executions_are_named(hw):
    stale = pretrained.stale_runs(hw, fingerprint="feedfacefeedface")
    assert len(stale) == len(pretrained.lookup(NAME).methods)
    assert all("but this one is feedfacefeedface" in reason for _, reason in stale)


def test_cli_list_and_get(tmp_path, capsys, monkeypatch):
    assert main(["pretrained", "list"]) == 0
    listed = capsys.readouterr().out
    assert NAME in listed and pretrained.lookup(NAME).sha256 in listed
    _tiny(tmp_path, {"runs/x/results.json": b"{}", "leaderboard.md": b"#\n"},
          monkeypatch=monkeypatch)
    out = tmp_path / "got"
    assert main(["pretrained", "get", "tiny", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"results: {out}" in printed and "next:" in printed
    assert f"cat {out / 'leaderboard.md'}" in printed


def test_get_says_when_the_executions_are_another_simulators(tmp_path, capsys, monkeypatch):
    """Executions made by another simulator: tables, figures and videos still work, and
    `get` says which runs `clfd-bench evaluate` would re-execute (without training)."""
    monkeypatch.setattr("clfd_bench.execution.fingerprint.sim_fingerprint",
                        lambda: "feedfacefeedface")
    out = tmp_path / "hw"
    assert main(["pretrained", "get", NAME, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "note: the execution results of 7 run(s) were made by another simulator" in printed
    assert "`clfd-bench evaluate RUN_DIR` re-executes" in printed
    compare = next(line for line in printed.splitlines() if "--compare" in line).split()
    runs = [Path(p).parent.name for p in compare if p.endswith("fast_nodet_o0_s0")]
    assert runs == list(pretrained.lookup(NAME).methods)  # the leaderboard's order


def test_unknown_name_lists_the_valid_ones(capsys):
    with pytest.raises(PretrainedError, match=f"unknown pretrained bundle 'hw'; valid: .*{NAME}"):
        pretrained.get("hw", "unused")
    assert main(["pretrained", "get", "hw"]) == 2
    assert f"valid: {NAME}" in capsys.readouterr().err
    assert not Path("unused").exists() and not Path("results/hw").exists()


def test_tampered_archive_fails_its_checksum_and_leaves_nothing(tmp_path, monkeypatch):
    bundle = _tiny(tmp_path, monkeypatch=monkeypatch)
    archive = tmp_path / "pkg" / bundle.file
    data = bytearray(archive.read_bytes())
    data[len(data) // 2] ^= 0xFF
    archive.write_bytes(bytes(data))
    out = tmp_path / "out"
    with pytest.raises(PretrainedError) as err:
        pretrained.get("tiny", out)
    message = str(err.value)
    assert f"archive {archive} failed its checksum" in message
    assert f"expected {bundle.sha256}" in message
    assert "corrupt or was modified; reinstall clfd-bench" in message
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pkg"]


def test_no_overwrite_without_force(tmp_path, monkeypatch):
    _tiny(tmp_path, {"leaderboard.md": b"new\n"}, monkeypatch=monkeypatch)
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    with pytest.raises(PretrainedError, match="exists and is not empty; .* add --force"):
        pretrained.get("tiny", out)
    assert (out / "mine.txt").read_text() == "keep"
    assert pretrained.get("tiny", out, force=True) == out
    assert sorted(p.name for p in out.iterdir()) == ["leaderboard.md"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "pkg"]  # nothing aside left
    empty = tmp_path / "empty"
    empty.mkdir()
    assert (pretrained.get("tiny", empty) / "leaderboard.md").read_text() == "new\n"


@pytest.mark.parametrize("member", ["../evil.txt", "/tmp/evil.txt", "a/../../evil.txt"])
def test_member_outside_the_folder_is_refused(tmp_path, monkeypatch, member):
    _tiny(tmp_path, {"leaderboard.md": b"ok\n", member: b"pwned\n"}, monkeypatch=monkeypatch)
    out = tmp_path / "sub" / "out"
    with pytest.raises(PretrainedError, match="has a member outside its folder"):
        pretrained.get("tiny", out)
    assert not (tmp_path / "evil.txt").exists() and not (tmp_path / "sub" / "evil.txt").exists()
    assert list((tmp_path / "sub").iterdir()) == []


def test_links_are_refused(tmp_path, monkeypatch):
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:xz") as tar:
        link = tarfile.TarInfo("runs")
        link.type, link.linkname = tarfile.SYMTYPE, "/etc"
        tar.addfile(link)
    _tiny(tmp_path, raw=buf.getvalue(), monkeypatch=monkeypatch)
    with pytest.raises(PretrainedError, match="not a regular file or folder"):
        pretrained.get("tiny", tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_make_archive_is_deterministic(tmp_path):
    folder = tmp_path / "results"
    (folder / "runs" / "a").mkdir(parents=True)
    (folder / "runs" / "a" / "results.json").write_text("{}")
    (folder / "leaderboard.md").write_text("# b\n")
    (folder / ".lock").write_text("pid 1")
    first = pretrained.make_archive(folder, tmp_path / "one.tar.xz")
    os.utime(folder / "leaderboard.md", (1, 1))
    assert pretrained.make_archive(folder, tmp_path / "two.tar.xz") == first
    with tarfile.open(tmp_path / "one.tar.xz") as tar:
        assert tar.getnames() == ["leaderboard.md", "runs", "runs/a", "runs/a/results.json"]


def test_fingerprint_is_the_same_in_a_wheel_layout(tmp_path, monkeypatch):
    """An installed wheel keeps tasks/ and assets/ under clfd_bench/_share/: the simulator's
    fingerprint must not change with that, or every shipped execution would be stale."""
    from clfd_bench import resources

    before = sim_fingerprint()
    share = tmp_path / "clfd_bench" / "_share"
    for name in ("tasks", "assets"):
        shutil.copytree(resources.resource_root(name), share / name)
    real = resources.resource_root
    monkeypatch.setattr(resources, "resource_root",
                        lambda folder: share / folder if folder in ("tasks", "assets")
                        else real(folder))
    sim_fingerprint.cache_clear()
    try:
        assert sim_fingerprint() == before
    finally:
        monkeypatch.undo()
        sim_fingerprint.cache_clear()


def test_find_runs_and_portable_files(hw):
    run = RunDir(pretrained.method_runs(hw)["sg"])
    names = [p.relative_to(run.path).as_posix() for p in run.portable_files()]
    assert "results.json" in names and "checkpoint.pt" in names
    assert [n for n in names if n.startswith("predictions/")] == [
        f"predictions/after_task_{i}.npz" for i in range(7)]
    assert ".lock" not in names
