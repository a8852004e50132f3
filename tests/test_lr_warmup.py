"""The learning-rate warm-up (``lr_warmup``): its schedule against hand-computed values, its
place in saved configs, and the divergence it prevents (CHN NODE^I, HelloWorld, seed 1:
without it the first letter ends at a DTW of 786549 cm and 'e' turns NaN; measured)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from clfd_bench.harness.config import resolve_config
from clfd_bench.harness.loop import lr_factor
from clfd_bench.harness.protocol import run_training
from clfd_bench.learning.part_config import ConfigError, PartConfig

SHARED = Path(__file__).resolve().parents[2] / "shared" / "datasets"


def _cfg(**kw) -> PartConfig:
    return PartConfig(iterations=100, lr=1e-3, node_hidden=(8,), **kw)


def test_warmup_multiplies_the_schedule_linearly():
    cos = _cfg(lr_schedule="cosine", lr_warmup=0.1)  # 10 warm-up steps
    assert lr_factor(cos, 0) == pytest.approx(0.1)  # (0 + 1) / 10 * cos(0)
    assert lr_factor(cos, 4) == pytest.approx(0.5 * 0.5 * (1 + math.cos(math.pi * 0.04)))
    assert lr_factor(cos, 9) == pytest.approx(0.5 * (1 + math.cos(math.pi * 0.09)))
    assert lr_factor(cos, 50) == pytest.approx(0.5)  # past the warm-up: the cosine alone
    const = _cfg(lr_warmup=0.2)  # 20 steps
    assert [lr_factor(const, i) for i in (0, 4, 19, 20, 99)] == pytest.approx(
        [0.05, 0.25, 1.0, 1.0, 1.0])
    assert all(lr_factor(_cfg(), i) == 1.0 for i in range(100))  # default: no warm-up


def test_warmup_is_saved_only_when_used_and_checked():
    assert "lr_warmup" not in _cfg().to_dict()  # older runs' saved configs read the same
    assert _cfg(lr_warmup=0.1).to_dict()["lr_warmup"] == 0.1
    with pytest.raises(ConfigError, match="lr_warmup"):
        _cfg(lr_warmup=1.5)
    paper = resolve_config("chn", "helloworld", "paper").part("position")
    assert paper.lr_warmup == 0.0  # the paper's constant learning rate
    assert resolve_config("chn", "helloworld", "fast").part("position").lr_warmup == 0.1


def test_chn_without_time_input_learns_seed_1s_first_letter(tmp_path):
    if "CLFD_DATA_DIR" not in os.environ and SHARED.is_dir():
        os.environ["CLFD_DATA_DIR"] = str(SHARED)
    cfg = resolve_config("chn", "helloworld", "fast", seed=1, node="i", tasks=1)
    results = run_training(cfg, tmp_path, threads=1, log=None)
    dtw_cm = 100 * np.median(results["errors"]["dtw"][0][0])
    assert results["accuracy"]["dtw"][0][0] == 1.0, f"median DTW {dtw_cm:.0f} cm"
