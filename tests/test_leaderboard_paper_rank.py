"""The leaderboard shows the paper's ranking beside ours when its grid matches a paper table
(same dataset, NODE variant and methods), and says why not otherwise. Built from hand-made
aggregate rows: nothing is trained."""

from __future__ import annotations

import csv
import json

import pytest

from clfd_bench.leaderboard.aggregate import MethodRow
from clfd_bench.leaderboard.grid import GridOptions
from clfd_bench.leaderboard.report import paper_ranking, write_tables

HW_METHODS = ["sg", "ft", "rep", "si", "mas", "hn", "chn"]
# tab:hw_cl_explicit_time's CL_scores: CHN 0.92 > HN 0.90 > REP 0.86 > SG 0.72 > FT 0.69 >
# MAS 0.64 > SI 0.57.
HW_PAPER = {"sg": 0.72, "ft": 0.69, "rep": 0.86, "si": 0.57, "mas": 0.64, "hn": 0.90, "chn": 0.92}


def _rows(scores: dict[str, float | None]) -> list[MethodRow]:
    """One row per method with two runs of the given CL_score (None: no finished run)."""
    rows = []
    for method, score in scores.items():
        row = MethodRow(method)
        if score is not None:
            row.runs_ok = 2
            row.values["CL_score"] += [score, score]
            row.values["ACC"] += [0.5, 0.5]
        rows.append(row)
    return rows


def _meta(dataset="helloworld", methods=HW_METHODS, node="t", profile="fast", **extra):
    return dict(dataset=dataset, methods=list(methods), profile=profile, seeds=[0, 1],
                orders=[0], node=node, tasks=None, sim=False, **extra)


def _write(tmp_path, scores, **meta):
    write_tables(_rows(scores), tmp_path, _meta(methods=list(scores), **meta))
    md = (tmp_path / "leaderboard.md").read_text()
    js = json.loads((tmp_path / "leaderboard.json").read_text())
    with open(tmp_path / "leaderboard.csv", newline="") as f:
        table = list(csv.DictReader(f))
    line = next(ln for ln in md.splitlines() if ln.startswith("Paper:"))
    return md, js, table, line


def test_same_order_as_the_paper_matches(tmp_path):
    md, js, table, line = _write(tmp_path, {m: s - 0.05 for m, s in HW_PAPER.items()})
    assert "| # | paper # | method | runs | CL_score | paper CL_score |" in md
    assert "| 2 | 2 | HN | 2 | 0.85 | 0.90 |" in md
    assert "tab:hw_cl_explicit_time" in line and "HelloWorld NODE^T" in line
    assert "equals the paper's." in line and "swapped" not in line
    assert js["paper"]["table"] == "tab:hw_cl_explicit_time"
    assert js["paper"]["ranking_matches"] is True and js["paper"]["swaps"] == []
    by_method = {r["method"]: r for r in js["rows"]}
    assert {m: r["paper_rank"] for m, r in by_method.items()} == {
        "chn": 1, "hn": 2, "rep": 3, "sg": 4, "ft": 5, "mas": 6, "si": 7}
    assert by_method["hn"]["paper_cl_score"] == 0.90
    csv_rows = {r["method"]: r for r in table}
    assert csv_rows["si"]["paper_rank"] == "7" and float(csv_rows["si"]["paper_cl_score"]) == 0.57


def test_hn_and_sg_swapped_by_a_tenth_is_named(tmp_path):
    scores = {**HW_PAPER, "hn": 0.75, "sg": 0.85}
    md, js, _, line = _write(tmp_path, scores)
    assert "differs from the paper's" in line
    assert "HN/SG (ours: SG ahead by 0.10; paper: HN ahead by 0.18)" in line
    swap = next(s for s in js["paper"]["swaps"] if s["ours_ahead"] == "sg")
    assert swap["paper_ahead"] == "hn" and not swap["tie"]
    assert swap["ours_diff"] == pytest.approx(0.10)
    assert js["paper"]["ranking_matches"] is False
    assert js["paper"]["ranking_matches_up_to_ties"] is False
    assert "| 4 | 2 | HN | 2 | 0.75 | 0.90 |" in md  # ours 4th, the paper's 2nd


def test_swap_within_two_hundredths_is_a_tie(tmp_path):
    # ours: CHN, SG 0.81, REP 0.805, HN 0.80: every swap is by at most 0.01
    scores = {**HW_PAPER, "sg": 0.81, "rep": 0.805, "hn": 0.80}
    _, js, _, line = _write(tmp_path, scores)
    assert "equals the paper's up to ties" in line
    assert "HN/SG (ours: SG ahead by 0.01; paper: HN ahead by 0.18), a tie (within 0.02)" in line
    assert all(s["tie"] for s in js["paper"]["swaps"]) and len(js["paper"]["swaps"]) == 3
    assert js["paper"]["ranking_matches"] is False
    assert js["paper"]["ranking_matches_up_to_ties"] is True


def test_tie_and_real_swap_are_told_apart(tmp_path):
    scores = {**HW_PAPER, "hn": 0.93, "mas": 0.50}  # HN/CHN by 0.01 (tie), SI/MAS by 0.07
    _, _, _, line = _write(tmp_path, scores)
    assert "differs from the paper's" in line
    assert "CHN/HN (ours: HN ahead by 0.01; paper: CHN ahead by 0.02), a tie" in line
    assert "MAS/SI (ours: SI ahead by 0.07; paper: MAS ahead by 0.07)" in line
    assert "MAS/SI (ours: SI ahead by 0.07; paper: MAS ahead by 0.07), a tie" not in line


def test_grid_without_si_and_mas_matches_no_table(tmp_path):
    scores = {m: s for m, s in HW_PAPER.items() if m not in ("si", "mas")}
    md, js, table, line = _write(tmp_path, scores, profile="smoke")
    assert line == ("Paper: no paper CL table matches this grid (methods differ from "
                    "tab:hw_cl_explicit_time: missing SI, MAS).")
    assert "paper #" not in md and "paper CL_score" not in md
    assert "| # | method | runs | CL_score | CL_stab |" in md
    assert js["paper"]["table"] is None and "missing SI, MAS" in js["paper"]["reason"]
    assert all(r["paper_rank"] is None and r["paper_cl_score"] is None for r in js["rows"])
    assert all(r["paper_rank"] == "" and r["paper_cl_score"] == "" for r in table)


def test_extra_method_or_other_variant_matches_no_table():
    rows = _rows({m: 0.5 for m in ["sg", "ft", "rep", "hn", "chn", "si"]})
    extra = paper_ranking(rows, _meta("robotasks", methods=["sg", "ft", "rep", "hn", "chn", "si"]))
    assert extra.label is None and "tab:rt_pos_cl: not in it SI" in extra.note
    node_i = paper_ranking(rows[:5], _meta("robotasks", methods=["sg", "ft", "rep", "hn", "chn"],
                                           node="i"))
    assert node_i.label is None and "NODE^T only" in node_i.note
    other = paper_ranking(rows[:5], _meta("robotasks9", methods=["sg", "ft", "rep", "hn", "chn"]))
    assert other.label is None and "robotasks9" in other.note


def test_robotasks_is_compared_with_the_position_table():
    methods = ["sg", "ft", "rep", "hn", "chn"]
    # tab:rt_pos_cl: CHN 0.88 > HN 0.84 > REP 0.80 > SG 0.73 > FT 0.66
    ranking = paper_ranking(_rows(dict(zip(methods, [0.73, 0.66, 0.80, 0.84, 0.88], strict=True))),
                            _meta("robotasks", methods=methods))
    assert ranking.label == "tab:rt_pos_cl" and ranking.matches is True
    assert ranking.ranks == {"chn": 1, "hn": 2, "rep": 3, "sg": 4, "ft": 5}


def test_paper_ties_share_a_rank_and_missing_runs_are_not_compared():
    # tab:lasa_cl_no_time: HN 0.87, REP = CHN 0.82, MAS 0.76, FT = SI 0.69, SG 0.64
    scores = {"sg": 0.6, "ft": 0.7, "rep": 0.8, "si": 0.7, "mas": 0.75, "hn": 0.9, "chn": None}
    ranking = paper_ranking(_rows(scores), _meta("lasa", methods=list(scores), node="i"))
    assert ranking.label == "tab:lasa_cl_no_time"
    assert ranking.ranks == {"hn": 1, "rep": 2, "chn": 2, "mas": 4, "ft": 5, "si": 5, "sg": 7}
    assert "ties sharing a rank (REP/CHN 0.82, FT/SI 0.69)" in ranking.note
    assert ranking.not_compared == ["chn"]
    assert "Not compared (no CL_score of ours): CHN" in ranking.note
    assert ranking.matches is True  # the others are in the paper's order


def test_exec_cl_score_replaces_acc_and_rem_and_is_ranked_against_the_paper(tmp_path):
    """HelloWorld NODE^I as measured: SG's letters pass the DTW threshold without their loops
    (trajectory ACC 1.00) but not the writing criterion; FT forgets. By CL_score SG is ahead
    of FT, against the paper; by exec CL_score FT is, as in the paper."""
    from clfd_bench.leaderboard.aggregate import RunRecord, aggregate
    from clfd_bench.leaderboard.grid import make_grid

    paper_i = {"sg": 0.67, "ft": 0.70, "rep": 0.82, "si": 0.60, "mas": 0.66, "hn": 0.86,
               "chn": 0.88}  # tab:hw_cl_no_time
    specs = make_grid("helloworld", HW_METHODS, "fast", [0], [0], GridOptions(node="i"))
    traj = {"sg": (1.00, 1.00), "ft": (0.25, 0.00)}
    executed = {"sg": (0.64, 1.00), "ft": (0.16, 0.29)}
    records = []
    for spec in specs:
        acc, rem = traj.get(spec.method, (0.9, 0.9))
        e_acc, e_rem = executed.get(spec.method, (0.9, 0.9))
        size = 236_558 if spec.method == "sg" else 34_000
        ms = 0.37 if spec.method == "sg" else 1.0  # SG grows a NODE per task
        cl = {"ACC": acc, "REM": rem, "BWT": rem - 1, "MS": ms, "TE": 1.0, "SSS": 1.0}
        records.append(RunRecord(spec, "done", {
            "cl_metrics": cl, "num_params": [size],
            "sim_cl_metrics": {"ACC": e_acc, "REM": e_rem, "BWT": e_rem - 1}}))
    rows = {r.method: r for r in aggregate(records, HW_METHODS)}
    # SG: FS 0 (the largest model); hand-computed means of the six criteria.
    assert rows["sg"].values["CL_score"] == [pytest.approx((1 + 1 + 0.37 + 1 + 0 + 1) / 6)]
    assert rows["sg"].values["exec_CL_score"] == [
        pytest.approx((0.64 + 1 + 0.37 + 1 + 0 + 1) / 6)]
    fs_ft = 1 - 34_000 / 236_558
    assert rows["ft"].values["exec_CL_score"] == [
        pytest.approx((0.16 + 0.29 + 1 + 1 + fs_ft + 1) / 6)]
    # The rows here rank SG/FT against the paper's tab:hw_cl_no_time by both scores.
    for row in rows.values():  # the others far ahead of or behind SG and FT, as in the paper
        if row.method not in ("sg", "ft"):
            far = paper_i[row.method] + (0.2 if paper_i[row.method] > 0.7 else -0.2)
            row.values["CL_score"] = [far]
            row.values["exec_CL_score"] = [far]
    write_tables(list(rows.values()), tmp_path, {**_meta(node="i"), "sim": True})
    md = (tmp_path / "leaderboard.md").read_text()
    line = next(ln for ln in md.splitlines() if ln.startswith("Paper:"))
    assert "Our ranking by CL_score differs from the paper's; swapped: FT/SG" in line
    assert ("Our ranking by exec CL_score (ACC and REM from execution) equals the paper's."
            in line)
    js = json.loads((tmp_path / "leaderboard.json").read_text())
    assert js["paper"]["ranking_matches"] is False
    assert js["paper"]["executed"]["key"] == "exec_CL_score"
    assert js["paper"]["executed"]["ranking_matches"] is True
    assert "| exec CL_score |" in md


def test_no_exec_comparison_without_execution(tmp_path):
    md, js, _, line = _write(tmp_path, dict(HW_PAPER))
    assert "exec CL_score (ACC" not in line and js["paper"]["executed"] is None
