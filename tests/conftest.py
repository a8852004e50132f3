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
