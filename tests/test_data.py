"""The data layer: counts, units, quaternions, task orders, offline and checksum errors."""

from __future__ import annotations

import io
import json
import shutil
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from clfd_bench.cli.main import main
from clfd_bench.data import (
    TASK_ORDERS,
    ChecksumError,
    CorruptDatasetError,
    DatasetUnavailableError,
    list_datasets,
    load_dataset,
    sources,
)

EXPECTED = {
    # dataset: (tasks, demos, steps, dim)
    "lasa": (26, 7, 1000, 2),
    "helloworld": (7, 8, 1000, 2),
    "robotasks": (4, 9, 1000, 7),
    "robotasks9": (9, 9, 1000, 7),
}


@pytest.mark.parametrize("name", list(EXPECTED))
def test_counts_and_shapes(name):
    ds = load_dataset(name)
    n_tasks, n_demos, n_steps, dim = EXPECTED[name]
    assert len(ds) == n_tasks
    for task in ds:
        assert task.demos.shape == (n_demos, n_steps, dim)
        assert task.times.shape == (n_steps,)
        assert task.times[0] == 0.0 and np.all(np.diff(task.times) > 0)
        assert np.isfinite(task.demos).all()
        np.testing.assert_array_equal(task.demo_goals, task.demos[:, -1])


def test_lasa_comes_in_the_papers_order_0_without_multi_models():
    from clfd_bench.data.orders import TASK_ORDERS

    names = load_dataset("lasa").task_names
    assert not any(n.startswith("Multi_Models") for n in names)
    # The paper's appendix table, order 0: alphabetical ignoring case, except that the paper
    # lists JShape_2 before JShape.
    assert list(names) == list(TASK_ORDERS["lasa"][0])
    swapped = [n for n in names]
    k = swapped.index("JShape_2")
    swapped[k], swapped[k + 1] = swapped[k + 1], swapped[k]
    assert swapped == sorted(names, key=str.lower)
    assert names[:3] == ["Angle", "BendedLine", "CShape"] and names[-1] == "Zshape"
    task = load_dataset("lasa")[0]
    assert task.units == "lasa"
    np.testing.assert_allclose(task.goal, [0.0, 0.0], atol=1e-9)  # LASA ends at the origin
    assert task.dt == pytest.approx(0.002968502735264841)  # Angle.mat's dt
    assert 0 < task.sim_scale * np.ptp(task.demos[..., 0]) < 0.25  # fits on the table


def test_helloworld_converted_from_cm_to_m():
    task = load_dataset("helloworld")[0]
    raw = np.load(sources.fetch("robot_hello_world/processed_demos/h.npy"))
    np.testing.assert_allclose(task.demos, raw / 100.0)
    assert task.units == "m"
    # The letters lie in front of the robot, tens of centimetres out: metres, not cm.
    assert 0.3 < task.demos[..., 0].mean() < 0.5
    assert task.dt == pytest.approx(1 / 60)


def test_robotasks_positions_in_metres_quaternions_unit():
    for task in load_dataset("robotasks"):
        raw = np.load(sources.fetch(f"robottasks/pos_ori/{task.name}.npy"))
        np.testing.assert_allclose(task.positions, raw[..., :3] / 100.0)
        norms = np.linalg.norm(task.quaternions, axis=-1)
        np.testing.assert_allclose(norms, 1.0, atol=1e-12)
        assert task.positions.shape[-1] == 3 and task.quaternions.shape[-1] == 4
        # All demos end at one position; the goal quaternion is a unit average.
        np.testing.assert_allclose(task.demo_goals[:, :3] - task.goal[:3], 0.0, atol=1e-6)
        assert np.linalg.norm(task.goal[3:]) == pytest.approx(1.0)
        assert np.abs(task.positions).max() < 1.0  # within the Panda's reach, in metres


def test_arrays_are_read_only():
    task = load_dataset("helloworld")[0]
    with pytest.raises(ValueError):
        task.demos[0, 0, 0] = 1.0


@pytest.mark.parametrize(
    ("name", "order", "first", "last"),
    [
        ("lasa", 0, "Angle", "Zshape"),
        ("lasa", 1, "Spoon", "Trapezoid"),
        ("lasa", 2, "BendedLine", "Leaf_1"),
        ("helloworld", 0, "h", "d"),
        ("helloworld", 1, "l", "e"),
        ("helloworld", 2, "o", "r"),
        ("robotasks", 0, "openbox", "pouring"),
        ("robotasks", 1, "platestandingtolying", "pouring"),
        ("robotasks", 2, "pouring", "bottle2shelf"),
    ],
)
def test_task_orders_follow_the_papers_table(name, order, first, last):
    ds = load_dataset(name, order=order)
    assert ds.order == order
    assert ds.task_names[0] == first and ds.task_names[-1] == last
    assert ds.task_names == list(TASK_ORDERS[name][order])
    # Every order is a permutation of order 0, and the data follow the names.
    assert sorted(ds.task_names) == sorted(TASK_ORDERS[name][0])
    base = load_dataset(name, order=0)
    np.testing.assert_array_equal(ds[0].demos, base.task(first).demos)


def test_helloworld_order_1_matches_table():
    assert load_dataset("helloworld", 1).task_names == ["l", "d", "h", "o", "w", "r", "e"]


def test_robotasks9_follows_upstream_sequence():
    names = load_dataset("robotasks9").task_names
    assert names[:4] == list(TASK_ORDERS["robotasks"][0])
    assert names[4:] == ["matfolding", "obstaclerotate", "pan2stove", "scoop", "wineglass"]
    with pytest.raises(ValueError, match=r"task orders \[0\]"):
        load_dataset("robotasks9", order=1)


def test_unknown_dataset_lists_valid_names():
    with pytest.raises(KeyError, match="helloworld, robotasks"):
        load_dataset("hellowrld")
    assert list_datasets() == ["lasa", "helloworld", "robotasks", "robotasks9"]


def test_bad_order_is_a_clear_error():
    with pytest.raises(ValueError, match=r"task orders \[0, 1, 2\], not 3"):
        load_dataset("helloworld", order=3)


# --- where files come from -------------------------------------------------------------


HW_FILES = [f"robot_hello_world/processed_demos/{n}.npy" for n in "helowrd"]


@pytest.fixture
def hw_bytes():
    """The pinned HelloWorld files' bytes, read before any test changes the environment."""
    return {rel: sources.fetch(rel).read_bytes() for rel in HW_FILES}


@pytest.fixture
def empty_cache(tmp_path, monkeypatch, hw_bytes):
    """No CLFD_DATA_DIR, an empty cache: files must be downloaded."""
    monkeypatch.delenv("CLFD_DATA_DIR", raising=False)
    monkeypatch.setenv("CLFD_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _raise_offline(*args, **kwargs):
    raise urllib.error.URLError("[Errno -3] Temporary failure in name resolution")


def test_offline_without_local_copy_is_one_clear_error(empty_cache, monkeypatch):
    monkeypatch.setattr(urllib.request, "urlopen", _raise_offline)
    with pytest.raises(DatasetUnavailableError) as info:
        load_dataset("helloworld")
    message = str(info.value)
    assert "'helloworld'" in message
    assert "https://raw.githubusercontent.com/sayantanauddy/clfd/" in message
    assert "CLFD_DATA_DIR" in message
    assert not any(empty_cache.rglob("*.npy"))


class _FakeResponse(io.BytesIO):
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def _serve(files: dict[str, bytes]):
    def urlopen(url, timeout=None):
        for rel, payload in files.items():
            if url.endswith(rel.split("/", 1)[1]) or url.endswith(rel):
                return _FakeResponse(payload)
        raise urllib.error.HTTPError(url, 404, "not found", None, None)

    return urlopen


def test_download_lands_in_cache_checked(empty_cache, monkeypatch, hw_bytes):
    monkeypatch.setattr(urllib.request, "urlopen", _serve(hw_bytes))
    ds = load_dataset("helloworld")
    assert len(ds) == 7
    cached = sorted(p.name for p in empty_cache.rglob("*.npy"))
    assert cached == sorted(f"{n}.npy" for n in "helowrd")
    assert not [p for p in empty_cache.rglob("*") if p.name.endswith(".tmp")]
    # Second load: everything from the cache, no network.
    monkeypatch.setattr(urllib.request, "urlopen", _raise_offline)
    np.testing.assert_array_equal(load_dataset("helloworld")[0].demos, ds[0].demos)


def test_corrupt_download_never_stays_in_cache(empty_cache, monkeypatch, hw_bytes):
    rel = "robot_hello_world/processed_demos/h.npy"
    payload = bytearray(hw_bytes[rel])
    payload[-1] ^= 0xFF
    monkeypatch.setattr(urllib.request, "urlopen", _serve({rel: bytes(payload)}))
    with pytest.raises(ChecksumError, match="h.npy.*failed its checksum.*nothing was saved"):
        load_dataset("helloworld")
    assert not [p for p in empty_cache.rglob("*") if p.is_file()]


@pytest.fixture
def local_copy(tmp_path, monkeypatch):
    """A writable copy of the HelloWorld and RoboTasks files, used through CLFD_DATA_DIR."""
    root = tmp_path / "datasets"
    for rel in sources.FILES:
        if rel.startswith(("robot_hello_world", "robottasks/")):
            target = root / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(sources.fetch(rel), target)
    monkeypatch.setenv("CLFD_DATA_DIR", str(root))
    return root


def test_local_copy_with_bad_checksum_names_the_file(local_copy, monkeypatch):
    monkeypatch.setattr(urllib.request, "urlopen", _raise_offline)  # never downloads
    target = local_copy / "robottasks/pos_ori/pouring.npy"
    data = bytearray(target.read_bytes())
    data[200] ^= 0x01
    target.write_bytes(bytes(data))
    with pytest.raises(ChecksumError) as info:
        load_dataset("robotasks")
    assert str(target) in str(info.value)
    assert "delete it" in str(info.value) and "CLFD_DATA_DIR" in str(info.value)


def test_local_copy_missing_file_is_not_downloaded(local_copy, monkeypatch):
    monkeypatch.setattr(urllib.request, "urlopen", _raise_offline)
    (local_copy / "robot_hello_world/processed_demos/w.npy").unlink()
    with pytest.raises(DatasetUnavailableError, match="CLFD_DATA_DIR=.*has no file.*w.npy"):
        load_dataset("helloworld")


def test_file_that_is_not_an_array_is_a_clear_error(tmp_path, monkeypatch):
    bad = tmp_path / "bad.npy"
    bad.write_bytes(b"definitely not numpy")
    from clfd_bench.data.loaders import _load_npy

    with pytest.raises(CorruptDatasetError, match="bad.npy cannot be read"):
        _load_npy(bad, (2,))


# --- the data command --------------------------------------------------------------------


def test_data_command_json_lists_the_four_datasets(capsys):
    assert main(["data", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == ["lasa", "helloworld", "robotasks", "robotasks9"]
    for row in rows:
        n_tasks, n_demos, n_steps, dim = EXPECTED[row["name"]]
        assert row["num_tasks"] == n_tasks and len(row["tasks"]) == n_tasks
        assert {(t["num_demos"], t["num_steps"], t["dim"]) for t in row["tasks"]} == {
            (n_demos, n_steps, dim)
        }
        assert Path(row["source"]).is_dir()


def test_data_command_reports_unavailable_dataset(capsys, empty_cache, monkeypatch):
    monkeypatch.setattr(urllib.request, "urlopen", _raise_offline)
    assert main(["data", "helloworld"]) == 1
    out = capsys.readouterr().out
    assert "helloworld: NOT AVAILABLE" in out and "CLFD_DATA_DIR" in out
