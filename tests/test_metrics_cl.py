"""CL metrics against hand-made matrices and the paper's tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from clfd_bench.metrics.cl import (
    CRITERIA,
    acc,
    accuracy_matrix,
    bwt,
    cl_metrics,
    cl_score,
    cl_stability,
    final_model_size,
    model_size_efficiency,
    rem,
    sss,
    time_efficiency,
)

NAN = math.nan

# Hand-made R (rows: after learning task i; columns: evaluated task j).
R3 = np.array(
    [
        [1.00, NAN, NAN],
        [0.50, 1.00, NAN],
        [0.25, 0.50, 0.75],
    ]
)


def _two_decimals(value: float, expected: float) -> bool:
    """The paper prints 2 decimals; allow its rounding (half up or half even)."""
    return abs(value - expected) <= 0.005 + 1e-9


def test_acc_bwt_rem_by_hand():
    # ACC = (1 + .5 + 1 + .25 + .5 + .75) / 6 = 4 / 6.
    assert acc(R3) == pytest.approx(4 / 6)
    # BWT = mean of R[1,0]-R[0,0] = -.5, R[2,0]-R[0,0] = -.75, R[2,1]-R[1,1] = -.5.
    assert bwt(R3) == pytest.approx(-1.75 / 3)
    assert rem(R3) == pytest.approx(1 - 1.75 / 3)
    # Positive backward transfer: REM is capped at 1.
    better = np.array([[0.5, NAN], [1.0, 1.0]])
    assert bwt(better) == pytest.approx(0.5)
    assert rem(better) == 1.0
    # A single task has no backward transfer.
    assert math.isnan(bwt(np.array([[1.0]])))
    assert acc(np.array([[0.25]])) == 0.25


def test_accuracy_matrix_from_errors():
    thr = 2.0
    errors = [
        [[1.0, 3.0]],  # ragged: only task 0 after task 0
        [[1.0, 1.0], [5.0, 0.0]],
        [[2.0, NAN], [1.0, 2.5], [0.0, 0.5, 9.0]],  # NaN (diverged) counts as inaccurate
    ]
    r = accuracy_matrix(errors, thr)
    expected = np.array([[0.5, NAN, NAN], [1.0, 0.5, NAN], [0.5, 0.5, 2 / 3]])
    np.testing.assert_allclose(r, expected)
    # A full [M, M, N] array with NaN/None above the diagonal works the same way.
    full = [[[1.0, 3.0], None, None], [[1.0, 1.0], [5.0, 0.0], None]]
    np.testing.assert_allclose(accuracy_matrix(full, thr), [[0.5, NAN], [1.0, 0.5]])
    arr = np.full((2, 2, 2), NAN)
    arr[0, 0] = [1.0, 3.0]
    arr[1, :] = [[1.0, 1.0], [5.0, 0.0]]
    np.testing.assert_allclose(accuracy_matrix(arr, thr), [[0.5, NAN], [1.0, 0.5]])
    with pytest.raises(ValueError, match=r"errors\[1\] must hold the errors of tasks 0..1"):
        accuracy_matrix([[[1.0]], [[1.0]]], thr)


def test_model_size_efficiency():
    # SG adds one equal network per task: MS = mean 1/(i+1) = H_M / M, the paper's SG values
    # 0.15 (LASA, 26 tasks), 0.37 (HelloWorld, 7), 0.52 (RoboTasks, 4).
    for m, expected in ((26, 0.15), (7, 0.37), (4, 0.52)):
        sizes = [2.0e6 * (i + 1) for i in range(m)]
        assert _two_decimals(model_size_efficiency(sizes), expected)
    # HN on LASA: 4.3e6 parameters after 26 tasks, +256 per task -> 1.00.
    hn = [4.3e6 - 256 * (25 - i) for i in range(26)]
    assert _two_decimals(model_size_efficiency(hn), 1.00)
    assert model_size_efficiency([10, 10, 10]) == 1.0
    assert model_size_efficiency([10, 5]) == 1.0  # shrinking is capped at 1


def test_sss_replay_values():
    # REP keeps every seen task's demonstrations; equal tasks of N demos x T points.
    for m, expected in ((26, 0.48), (7, 0.43), (4, 0.38)):
        per_task = 7 * 1000
        stored = [per_task * (i + 1) for i in range(m)]
        assert _two_decimals(sss(stored, per_task * m), expected), m
        assert sss(stored, per_task * m) == pytest.approx(1 - (m + 1) / (2 * m))
    assert sss([0, 0, 0], 3000) == 1.0


# Tab. wall_clock (seconds per task, median over 5 seeds) and TE from the CL tables. The CL
# tables' TE is the median over seeds of each seed's TE, not TE of the median times, so
# most rows agree to 2 decimals and a few differ by up to ~0.02 (checked below apart).
WALL_CLOCK = {
    ("helloworld", "REP"): ([1926, 1939, 1950, 1942, 1957, 1975, 2016], 0.98),
    ("helloworld", "SI"): ([2019, 2128, 2093, 2091, 2110, 2132, 2268], 0.95),
    ("helloworld", "HN"): ([1968, 2337, 2508, 2702, 2843, 2930, 3234], 0.76),
    ("helloworld", "CHN"): ([1948, 2254, 2341, 2578, 2786, 2858, 3150], 0.78),
    ("robotasks_pos", "FT"): ([1483, 1985, 1923, 1732], 0.84),
    ("robotasks_pos", "REP"): ([1486, 1952, 1901, 1797], 0.84),
    ("robotasks_pos", "HN"): ([1508, 2387, 2585, 2214], 0.72),
    ("robotasks_ori", "FT"): ([2026, 2068, 2061, 2058], 0.99),
    ("robotasks_ori", "HN"): ([1461, 1903, 2116, 2303], 0.77),
}
WALL_CLOCK_LOOSE = {
    ("helloworld", "SG"): ([1896, 2012, 1872, 1960, 2030, 2030, 2281], 0.94),
    ("helloworld", "FT"): ([1954, 2022, 1973, 2016, 2050, 2086, 2385], 0.97),
    ("helloworld", "MAS"): ([1965, 2281, 2252, 2302, 2316, 2362, 2500], 0.86),
    ("robotasks_pos", "SG"): ([1869, 2400, 2328, 1684], 0.93),
    ("robotasks_pos", "CHN"): ([1591, 2484, 2662, 2141], 0.75),
    ("robotasks_ori", "SG"): ([1809, 1800, 1800, 1783], 0.99),
    ("robotasks_ori", "REP"): ([1396, 1409, 1409, 1409], 1.00),
    ("robotasks_ori", "CHN"): ([1504, 1840, 2204, 2511], 0.78),
}


@pytest.mark.parametrize("key", sorted(WALL_CLOCK))
def test_time_efficiency_reproduces_paper(key):
    times, expected = WALL_CLOCK[key]
    assert _two_decimals(time_efficiency(times), expected)


@pytest.mark.parametrize("key", sorted(WALL_CLOCK_LOOSE))
def test_time_efficiency_close_to_paper_for_other_rows(key):
    times, expected = WALL_CLOCK_LOOSE[key]
    assert abs(time_efficiency(times) - expected) <= 0.03


def test_time_efficiency_formula():
    # TE = min(1, T0/M * sum 1/Ti): doubling time per task from the second on -> (1 + .5)/2.
    assert time_efficiency([100, 200]) == pytest.approx(0.75)
    assert time_efficiency([100, 100, 100]) == 1.0
    assert time_efficiency([100, 50]) == 1.0  # faster later tasks are capped at 1


def test_final_model_size():
    # LASA sizes from the paper's text: SG 52.2e6, HN 4.3e6, CHN 1.9e6; FT is one NODE
    # (SG's per-task size) plus 26 task embeddings of 256.
    sizes = {"SG": 52.2e6, "HN": 4.3e6, "CHN": 1.9e6, "FT": 52.2e6 / 26 + 26 * 256}
    assert final_model_size(sizes, "SG") == 0.0
    assert _two_decimals(final_model_size(sizes, "HN"), 0.92)
    assert _two_decimals(final_model_size(sizes, "CHN"), 0.96)
    assert _two_decimals(final_model_size(sizes, "FT"), 0.96)
    with pytest.raises(ValueError, match="not among the compared sizes"):
        final_model_size(sizes, "REP")


# Rows of the paper's CL tables: (ACC, REM, MS, TE, FS, SSS) -> (CL_score, CL_stability).
# Line numbers in paper/continual-lfd-paper.tex.
PAPER_ROWS = {
    "LASA NODE^T HN (l.688)": ((0.86, 0.97, 1.00, 0.51, 0.92, 1.00), (0.88, 0.81)),
    "LASA NODE^T SG (l.683)": ((0.87, 1.00, 0.15, 0.85, 0.00, 1.00), (0.64, 0.55)),
    "LASA NODE^T REP (l.685)": ((0.67, 1.00, 1.00, 0.88, 0.96, 0.48), (0.83, 0.79)),
    "LASA NODE^T MAS (l.687)": ((0.02, 0.86, 1.00, 0.83, 0.83, 1.00), (0.76, 0.63)),
    "LASA NODE^T CHN (l.689)": ((0.51, 0.80, 1.00, 0.53, 0.96, 1.00), (0.80, 0.77)),
    "LASA NODE^I HN (l.709)": ((0.76, 0.97, 1.00, 0.55, 0.92, 1.00), (0.87, 0.82)),
    "HW NODE^T HN (l.800)": ((0.97, 0.98, 1.00, 0.76, 0.69, 1.00), (0.90, 0.86)),
    "HW NODE^T CHN (l.801)": ((0.89, 0.95, 1.00, 0.78, 0.87, 1.00), (0.92, 0.91)),
    "HW NODE^T REP (l.797)": ((0.94, 0.96, 1.00, 0.98, 0.84, 0.43), (0.86, 0.78)),
    "HW NODE^I MAS (l.820)": ((0.25, 0.47, 1.00, 0.86, 0.36, 1.00), (0.66, 0.66)),
    "RT pos CHN (l.909)": ((0.90, 0.90, 1.00, 0.75, 0.74, 1.00), (0.88, 0.89)),
    "RT pos HN (l.908)": ((0.88, 0.98, 1.00, 0.72, 0.45, 1.00), (0.84, 0.78)),
    "RT ori HN (l.927)": ((0.99, 1.00, 1.00, 0.77, 0.20, 1.00), (0.83, 0.68)),
    "RT ori REP (l.926)": ((0.99, 1.00, 1.00, 1.00, 0.66, 0.38), (0.84, 0.74)),
}


@pytest.mark.parametrize("row", sorted(PAPER_ROWS))
def test_cl_score_and_stability_reproduce_paper_rows(row):
    values, (score, stability) = PAPER_ROWS[row]
    criteria = dict(zip(("ACC", "REM", "MS", "TE", "FS", "SSS"), values, strict=True))
    assert _two_decimals(cl_score(criteria), score)
    assert _two_decimals(cl_stability(criteria), stability)


def test_cl_score_subset_and_errors():
    # The paper's hyperparameter study leaves SSS out: any subset of the six is allowed.
    five = {"ACC": 0.8, "REM": 1.0, "MS": 1.0, "TE": 0.6, "FS": 0.9}
    assert cl_score(five) == pytest.approx(0.86)
    assert cl_stability(five) == pytest.approx(1 - np.std(list(five.values()), ddof=1))
    with pytest.raises(ValueError, match="unknown CL criteria.*valid"):
        cl_score({"ACC": 1.0, "Acc": 1.0})
    with pytest.raises(ValueError, match="at least two"):
        cl_stability({"ACC": 1.0})


def test_cl_metrics_bundle():
    stored = [0, 0, 0]
    out = cl_metrics(
        R3, num_params=[100, 110, 120], stored=stored, total=300, train_times=[10, 10, 20]
    )
    assert set(out) == {"ACC", "REM", "BWT", "MS", "SSS", "TE"}
    assert out["ACC"] == pytest.approx(acc(R3))
    assert out["REM"] == pytest.approx(rem(R3))
    assert out["SSS"] == 1.0
    assert out["TE"] == pytest.approx((1 + 1 + 0.5) / 3)
    assert out["MS"] == pytest.approx(np.mean([1, 100 / 110, 100 / 120]))
    full = cl_metrics(R3, [100, 110, 120], stored, 300, [10, 10, 20], fs=0.5)
    assert set(full) == {"ACC", "REM", "BWT", "MS", "SSS", "TE", "FS", "CL_score", "CL_stability"}
    criteria = {k: full[k] for k in CRITERIA}
    assert full["CL_score"] == pytest.approx(np.mean(list(criteria.values())))
    assert full["CL_stability"] == pytest.approx(1 - np.std(list(criteria.values()), ddof=1))
    with pytest.raises(ValueError, match="one value per task"):
        cl_metrics(R3, [100, 110], stored, 300, [10, 10, 20])
