"""Rollouts logged with rerun-sdk: the .rrd file opens with rerun's own reader and holds the
paths, poses, prediction, demonstration and the outcome of each rollout."""

from __future__ import annotations

import numpy as np
import pytest

from clfd_bench.data import load_dataset
from clfd_bench.execution.env_pool import get_env
from clfd_bench.execution.execute import execute
from clfd_bench.viz.rerun_log import RolloutLogger, rrd_entity_paths


def test_rrd_opens_with_rerun_and_holds_the_rollout(tmp_path):
    demos = np.asarray(load_dataset("helloworld").tasks[0].demos)  # 'h'
    env = get_env("clfd/HelloWorld-h-v3")
    ok = execute(env, demos[0], 0, trace=True)
    bad = execute(env, demos[0, ::-1], 0, trace=True)
    path = tmp_path / "logs" / "rollouts.rrd"
    with RolloutLogger(path, recording_name="test") as log:
        log.log_rollout("after_task_0/h/demo_0", env.unwrapped, ok, prediction=demos[0],
                        demonstration=demos[0])
        log.log_rollout("after_task_0/h/reversed", env.unwrapped, bad,
                        prediction=demos[0, ::-1])
    assert path.is_file() and not list(path.parent.glob("*.tmp"))
    counts = rrd_entity_paths(path)
    steps = ok.steps + 1  # the reset state, then every step
    for name in ("tool", "hand"):
        assert counts[f"/after_task_0/h/demo_0/{name}"] >= steps
    for name in ("prediction", "demonstration", "tool_path", "ink", "events"):
        assert f"/after_task_0/h/demo_0/{name}" in counts
    assert "/after_task_0/h/reversed/demonstration" not in counts
    assert counts["/events"] == 2  # one outcome per rollout

    from rerun.chunk import RrdReader

    store = RrdReader(path).store()
    columns = store.schema().column_names()
    assert any(c.startswith("/after_task_0/h/demo_0/prediction:LineStrips3D") for c in columns)


def test_logger_refuses_wrong_suffix_and_missing_trace(tmp_path):
    with pytest.raises(ValueError, match=r"end in \.rrd"):
        RolloutLogger(tmp_path / "log.txt")
    env = get_env("clfd/HelloWorld-h-v3")
    demos = np.asarray(load_dataset("helloworld").tasks[0].demos)
    res = execute(env, demos[0, :120], 0, settle_s=0.0)
    log = RolloutLogger(tmp_path / "x.rrd")
    with pytest.raises(ValueError, match="trace=True"):
        log.log_rollout("a", env.unwrapped, res, prediction=demos[0, :120])
    log.close()
