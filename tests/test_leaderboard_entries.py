"""Named leaderboard entries (HN-SNODE, CHN-SNODE): their runs carry the entry's NODE variant
and settings whatever the grid's --node, never share directories or rows with the bare
method, and unknown names fail listing the entries."""

from __future__ import annotations

import pytest

from clfd_bench.leaderboard import entries
from clfd_bench.leaderboard.aggregate import RunRecord, aggregate
from clfd_bench.leaderboard.entries import ENTRIES, Entry
from clfd_bench.leaderboard.grid import GridOptions, RunSpec, make_grid
from clfd_bench.leaderboard.report import paper_ranking, write_tables
from clfd_bench.leaderboard.runner import check_methods
from clfd_bench.methods import UnknownMethodError


def test_entry_runs_carry_their_node_and_settings(tmp_path):
    specs = make_grid("lasa", ["hn", "hn-snode", "chn-snode"], "fast", [0], [0],
                      GridOptions(node="t"))
    hn, hn_s, chn_s = specs
    assert (hn.node, hn.overrides, hn.label) == ("t", (), "hn")
    assert (hn_s.method, hn_s.node, hn_s.label) == ("hn", "s", "hn-snode")
    assert hn_s.overrides == (("hnet_reg", "sampled"),)
    assert (chn_s.method, chn_s.node) == ("chn", "s")
    # Same method folder, different runs.
    assert hn.name == "lasa/hn/fast_nodet_o0_s0"
    assert hn_s.name == "lasa/hn/fast_nodes_o0_s0_hnet_reg=sampled"
    train = hn_s.job(tmp_path).train
    assert (train.node, train.overrides, train.method) == ("s", ("hnet_reg=sampled",), "hn")
    # Executors ship specs as plain data: the entry survives the round trip.
    assert RunSpec(**hn_s.to_dict()) == hn_s
    # The entry's node wins over the grid's.
    assert make_grid("lasa", ["hn-snode"], "fast", [0], [0], GridOptions(node="i"))[0].node == "s"
    # Its configuration resolves (the sNODE keys and the regulariser are accepted).
    cfg = hn_s.config()
    assert cfg.node == "s"


def test_two_names_training_the_same_runs_are_refused(monkeypatch):
    twin = Entry("hn-twin", "hn", "s", (("hnet_reg", "sampled"),), "test")
    monkeypatch.setitem(entries.ENTRIES, "hn-twin", twin)
    with pytest.raises(ValueError, match="'hn-snode' and 'hn-twin' in --methods would train "
                                         "the same runs"):
        make_grid("lasa", ["hn-snode", "hn-twin"], "fast", [0], [0])


def test_unknown_name_lists_methods_and_entries():
    check_methods(["sg", "hn-snode", "chn-snode"])
    with pytest.raises(UnknownMethodError) as err:
        check_methods(["hn-snod"])
    text = str(err.value)
    assert "'hn-snod'" in text and "chn" in text and "named entries: hn-snode, chn-snode" in text
    assert text.endswith("(did you mean 'hn-snode'?)")


def _record(spec: RunSpec, acc: float, size: int) -> RunRecord:
    cl = {"ACC": acc, "REM": 1.0, "BWT": 0.0, "MS": 1.0, "TE": 1.0, "SSS": 1.0}
    return RunRecord(spec, "done", {"cl_metrics": cl, "num_params": [size]})


def test_entry_and_bare_method_are_separate_rows(tmp_path):
    hn, hn_s = make_grid("lasa", ["hn", "hn-snode"], "fast", [0], [0])
    rows = aggregate([_record(hn, 0.5, 100), _record(hn_s, 0.9, 300)], ["hn", "hn-snode"])
    assert [r.method for r in rows] == ["hn", "hn-snode"]
    assert rows[0].values["ACC"] == [0.5] and rows[1].values["ACC"] == [0.9]
    # FS across both rows: 1 - 100/300 for HN, 0 for the larger entry.
    assert rows[0].values["FS"] == [pytest.approx(2 / 3)] and rows[1].values["FS"] == [0.0]
    meta = {"dataset": "lasa", "profile": "fast", "methods": ["hn", "hn-snode"], "seeds": [0],
            "orders": [0], "node": "t", "tasks": None, "sim": False, "figures": []}
    write_tables(rows, tmp_path, meta)
    table = (tmp_path / "leaderboard.md").read_text()
    assert "| HN-SNODE | 1 |" in table and "| HN | 1 |" in table
    assert "Named entries: HN-SNODE = HN with sNODE, hnet_reg=sampled" in table


def test_entries_are_not_ranked_against_the_paper():
    meta = {"dataset": "lasa", "node": "t",
            "methods": ["sg", "ft", "rep", "si", "mas", "hn", "chn", "chn-snode"]}
    ranking = paper_ranking([], meta)
    assert ranking.label is None and "not in it CHN-SNODE" in ranking.note


def test_describe_names_the_configuration():
    assert ENTRIES["chn-snode"].describe().startswith(
        "CHN-SNODE = CHN with sNODE, hnet_reg=sampled (")
