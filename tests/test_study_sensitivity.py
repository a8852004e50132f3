"""The sensitivity study: the configuration draw is uniform in range, seeded and recorded in
the run names; CL_score / CL_stability without SSS equal a hand computation (FS across the
compared methods); the summary and figure have one entry/panel per method."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from clfd_bench.leaderboard.aggregate import RunRecord
from clfd_bench.leaderboard.grid import GridOptions, RunSpec
from clfd_bench.studies.sensitivity import (
    apply_ranges,
    config_scores,
    default_ranges,
    draw_configs,
    parse_range,
    sensitivity_figure,
    sensitivity_specs,
    summarize,
)

RANGES = {"si": {"si_c": (0.1, 0.5), "si_xi": (0.1, 0.5)}, "hn": {"beta": (1e-3, 1e-2)}}


def test_paper_ranges_are_the_defaults():
    assert default_ranges() == {
        "si": {"si_c": (0.1, 0.5), "si_xi": (0.1, 0.5)}, "mas": {"mas_lambda": (0.1, 0.5)},
        "hn": {"beta": (1e-3, 1e-2)}, "chn": {"beta": (1e-3, 1e-2)},
    }  # fmt: skip


def test_draw_is_uniform_in_range():
    draws = draw_configs(["si", "hn"], 400, seed=0, ranges=RANGES)
    assert [d.method for d in draws] == ["si"] * 400 + ["hn"] * 400
    for method, keys in RANGES.items():
        for key, (low, high) in keys.items():
            vals = np.array([d.value(key) for d in draws if d.method == method])
            assert vals.min() >= low and vals.max() <= high
            # uniform: Kolmogorov-Smirnov against U(low, high), and it covers the range
            assert stats.kstest(vals, stats.uniform(low, high - low).cdf).pvalue > 1e-3
            assert vals.min() < low + 0.05 * (high - low) and vals.max() > high - 0.05 * (
                high - low)
    si_c = [d.value("si_c") for d in draws if d.method == "si"]
    si_xi = [d.value("si_xi") for d in draws if d.method == "si"]
    assert abs(np.corrcoef(si_c, si_xi)[0, 1]) < 0.2  # drawn independently


def test_draw_is_seeded_and_stable():
    first = draw_configs(["si", "hn"], 5, seed=0, ranges=RANGES)
    assert first == draw_configs(["si", "hn"], 5, seed=0, ranges=RANGES)
    assert first != draw_configs(["si", "hn"], 5, seed=1, ranges=RANGES)
    # a method's draws do not depend on the other methods, and more configs keep the first
    assert draw_configs(["hn"], 5, seed=0, ranges=RANGES) == first[5:]
    assert draw_configs(["si", "hn"], 8, seed=0, ranges=RANGES)[:5] == first[:5]


def test_draw_is_recorded_in_the_run_names(tmp_path):
    draws = draw_configs(["si", "hn"], 3, seed=7, ranges=RANGES)
    specs = sensitivity_specs(draws, "lasa", "fast", 7, GridOptions(tasks=5, sim=False))
    names = [s.name for s in specs]
    assert len(set(names)) == 6
    for draw, spec in zip(draws, specs, strict=True):
        for key, text in draw.values:
            assert f"_{key}={text}" in spec.name
            assert f"{key}={text}" in spec.job(tmp_path).train.overrides
            assert float(text) == draw.value(key)
        assert spec.name.startswith(f"lasa/{draw.method}/fast_nodet_o0_s7_k5_nosim_")


def test_range_options():
    assert parse_range("beta=1e-3,1e-2") == (None, "beta", 1e-3, 1e-2)
    assert parse_range("HN.beta=0.01,1") == ("hn", "beta", 0.01, 1.0)
    ranges = apply_ranges(default_ranges(), ["hn", "chn"], ["beta=0.01,1", "chn.beta=2,3"])
    assert ranges == {"hn": {"beta": (0.01, 1.0)}, "chn": {"beta": (2.0, 3.0)}}
    with pytest.raises(ValueError, match="no studied method samples 'xi'"):
        apply_ranges(default_ranges(), ["hn"], ["xi=0.1,0.2"])
    with pytest.raises(ValueError, match="no hyperparameter range for sg"):
        apply_ranges(default_ranges(), ["sg"], [])
    with pytest.raises(ValueError, match="low < high"):
        parse_range("beta=0.5,0.1")


def _record(method: str, sets: dict, cl: dict, size: int, status: str = "done") -> RunRecord:
    spec = RunSpec("lasa", method, "fast", 0, overrides=tuple(sets.items()))
    results = {"cl_metrics": cl, "num_params": [size // 2, size]} if status == "done" else None
    return RunRecord(spec, status, results, None if status == "done" else "boom")


def test_cl_score_without_sss_matches_hand_computation():
    # SSS is present in the runs' metrics (and terrible) but must not count.
    hn_a = {"ACC": 0.8, "REM": 0.9, "BWT": -0.1, "MS": 1.0, "TE": 0.5, "SSS": 0.0}
    hn_b = {"ACC": 0.6, "REM": 1.0, "BWT": 0.0, "MS": 1.0, "TE": 0.7, "SSS": 0.0}
    si_a = {"ACC": 0.4, "REM": 0.5, "BWT": -0.5, "MS": 1.0, "TE": 1.0, "SSS": 0.0}
    records = [_record("hn", {"beta": "0.002"}, hn_a, 100),
               _record("hn", {"beta": "0.008"}, hn_b, 100),
               _record("si", {"si_c": "0.3", "si_xi": "0.2"}, si_a, 400),
               _record("si", {"si_c": "0.4", "si_xi": "0.1"}, {}, 400, "failed")]
    scores = config_scores(records, ["hn", "si"])
    # FS: hn 1 - 100/400 = 0.75, si 1 - 400/400 = 0.
    a, b, s, failed = scores
    assert a.criteria == pytest.approx({"ACC": 0.8, "REM": 0.9, "MS": 1.0, "TE": 0.5, "FS": 0.75})
    assert a.cl_score == pytest.approx((0.8 + 0.9 + 1.0 + 0.5 + 0.75) / 5)  # 0.79
    dev = np.array([0.8, 0.9, 1.0, 0.5, 0.75]) - 0.79
    assert a.cl_stability == pytest.approx(1 - math.sqrt((dev**2).sum() / 4))
    assert b.cl_score == pytest.approx((0.6 + 1.0 + 1.0 + 0.7 + 0.75) / 5)  # 0.81
    assert s.cl_score == pytest.approx((0.4 + 0.5 + 1.0 + 1.0 + 0.0) / 5)
    assert a.values == {"beta": 0.002}
    assert math.isnan(failed.cl_score) and failed.status == "failed"
    summary = summarize(scores, ["hn", "si"])
    assert summary["hn"]["n"] == 2 and summary["si"]["n"] == 1 and summary["si"]["runs"] == 2
    assert summary["hn"]["CL_score_median"] == pytest.approx(0.80)
    assert summary["hn"]["CL_score_iqr"] == pytest.approx(0.01)  # q3 0.805 - q1 0.795
    assert summary["hn"]["paper_CL_score_median"] == pytest.approx(0.8578)
    assert summary["hn"]["diff_CL_score_median"] == pytest.approx(0.80 - 0.8578)
    fig = sensitivity_figure(scores, summary, RANGES, "test")
    assert [ax.get_title() for ax in fig.axes] == ["HN", "SI"]
    assert [ax.get_xlabel() for ax in fig.axes] == ["beta", "si_c (numbers: si_xi)"]
    hn_ax, si_ax = fig.axes
    assert sorted(hn_ax.collections[0].get_offsets()[:, 0]) == [0.002, 0.008]  # x: beta
    assert [t.get_text() for t in si_ax.texts] == ["0.2"]  # the other key, annotated
