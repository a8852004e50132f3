"""Executing predictions in simulation: true demos succeed, wrong ones fail, bad input is
refused with a message, and the execution R matrix follows the CL formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest

from clfd_bench.data import load_dataset
from clfd_bench.execution.env_pool import get_env
from clfd_bench.execution.execute import execute, execute_predictions, explain_check
from clfd_bench.execution.scoring import sim_fields
from clfd_bench.execution.trace import tool_path


@pytest.fixture(scope="module")
def letter_h() -> np.ndarray:
    return np.asarray(load_dataset("helloworld").tasks[0].demos)  # 'h' in order 0


def test_true_demo_succeeds_reversed_demo_fails(letter_h):
    assert load_dataset("helloworld").tasks[0].name == "h"
    ok = execute_predictions("helloworld", "h", letter_h, demos=[1])
    assert len(ok) == 1 and ok[0].demo == 1
    assert ok[0].success, ok[0].failure_reason
    assert ok[0].failure_reason is None
    assert ok[0].mean_tracking_error < 0.005  # metres: the hand follows the letter closely
    assert ok[0].steps == letter_h.shape[1] + 60  # trajectory + 1 s of settling at 60 Hz

    bad = execute_predictions("helloworld", "h", letter_h[1:2, ::-1], demos=[1])
    assert not bad[0].success
    # The reversed letter starts at the other end: the first command is a jump the real
    # Panda refuses.
    assert bad[0].failure_kind == "reflex"
    assert bad[0].failure_reason.startswith("reflex: cartesian velocity")
    assert "at step 0" in bad[0].failure_reason
    # The wrong shape: the task's own criterion says no, as soon as the ink leaves the letter's
    # tolerance tube (the rollout stops there) ...
    mirrored = letter_h[1, ::-1] + letter_h[1, 0] - letter_h[1, -1]  # reversed, same start
    (wrong,) = execute_predictions("helloworld", "h", mirrored[None], demos=[1])
    assert not wrong.success and wrong.failure_kind == "task"
    assert wrong.failure_reason.startswith("task failed, decided after")
    assert "Hausdorff tolerance" in wrong.failure_reason and wrong.steps < 1060
    # ... or, executed to the end, with every measure of the ink.
    env = get_env("clfd/HelloWorld-h-v3")
    full = execute(env, mirrored, 1, stop_when_decided=False)
    assert not full.success and full.failure_kind == "task" and full.steps == 1060
    assert full.failure_reason.startswith("task not achieved: ")
    # The summary (what the sim cache stores) says which rollout stopped early and keeps the
    # env's final checks; a task failure's reason names the failed checks first.
    assert wrong.summary()["stopped_early"] is True
    assert full.summary()["stopped_early"] is False
    assert full.summary()["checks"] == full.info.get("checks")
    if full.checks():  # envs that report checks (info["checks"])
        failed = [explain_check(c) for c in full.checks() if not c.passed]
        assert failed and full.failure_reason == f"task not achieved: {'; '.join(failed)}"


def test_env_is_reused_between_calls():
    assert get_env("clfd/HelloWorld-h-v3") is get_env("clfd/HelloWorld-h-v3")


def test_bad_predictions_are_refused(letter_h):
    with pytest.raises(ValueError, match=r"must be \[N, T, D\]"):
        execute_predictions("helloworld", "h", letter_h[0])
    nan = letter_h[:2].copy()
    nan[1, 5, 0] = np.nan
    with pytest.raises(ValueError, match=r"demos \[1\] contain NaN"):
        execute_predictions("helloworld", "h", nan)
    with pytest.raises(ValueError, match="out of range"):
        execute_predictions("helloworld", "h", letter_h, demos=[99])
    with pytest.raises(KeyError, match="valid"):
        execute_predictions("helloworld", "zz", letter_h)


def test_tool_path_of_a_letter_lies_on_the_board(letter_h):
    base = get_env("clfd/HelloWorld-h-v3").unwrapped
    path = tool_path(base, letter_h[0])
    assert path.shape == (letter_h.shape[1], 3)
    np.testing.assert_allclose(path[:, :2], letter_h[0])  # HelloWorld data are board metres
    np.testing.assert_allclose(path[:, 2], base.wspec.surface_height)


def test_sim_fields_builds_r_matrix_and_metrics():
    t, f = True, False
    success = [
        [[t, t, t, t], None, None],
        [[t, t, f, f], [t, t, t, t], None],
        [[f, f, f, f], [t, t, t, f], [t, t, t, t]],
    ]
    out = sim_fields(success)
    r = out["sim_accuracy"]
    assert r[0] == [1.0, None, None]
    assert r[1] == [0.5, 1.0, None]
    assert r[2] == [0.0, 0.75, 1.0]
    assert out["success"][2][0] == [f, f, f, f]
    assert out["success"][0][1] is None
    acc = (1 + 0.5 + 1 + 0 + 0.75 + 1) / 6
    bwt = ((0.5 - 1) + (0 - 1) + (0.75 - 1)) / 3
    assert math.isclose(out["sim_cl_metrics"]["ACC"], acc)
    assert math.isclose(out["sim_cl_metrics"]["BWT"], bwt)
    assert math.isclose(out["sim_cl_metrics"]["REM"], 1 - abs(bwt))


def test_sim_fields_leaves_out_tasks_without_env():
    t, f = True, False
    out = sim_fields([[[t, t], None], [[f, t], None]], scored=[True, False])
    assert out["sim_accuracy"] == [[1.0, None], [0.5, None]]
    assert math.isclose(out["sim_cl_metrics"]["ACC"], 0.75)
    assert math.isclose(out["sim_cl_metrics"]["BWT"], -0.5)
    one = sim_fields([[[t, f]]])
    assert one["sim_cl_metrics"] == {"ACC": 0.5, "REM": None, "BWT": None}
    with pytest.raises(ValueError, match=r"success\[1\]\[0\] is missing"):
        sim_fields([[[t]], [None, [t]]])
