"""Shared test set-up: no progress bars, deterministic threads."""

from __future__ import annotations

import os

os.environ.setdefault("CLFD_NO_PROGRESS", "1")
os.environ.setdefault("MUJOCO_GL", "egl")


import numpy as np  # noqa: E402
import pytest  # noqa: E402

from clfd_bench.envs.base import PandaEnv  # noqa: E402


class BarePoseEnv(PandaEnv):
    """A bare Panda env (floor only, the base class's default 7-D pose action + gripper) at
    openbox demo 0's start configuration; module level, so that it pickles."""

    gripper_action = True
    dataset = "robotasks"
    task_name = "openbox"
    starts: np.ndarray

    @property
    def num_demos(self) -> int:
        return len(self.starts)

    def _start_qpos(self, demo: int) -> np.ndarray:
        return np.asarray(self.starts[demo]).copy()


@pytest.fixture(scope="session")
def pose_env_cls():
    """`BarePoseEnv` with its start configuration (backward IK tracking of openbox demo 0)."""
    from clfd_bench.data import load_task
    from clfd_bench.sim.robot import robot_model
    from clfd_bench.sim.start_configs import backward_start_configs

    task = load_task("robotasks", "openbox")
    BarePoseEnv.starts = backward_start_configs(robot_model(), task.positions[:1],
                                                task.quaternions[:1])
    return BarePoseEnv


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Under pytest-xdist (`bash run.sh test` runs ``-n auto --dist loadgroup``): the tests of a
    module that share a module- or class-scoped fixture run on one worker, so that fixture
    (a trained run, a built site) is made once; every other test is dealt out alone. Runs
    before xdist reads the groups (``tryfirst``)."""
    if not config.pluginmanager.hasplugin("xdist"):
        return
    for item in items:
        info = getattr(item, "_fixtureinfo", None)
        if info is None:
            continue
        if any(d.scope in ("module", "class", "package")
               for defs in info.name2fixturedefs.values() for d in defs):
            item.add_marker(pytest.mark.xdist_group(item.module.__name__))
