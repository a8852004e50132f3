"""The RoboTasks tasks live one folder each, listed in one registry: every per-task table is
derived from it, the env never imports the build-time derivation, the simulator fingerprint
covers what the envs run (and only that), and tasks/README.md's table is the one the tasks'
words generate. No simulation."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym

from clfd_bench.envs.registration import ROBOTASKS_ENVS, env_id_for, register_envs
from clfd_bench.envs.robotasks import doc
from clfd_bench.envs.robotasks.common import Scene
from clfd_bench.envs.robotasks.registry import TASKS, task_module
from clfd_bench.envs.robotasks.specs import TASK_DATASETS
from clfd_bench.execution.fingerprint import _sim_files
from clfd_bench.resources import resource_path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "clfd_bench"


def test_every_table_comes_from_the_registry():
    register_envs()
    assert ROBOTASKS_ENVS == {t.env_name: t.name for t in TASKS}
    assert TASK_DATASETS == {t.name: t.dataset for t in TASKS}
    for task in TASKS:
        env_id = env_id_for(task.dataset, task.name)
        assert gym.spec(env_id).kwargs == {"task": task.name}
        assert resource_path("tasks", f"{task.name}.xml").is_file(), task.name
        assert issubclass(task_module(task.name, "scene").SCENE, Scene), task.name
    from clfd_bench.execution import bench, limit_calibration, task_variants

    assert bench.DEFAULT_ENVS[2:] == tuple(env_id_for(t.dataset, t.name) for t in TASKS)
    assert set(limit_calibration.ADDED_AFTER_CALIBRATION) == {
        t.env_name for t in TASKS if task_module(t.name, "doc").CALIBRATION}
    from clfd_bench.envs.robotasks.variants import NEARBY

    assert set(task_variants.VARIANTS) == {env_id_for(t.dataset, t.name) for t in TASKS}
    for t in TASKS:  # every scene: the nearby edits, then its own variants
        own = task_module(t.name, "variants", optional=True)
        assert task_variants.VARIANTS[env_id_for(t.dataset, t.name)] == [
            *NEARBY, *(own.VARIANTS if own is not None else [])]


def test_making_an_env_imports_no_derivation():
    code = ("import sys, gymnasium as gym, clfd_bench; gym.make('clfd/Scoop-v3'); "
            "print(sorted(m for m in sys.modules if 'derive' in m or 'variants' in m))")
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, env={**os.environ, "PYTHONPATH": path}, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_the_fingerprint_covers_what_the_envs_run_and_only_that():
    hashed = {name for name, _ in _sim_files()}
    envs = PACKAGE / "envs"
    for path in envs.rglob("*.py"):
        name = path.relative_to(PACKAGE).as_posix()
        build_time = path.name in ("derive.py", "derive_common.py", "variants.py", "doc.py")
        assert (name in hashed) is not build_time, name
    for task in TASKS:
        assert f"envs/robotasks/{task.name}/scene.py" in hashed
        assert f"envs/robotasks/{task.name}/success.py" in hashed
        assert f"tasks/{task.name}.toml" in hashed


def test_the_tasks_readme_table_is_the_generated_one():
    text = resource_path("tasks", "README.md").read_text(encoding="utf-8")
    assert doc.replace_readme_table(text) == text, (
        "tasks/README.md's table differs from the tasks' doc.py: edit those, then run python "
        "eval/make_task_specs.py --docs")


def test_the_env_docstring_has_every_tasks_rules():
    from clfd_bench.envs.robotasks import RoboTaskEnv

    text = " ".join(RoboTaskEnv.__doc__.split())
    for task in TASKS:
        own = task_module(task.name, "doc")
        assert f"- {task.name}: " in text, task.name
        assert f"(`{env_id_for(task.dataset, task.name)}`" in text, task.name
        assert own.INFO.split(",")[0] in text, task.name
