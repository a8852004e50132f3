"""Time per task of the hypernetwork regularisers: medians and ratios on hand-made runs, the
study's grid (one run per method x mode, labelled apart), refusals before any training, and
an end-to-end smoke study."""

from __future__ import annotations

import json

import pytest

from clfd_bench.cli.main import main
from clfd_bench.leaderboard.aggregate import RunRecord
from clfd_bench.studies.task_time import study_specs, summarize, write_outputs


def _record(label_spec, times, status="done"):
    return RunRecord(label_spec, status, {"train_time_s": times} if status == "done" else None)


def test_medians_and_ratios_by_hand(tmp_path):
    specs = study_specs("lasa", ["hn"], ["all", "sampled"], "fast", [0, 1])
    all0, all1, smp0, smp1 = specs
    assert [s.label for s in specs] == ["hn all", "hn all", "hn sampled", "hn sampled"]
    assert all0.overrides == (("hnet_reg", "all"),) and all0.name != smp0.name
    records = [
        _record(all0, [10.0, 12.0, 14.0, 16.0]),
        _record(all1, [10.0, 14.0, 14.0, 20.0, 99.0]),  # one task more: cut to 4
        _record(smp0, [10.0, 11.0, 11.0, 11.0]),
        _record(smp1, [], "failed"),
    ]
    rows = summarize(records, ["hn all", "hn sampled", "chn all"])
    a, s, missing = rows
    assert a.per_task == [10.0, 13.0, 14.0, 18.0] and a.runs == 2
    assert (a.first, a.second, a.last) == (10.0, 13.0, 18.0)
    assert a.last_over_first == pytest.approx(1.8)
    assert a.last_over_second == pytest.approx(18 / 13)
    assert s.runs == 1 and s.last_over_first == pytest.approx(1.1)
    assert missing.runs == 0 and missing.per_task == []
    files = write_outputs(rows, tmp_path, {"dataset": "lasa", "profile": "fast", "seeds": [0, 1]})
    assert all(f.stat().st_size > 0 for f in files) and (tmp_path / "task_time.png").exists()
    table = (tmp_path / "task_time.md").read_text()
    assert "| hn all | 2 | 4 | 10.0 | 13.0 | 18.0 | 1.80 | 1.38 |" in table
    assert "| chn all | 0 | 0 | – |" in table
    doc = json.loads((tmp_path / "task_time.json").read_text())
    assert doc["rows"][2]["first"] is None  # no NaN in JSON


def test_bad_modes_and_methods_are_refused_before_training(tmp_path, capsys):
    out = tmp_path / "tt"
    assert main(["study", "tasktime", "--regs", "all,loop", "--out", str(out)]) == 2
    assert "--regs takes all, batched, sampled" in capsys.readouterr().err
    assert main(["study", "tasktime", "--methods", "sg", "--regs", "sampled", "--profile",
                 "smoke", "--out", str(out)]) == 2
    assert "hnet_reg" in capsys.readouterr().err
    assert not (out / "runs").exists()


def test_smoke_study(tmp_path):
    out = tmp_path / "tt"
    argv = ["study", "tasktime", "--dataset", "helloworld", "--methods", "hn", "--regs",
            "all,sampled", "--profile", "smoke", "--tasks", "3", "--out", str(out)]
    assert main(argv) == 0
    doc = json.loads((out / "task_time.json").read_text())
    assert [r["label"] for r in doc["rows"]] == ["hn all", "hn sampled"]
    assert all(len(r["per_task"]) == 3 and r["first"] > 0 for r in doc["rows"])
    runs = sorted(p.name for p in (out / "runs" / "helloworld" / "hn").iterdir())
    assert runs == ["smoke_nodet_o0_s0_k3_nosim_hnet_reg=all",
                    "smoke_nodet_o0_s0_k3_nosim_hnet_reg=sampled"]
