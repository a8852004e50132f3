"""clfd_bench.studies.profile_compare: two profiles' leaderboards side by side, by hand."""

import json

import pytest

from clfd_bench.cli.main import main
from clfd_bench.harness.validate import InputError
from clfd_bench.studies.profile_compare import (
    compare_profiles,
    markdown,
    read_comparison,
    write_comparison,
)


def _board(folder, dataset, seeds, rows):
    folder.mkdir(parents=True)
    meta = {"dataset": dataset, "seeds": seeds, "methods": list(rows), "profile": folder.name,
            "orders": [0], "node": "t", "tasks": None, "sim": True, "runs": {}, "figures": []}
    doc = {"schema_version": 1, "meta": meta, "paper": {},
           "rows": [{"rank": i, "method": m, "runs_ok": len(v["exec_ACC"]), "runs_failed": 0,
                     "paper_rank": None, "errors": [], "exec_failures": None,
                     "not_provided": [],
                     "metrics": {k: {"values": vals} for k, vals in v.items()}}
                    for i, (m, v) in enumerate(rows.items(), 1)]}
    (folder / "leaderboard.json").write_text(json.dumps(doc))
    return folder


@pytest.fixture
def folders(tmp_path):
    fast = _board(tmp_path / "fast", "helloworld", [0, 1, 2], {
        "hn": {"ACC": [1.0, 1.0, 1.0], "exec_ACC": [0.90, 0.94, 0.96],
               "train_cpu_s": [90.0, 100.0, 110.0]},
        "chn": {"ACC": [1.0, 1.0, 1.0], "exec_ACC": [0.60, 0.67, 0.28]},
    })
    full = _board(tmp_path / "full", "helloworld", [0], {
        "hn": {"ACC": [1.0], "exec_ACC": [0.97], "train_cpu_s": [3600.0]},
        "chn": {"ACC": [1.0], "exec_ACC": [0.95]},
        "sg": {"ACC": [1.0], "exec_ACC": [1.0]},
    })
    return {"fast": fast, "full": full}


def test_medians_gaps_and_marks(folders, tmp_path):
    cmp = compare_profiles(folders)
    assert cmp.methods == ("hn", "chn", "sg") and cmp.profiles == ("fast", "full")
    assert cmp.median("fast", "hn", "exec_ACC") == pytest.approx(0.94)
    assert cmp.exec_gap("hn", "fast") == pytest.approx(-0.03)   # within 0.05
    assert cmp.exec_gap("chn", "fast") == pytest.approx(-0.35)  # outside
    text = markdown(cmp)
    hn = next(line for line in text.splitlines() if line.startswith("| HN |"))
    chn = next(line for line in text.splitlines() if line.startswith("| CHN |"))
    sg = next(line for line in text.splitlines() if line.startswith("| SG |"))
    assert "0.94 [0.90–0.96]" in hn and "100 [90–110]" in hn and hn.endswith("| -0.03 |")
    assert chn.endswith("| -0.35 ✗ |")
    assert sg.endswith("| — |")  # no fast run: no gap
    md, js = write_comparison(cmp, tmp_path / "out")
    assert md.read_text() == text
    assert json.loads(js.read_text())["exec_gap"]["fast"]["sg"] is None
    assert markdown(read_comparison(tmp_path / "out")) == text
    assert read_comparison(tmp_path) is None


def test_other_datasets_or_one_folder_are_refused(folders, tmp_path):
    lasa = _board(tmp_path / "lasa", "lasa", [0], {"hn": {"exec_ACC": [1.0]}})
    with pytest.raises(InputError, match="different datasets"):
        compare_profiles({"fast": folders["fast"], "full": lasa})
    with pytest.raises(InputError, match="at least two"):
        compare_profiles({"fast": folders["fast"]})
    with pytest.raises(InputError, match="no leaderboard.json"):
        compare_profiles({"fast": folders["fast"], "full": tmp_path})


def test_cli_refuses_a_folder_without_label(folders, capsys):
    assert main(["paper", "profiles", f"fast={folders['fast']}", str(folders["full"])]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not LABEL=FOLDER" in err
    assert main(["paper", "profiles", f"fast={folders['fast']}", f"full={folders['full']}"]) == 0
    assert "| CHN |" in capsys.readouterr().out


def test_the_site_shows_a_written_comparison(folders, tmp_path):
    from clfd_bench.site import build_site

    results = folders["full"]
    index = build_site(results, tmp_path / "site0", videos=False).index.read_text()
    assert 'id="profiles-table"' not in index
    write_comparison(compare_profiles(folders), results)
    index = build_site(results, tmp_path / "site1", videos=False).index.read_text()
    assert 'id="profiles-table"' in index and "<td>-0.35 ✗</td>" in index
