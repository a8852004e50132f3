"""The grid commands' shared ending: a failed run makes the command fail and is named."""

from __future__ import annotations

import argparse
from types import SimpleNamespace

import pytest

from clfd_bench.cli.common import finish, ints, names


def _outcome(name: str, error: str) -> SimpleNamespace:
    return SimpleNamespace(spec=SimpleNamespace(name=name), ok=False, error=error, seconds=1.0)


def test_finish_fails_and_names_each_failed_run(tmp_path, capsys):
    table = tmp_path / "t.md"
    table.write_text("| method | ACC |\n")
    code = finish("study x", table, [table], [_outcome("lasa/ft/s0", "diverged at task 3")],
                  summary="1 run failed")
    out, err = capsys.readouterr()
    assert code == 1
    assert out.splitlines() == ["| method | ACC |", "", f"[study x] wrote {table}",
                                "1 run failed"]
    assert err.strip() == "[study x] FAILED lasa/ft/s0: diverged at task 3"


def test_finish_succeeds_with_no_failed_run(tmp_path, capsys):
    table = tmp_path / "t.md"
    table.write_text("table\n")
    assert finish("leaderboard", table, []) == 0
    assert capsys.readouterr().err == ""


def test_list_options():
    assert ints("0, 2,") == [0, 2]
    assert names("SG, hn,my.pkg:MyMethod") == ["sg", "hn", "my.pkg:MyMethod"]
    with pytest.raises(argparse.ArgumentTypeError, match="comma-separated integers.*'0,x'"):
        ints("0,x")
