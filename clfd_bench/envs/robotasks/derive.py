"""Derives the RoboTasks task specs (`tasks/<task>.toml`) from the demonstrations: build time
only. `eval/make_task_specs.py` writes what `derive_spec(task)` returns, each number's procedure
as a comment next to it; no env imports this module or the tasks' `derive.py` (the specs they
write are what the envs read, and what the simulator fingerprint hashes).

`derive_spec(task)` recomputes every data-derived number of a scene, its success thresholds and
the per-demo start configurations. What each task derives is in its folder's `derive.py`
(`<task>/derive.py`: `DESIGN`, `OBSERVER`, `derive`); every task also gets start
configurations by backward IK tracking from the common end pose
(`clfd_bench.sim.start_configs.backward_start_configs`), each checked by kinematic forward
tracking (a demo whose backward start does not track gets the IK solution of its first pose
from `home` instead, if that tracks), and a camera framing the demos' workspace.

Margins (design constants, `derive_common.POSITION_MARGIN`, `TURN_MARGIN_DEG`): a bound taken
from the demos is widened by what good-but-imperfect executions add: 1 cm (the smooth noise and
start offsets an execution must survive) + 5 mm (servo lag and IK error). Design constants (not
data-derived) sit in each task's `DESIGN` (over the shared defaults of `derive_common`) and in
the task MJCF.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from clfd_bench.data import load_dataset
from clfd_bench.envs.robotasks.derive_common import (
    camera_from_demos,
    replay_demos,
    start_configurations,
)
from clfd_bench.envs.robotasks.registry import TASKS, task_module
from clfd_bench.envs.robotasks.specs import TASK_DATASETS, load_task_spec

__all__ = ["DESIGN", "OBSERVER", "derive_spec", "start_configurations"]

#: Every task's design constants (its `derive.DESIGN`).
DESIGN: dict[str, dict[str, Any]] = {t.name: task_module(t.name, "derive").DESIGN for t in TASKS}
#: Every task's observer arguments (its `derive.OBSERVER`; docs/execution.md, "Where every bound
#: comes from").
OBSERVER: dict[str, dict[str, dict[str, str]]] = {
    t.name: task_module(t.name, "derive").OBSERVER for t in TASKS}

#: Comments on design entries every spec has.
_COMMON_COMMENTS = {
    "grasp": {
        "contact": "grip model (clfd_bench.sim.grasp): the contact the pads make with the prop; "
                   "the grip breaks when the wrench on the prop exceeds its capacity",
        "mu": "design: fingertip friction coefficient (stock Franka fingertips, 0.3-0.7 on "
              "PET / ceramic / wood)",
        "grip_force": "Franka Hand continuous grasp force, N (datasheet; 140 N peak)",
        "filter_steps": "control steps (60 Hz) the grip's load ratio is averaged over",
    },
    "camera": {"lookat": "the middle of the demos' grasp points (bounding box)"},
}


def derive_spec(task_name: str, with_starts: bool = True,
                comments: dict[str, dict[str, str]] | None = None
                ) -> dict[str, dict[str, Any]]:
    """The spec of a RoboTasks task as {table: {key: value}}, from the dataset.

    Args:
        task_name: a task of `registry.TASKS` ("openbox", ..., "scoop").
        with_starts: compute the start configurations (~20 s per task); False keeps those of
            the existing `tasks/<task>.toml`.
        comments: if given, filled with {table: {key: how the value was derived}} for
            `specs.dumps_task_spec`.
    """
    if task_name not in TASK_DATASETS:
        raise KeyError(f"no RoboTasks task {task_name!r}; valid: {sorted(TASK_DATASETS)}")
    own = task_module(task_name, "derive")
    dataset = TASK_DATASETS[task_name]
    ds = load_dataset(dataset)
    task = ds.tasks[ds.task_names.index(task_name)]
    design = own.DESIGN
    if with_starts:
        starts, methods, errors = start_configurations(task.positions, task.quaternions)
        # as the spec will hold them (10 decimals), so that a run with `with_starts=False`
        # derives from the very same starts
        starts = np.array([[round(float(v), 10) for v in row] for row in starts])
    else:
        old = load_task_spec(task_name)
        starts = np.asarray(old["start"]["qpos"], dtype=float)
        methods = old["derived"]["start_method"]
        errors = old["derived"]["start_forward_tracking_error_max"]
    derived = own.derive(task, design, starts)
    doc: dict[str, dict[str, Any]] = {
        "task": {"name": task_name, "dataset": dataset, **design["task"]},
        "grasp": {**design["grasp"], **derived.get("grasp", {})},
        "scene": dict(derived["scene"]),
        "success": {**design["success"], **derived.get("success", {})},
    }
    if "solver" in design:
        doc["solver"] = dict(design["solver"])
    doc["camera"] = camera_from_demos(task, design)
    doc["derived"] = dict(derived["derived"])
    # How the derived scene executes the demos (no motion-limit checks), for the record.
    infos = replay_demos(task, {**doc, "start": {"qpos": starts}})
    doc["derived"]["demo_replay_success"] = [bool(i["is_success"]) for i in infos]
    doc["derived"]["demo_replay_grip_load_max"] = [float(i["grip_load_max"]) for i in infos]
    doc["derived"]["start_method"] = methods
    doc["derived"]["start_forward_tracking_error_max"] = errors
    doc["start"] = {"qpos": starts}
    if comments is not None:
        for table, entries in _COMMON_COMMENTS.items():
            comments.setdefault(table, {}).update(entries)
        for table, entries in derived.get("comments", {}).items():
            comments.setdefault(table, {}).update(entries)
        for table, entries in own.OBSERVER.items():
            comments.setdefault(table, {}).update(entries)
        comments.setdefault("derived", {}).update({
            "demo_replay_success": "each demo replayed in this scene (+ 1 s settling, no "
                                   "motion-limit checks): success",
            "demo_replay_grip_load_max": "largest filtered load of the grip over that replay "
                                         "(1 = its capacity)"})
    return doc
