"""The same training command gives bit-identical predictions: twice, and with another
``--threads`` (MKL's thread-invariant mode, clfd_bench.kernels). Each run is its own process,
as a user's command is. The CHN RoboTasks smoke run is the case that differed by 6e-7 across
thread counts before the mode was set."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from clfd_bench.kernels import MKL_CBWR_DEFAULT
from clfd_bench.runs import RunDir

SHARED = Path(__file__).resolve().parents[2] / "shared" / "datasets"


def _train(out: Path, threads: int, env: dict[str, str]) -> dict[str, np.ndarray]:
    cmd = [sys.executable, "-m", "clfd_bench.cli.main", "train", "--method", "chn",
           "--dataset", "robotasks", "--profile", "smoke", "--tasks", "2", "--no-sim",
           "--quiet", "--threads", str(threads), "--out", str(out)]
    subprocess.run(cmd, check=True, env=env, capture_output=True, text=True, timeout=300)
    return RunDir(out).load_predictions(1)


@pytest.fixture(scope="module")
def env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "MKL_CBWR"}
    if "CLFD_DATA_DIR" not in env and SHARED.is_dir():
        env["CLFD_DATA_DIR"] = str(SHARED)
    return env


def test_same_command_and_other_thread_count_give_identical_predictions(tmp_path, env):
    runs = [_train(tmp_path / f"run{i}", threads, env) for i, threads in enumerate((1, 1, 2))]
    assert sorted(runs[0]) == sorted(runs[1]) == sorted(runs[2])
    cpu = json.loads((tmp_path / "run0" / "results.json").read_text())["provenance"]["cpu"]
    intel = "Intel" in cpu["model"]  # the CPU the run recorded (harness.evaluation.cpu_provenance)
    for part in runs[0]:
        assert np.array_equal(runs[0][part], runs[1][part]), f"{part}: twice differ"
        if intel:
            assert np.array_equal(runs[0][part], runs[2][part]), f"{part}: --threads 2 differs"
        else:
            # Measured on an AMD EPYC (2026-12-06): --threads 2 differs from 1 by 6e-7 to
            # 1.6e-6 with MKL_CBWR AUTO,STRICT, COMPATIBLE or AVX2,STRICT alike, so the
            # thread-invariant mode does not reach it there (docs/learning.md, reproducibility).
            # Bit-identity across thread counts is asserted on Intel only; elsewhere the
            # difference must stay at rounding level.
            np.testing.assert_allclose(runs[2][part], runs[0][part], rtol=0, atol=1e-4,
                                       err_msg=f"{part}: --threads 2 differs beyond rounding")
    assert cpu["blas"]["mkl_cbwr"] == MKL_CBWR_DEFAULT
    assert cpu["kernel_env"]["MKL_CBWR"] == MKL_CBWR_DEFAULT
    assert cpu["blas"]["torch_blas"] and cpu["torch_capability"]


def test_a_mode_the_user_set_is_kept(tmp_path, env):
    out = tmp_path / "run"
    _train(out, 1, env | {"MKL_CBWR": "COMPATIBLE"})
    cpu = json.loads((out / "results.json").read_text())["provenance"]["cpu"]
    assert cpu["blas"]["mkl_cbwr"] == "COMPATIBLE"
