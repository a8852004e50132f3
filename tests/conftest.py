"""Shared test set-up: no progress bars, deterministic threads."""

from __future__ import annotations

import ast
import functools
import os
from pathlib import Path

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


@pytest.fixture(scope="session")
def eval_script():
    """``eval_script(name)``: the module of ``eval/<name>.py`` (the scripts are not a package)."""
    import importlib.util

    def load(name: str):
        path = Path(__file__).resolve().parents[1] / "eval" / f"{name}.py"
        spec = importlib.util.spec_from_file_location(name, path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod

    return load


@functools.cache
def _shares_a_fixture(path: Path) -> bool:
    """Whether the test file at `path` defines a module-, class- or package-scoped fixture."""
    try:
        tree = ast.parse(path.read_text())
    except (OSError, SyntaxError):
        return False
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and any(
                k.arg == "scope" and isinstance(k.value, ast.Constant)
                and k.value.value in ("module", "class", "package") for k in node.keywords):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if name == "fixture":
                return True
    return False


try:
    from xdist.scheduler import LoadScopeScheduling
except ImportError:  # pytest-xdist is a dev dependency; without it the suite runs in one process
    LoadScopeScheduling = None

if LoadScopeScheduling is not None:

    class FixtureScopeScheduling(LoadScopeScheduling):
        """``--dist loadscope``, refined: a test file that defines a module- or class-scoped
        fixture (a trained run, a built site) is one unit of work, so the fixture is made once,
        on one worker; every other test is a unit of its own, dealt to whichever worker is
        free. (``--dist loadgroup`` with ``xdist_group`` marks would say the same, but on
        pytest 9.2 it silently stops grouping: pytest-xdist issue 1386.)"""

        def _split_scope(self, nodeid: str) -> str:
            module = nodeid.split("::", 1)[0]
            return module if _shares_a_fixture(self.config.rootpath / module) else nodeid

    def pytest_xdist_make_scheduler(config, log):
        """`bash run.sh test` runs ``-n auto --dist loadscope``: schedule it by
        `FixtureScopeScheduling`."""
        if config.getvalue("dist") == "loadscope":
            return FixtureScopeScheduling(config, log)
        return None
