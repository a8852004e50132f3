"""Accuracy thresholds: the paper's constants in any units, and the described procedure."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from clfd_bench.metrics import THRESHOLD_SOURCES, demo_spread_threshold, threshold
from clfd_bench.metrics.thresholds import THRESHOLDS


def test_paper_constants_in_their_units():
    assert threshold("lasa", "dtw", "lasa") == 2191.0
    assert threshold("lasa", "frechet", "lasa") == 5.0
    assert threshold("lasa", "swept_area", "lasa") == 70.0
    assert threshold("helloworld", "dtw", "cm") == 1821.0
    assert threshold("robotasks", "dtw", "cm") == 7131.0
    assert threshold("robotasks", "quaternion", "deg") == 10.0


def test_conversion_to_metres_and_radians():
    assert threshold("helloworld", "dtw", "m") == pytest.approx(18.21)
    assert threshold("robotasks", "dtw", "m") == pytest.approx(71.31)
    assert threshold("robotasks9", "dtw", "m") == pytest.approx(71.31)
    assert threshold("robotasks", "quaternion", "rad") == pytest.approx(np.radians(10.0))


def test_every_constant_has_a_source():
    assert set(THRESHOLD_SOURCES) == set(THRESHOLDS)


@pytest.mark.parametrize(
    ("dataset", "metric", "units", "match"),
    [
        ("lasa", "dtw", "m", r"units \['lasa'\]"),
        ("helloworld", "dtw", "lasa", r"units \['m', 'cm'\]"),
        ("helloworld", "frechet", "cm", "no accuracy threshold for dataset 'helloworld'"),
        ("mnist", "dtw", "m", "valid: lasa/dtw in lasa"),
        ("robotasks", "quaternion", "m", r"units \['deg', 'rad'\]"),
    ],
)
def test_unknown_combinations_list_valid_ones(dataset, metric, units, match):
    with pytest.raises(ValueError, match=match):
        threshold(dataset, metric, units)


def test_demo_spread_threshold_small_case():
    # Three 1-D "demos" of 2 points: pairwise DTW |0-1|+|0-1| = 2, |0-3|*2 = 6, |1-3|*2 = 4.
    demos = np.array([[[0.0], [0.0]], [[1.0], [1.0]], [[3.0], [3.0]]])
    assert demo_spread_threshold(demos) == pytest.approx(18.0)
    assert demo_spread_threshold([demos, demos[:2]], factor=1.0) == pytest.approx(6.0)
    with pytest.raises(ValueError, match="N >= 2"):
        demo_spread_threshold(demos[:1])


def _data_dir() -> Path | None:
    root = os.environ.get("CLFD_DATA_DIR")
    return Path(root) if root and (Path(root) / "robot_hello_world").is_dir() else None


@pytest.mark.skipif(_data_dir() is None, reason="CLFD_DATA_DIR with the HelloWorld data not set")
def test_demo_spread_does_not_reproduce_paper_constants():
    """The described procedure gives ~4510 cm for HelloWorld (paper: 1821) and ~7121 cm for
    RoboTasks positions with factor 1 (paper: 7131). About 7 s on a 2-core machine."""
    from clfd_bench.data import load_dataset

    hello = [100.0 * t.demos for t in load_dataset("helloworld").tasks]  # m -> cm
    assert demo_spread_threshold(hello, factor=3.0) == pytest.approx(4510.2, abs=1.0)
    robot = [100.0 * t.positions for t in load_dataset("robotasks").tasks]
    assert demo_spread_threshold(robot, factor=1.0) == pytest.approx(7121.2, abs=1.0)
