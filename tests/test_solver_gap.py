"""The solver gap: a model integrated as training integrates it (fixed steps on the
subsampled grid) against the same model integrated as predictions are. A gentle field
gives ~0; a fast field, whose coarse RK4 steps miss what happens between them, gives a gap
of centimetres; adaptive or per-sample training solvers report none; runs record it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from clfd_bench.data import load_dataset
from clfd_bench.harness.config import resolve_config
from clfd_bench.harness.learner import Learner
from clfd_bench.harness.protocol import run_training


def _learner(scale: float, **overrides):
    config = resolve_config("sg", "helloworld", "smoke", tasks=1)
    cfg = dataclasses.replace(config.parts[0][1], **overrides)
    config = dataclasses.replace(config, parts=(("position", cfg),))
    task = load_dataset("helloworld").tasks[0]
    torch.manual_seed(0)
    learner = Learner.from_config(config, task.dim)
    learner.parts["position"].add_task(task)
    with torch.no_grad():
        for p in learner.parts["position"].method.parameters():
            p.mul_(scale)
    return learner, task


def test_a_gentle_field_has_no_gap_and_a_fast_one_has_centimetres():
    gentle, task = _learner(0.05)
    fast, _ = _learner(2.5)
    small = gentle.solver_gaps(0, task)["position"]
    large = fast.solver_gaps(0, task)["position"]
    assert small < 1e-4  # metres: the coarse and fine solutions agree
    assert large > 0.01  # > 1 cm: the coarse steps do not follow this field
    # finer training steps close the gap of the same field
    finer, _ = _learner(2.5, substeps=64)
    assert finer.solver_gaps(0, task)["position"] < large / 10


@pytest.mark.parametrize("overrides", [{"solver": "dopri5", "segments": False},
                                       {"batch": "windows"}])
def test_no_gap_where_training_steps_follow_the_solution_or_the_data(overrides):
    learner, task = _learner(1.0, **overrides)
    assert learner.solver_gaps(0, task) == {"position": None}


def test_a_run_records_the_gap_per_task_and_part(tmp_path):
    results = run_training(resolve_config("hn", "helloworld", "smoke", tasks=2), tmp_path,
                           threads=1, log=None)
    gaps = results["solver_gap_by_part"]["position"]
    assert len(gaps) == 2 and all(np.isfinite(g) and g >= 0 for g in gaps)
