"""What the methods must do on HelloWorld's first two tasks with the ``fast`` profile.

* SG, REP, HN and CHN reproduce both letters: accuracy 1.0 at the paper's DTW threshold.
* FT forgets: task 0's error after learning task 1 is far above its error right after task 0.
* HN does not: task 0's prediction after task 1 stays close to its prediction after task 0.

Each method's two-task run is made once (module fixture) and shared by the tests.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from clfd_bench.harness.config import resolve_config
from clfd_bench.harness.protocol import run_training
from clfd_bench.runs import RunDir

SHARED = Path(__file__).resolve().parents[2] / "shared" / "datasets"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    if "CLFD_DATA_DIR" not in os.environ and SHARED.is_dir():
        os.environ["CLFD_DATA_DIR"] = str(SHARED)
    out = {}
    for method in ("sg", "rep", "hn", "chn", "ft"):
        cfg = resolve_config(method, "helloworld", "fast", seed=0, tasks=2)
        run_dir = tmp_path_factory.mktemp(method)
        out[method] = (run_training(cfg, run_dir, threads=1, log=None), run_dir)
    return out


@pytest.mark.parametrize("method", ["sg", "rep", "hn", "chn"])
def test_fast_profile_reproduces_the_first_two_letters(runs, method):
    results, _ = runs[method]
    r = np.array(results["accuracy"]["dtw"], dtype=float)
    assert r[0, 0] == 1.0 and r[1, 0] == 1.0 and r[1, 1] == 1.0, (
        f"{method}: R = {r.tolist()}, DTW (m) = {results['errors']['dtw']}"
    )


def test_finetuning_forgets(runs):
    results, _ = runs["ft"]
    before = np.median(results["errors"]["dtw"][0][0])
    after = np.median(results["errors"]["dtw"][1][0])
    assert after > 5 * before, (before, after)
    assert results["accuracy"]["dtw"][1][0] < 0.5


def test_hypernetwork_does_not_forget(runs):
    _, run_dir = runs["hn"]
    run = RunDir(run_dir)
    right_after, later = run.load_predictions(0)[0], run.load_predictions(1)[0]
    drift = np.linalg.norm(later - right_after, axis=-1)  # metres, per sample
    assert np.median(drift) < 0.005 and drift.max() < 0.02, (np.median(drift), drift.max())
    ft_dir = runs["ft"][1]
    ft = RunDir(ft_dir)
    ft_drift = np.linalg.norm(ft.load_predictions(1)[0] - ft.load_predictions(0)[0], axis=-1)
    assert np.median(ft_drift) > 10 * np.median(drift)  # the tolerance is meaningful
