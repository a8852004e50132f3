"""The settings file: the data and the robot model are found without exports, an export wins,
and a command that will execute checks the robot model before it trains or writes anything."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from clfd_bench.harness.validate import InputError, check_robot_model
from clfd_bench.settings import read_settings, write_settings


def _env(settings: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("CLFD_DATA_DIR", "MENAGERIE_ROOT")}
    env["CLFD_SETTINGS_FILE"] = str(settings)
    env.update(extra)
    return env


_PRINT = "import os, clfd_bench; print(os.environ.get('CLFD_DATA_DIR'), " \
         "os.environ.get('MENAGERIE_ROOT'))"


def test_a_new_shell_finds_the_written_values_and_an_export_wins(tmp_path):
    settings = tmp_path / "clfd-bench.toml"
    write_settings({"CLFD_DATA_DIR": "/data/here", "MENAGERIE_ROOT": "/robot/there"}, settings)
    out = subprocess.run([sys.executable, "-c", _PRINT], env=_env(settings),
                         capture_output=True, text=True, check=True).stdout.split()
    assert out == ["/data/here", "/robot/there"]
    out = subprocess.run([sys.executable, "-c", _PRINT],
                         env=_env(settings, CLFD_DATA_DIR="/exported"),
                         capture_output=True, text=True, check=True).stdout.split()
    assert out == ["/exported", "/robot/there"]


def test_write_merges_removes_and_refuses_unknown_keys(tmp_path):
    settings = tmp_path / "s.toml"
    write_settings({"CLFD_DATA_DIR": 'C:\\odd "path"'}, settings)
    write_settings({"MENAGERIE_ROOT": "/m"}, settings)
    assert read_settings(settings) == {"CLFD_DATA_DIR": 'C:\\odd "path"', "MENAGERIE_ROOT": "/m"}
    write_settings({"CLFD_DATA_DIR": ""}, settings)
    assert read_settings(settings) == {"MENAGERIE_ROOT": "/m"}
    with pytest.raises(ValueError, match="valid: CLFD_DATA_DIR, MENAGERIE_ROOT"):
        write_settings({"CLFD_DATA": "/x"}, settings)
    settings.write_text("MENAGERIE_ROOT = [1]\n")
    with pytest.raises(ValueError, match="non-string"):
        read_settings(settings)


def test_a_broken_settings_file_does_not_break_the_import(tmp_path):
    settings = tmp_path / "s.toml"
    settings.write_text("not = toml = at all\n")
    res = subprocess.run([sys.executable, "-c", _PRINT], env=_env(settings),
                         capture_output=True, text=True)
    assert res.returncode == 0
    assert "is not valid TOML" in res.stderr and str(settings) in res.stderr


def test_train_refuses_a_wrong_menagerie_root_before_any_work(tmp_path):
    out = tmp_path / "run"
    res = subprocess.run(
        [sys.executable, "-m", "clfd_bench.cli.main", "train", "--method", "sg", "--dataset",
         "helloworld", "--profile", "smoke", "--tasks", "1", "--out", str(out)],
        env=_env(tmp_path / "none.toml", MENAGERIE_ROOT=str(tmp_path),
                 CLFD_DATA_DIR=os.environ.get("CLFD_DATA_DIR", "")),
        capture_output=True, text=True, timeout=300,
    )
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "MENAGERIE_ROOT=" in lines[0] and lines[0].startswith(
        "clfd-bench train: error:"), res.stderr
    assert not out.exists()


def test_no_model_and_no_download_names_the_variable(monkeypatch):
    import clfd_bench.sim.robot as robot

    def offline():
        raise OSError("https://github.com/...: Name or service not known")

    monkeypatch.delenv("MENAGERIE_ROOT", raising=False)
    monkeypatch.setattr(robot, "menagerie_dir", offline)
    with pytest.raises(InputError, match="set MENAGERIE_ROOT to a local MuJoCo Menagerie copy"):
        check_robot_model()
