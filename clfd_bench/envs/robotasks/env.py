"""The RoboTasks environments (one class, `RoboTaskEnv(task=...)`, for every task of
`clfd_bench.envs.robotasks.registry`): `clfd/BoxOpening-v3`, ..., `clfd/Scoop-v3`. The scene of
a task is its folder's `scene.SCENE`; the docstring is assembled from the tasks' `doc.py`
(`clfd_bench.envs.robotasks.doc`)."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces

from clfd_bench.envs.base import PandaEnv
from clfd_bench.envs.robotasks.common import Scene
from clfd_bench.envs.robotasks.doc import env_docstring
from clfd_bench.envs.robotasks.registry import task_module
from clfd_bench.envs.robotasks.specs import TASK_DATASETS, TASKS, check_task_spec, load_task_spec
from clfd_bench.resources import resource_path
from clfd_bench.sim.grasp import Grasp, add_grasp_constraint
from clfd_bench.sim.limits import MotionLimits
from clfd_bench.sim.render import CameraSpec
from clfd_bench.sim.robot import FINGER_OPEN, gripper_ctrl

#: Settle steps the gripper stays closed after the trajectory before it opens (0.25 s at 60 Hz).
HOLD_STEPS = 15
#: Default episode length: a 1000-sample RoboTasks demo plus 1 s of settling at 60 Hz.
DEFAULT_HORIZON = 1060


def make_scene(task: str, doc: dict[str, Any]) -> Scene:
    """The scene of a RoboTasks task (its folder's `scene.SCENE`), configured by its spec."""
    if task not in TASKS:
        raise KeyError(f"no RoboTasks scene {task!r}; valid: {sorted(TASKS)}")
    return task_module(task, "scene").SCENE(doc)


class RoboTaskEnv(PandaEnv):
    __doc__ = None  # set below from the tasks' docs and specs (numbers stay in step with them)

    gripper_action = True

    def __init__(self, task: str, render_mode: str | None = None, *,
                 physics_dt: float | None = None, ik_iterations: int = 1, width: int = 640,
                 height: int = 480, spec: dict[str, Any] | None = None,
                 limits: str | MotionLimits | None = "panda"):
        if task not in TASKS:
            raise KeyError(f"unknown RoboTasks task {task!r}; valid: {list(TASKS)}")
        self.dataset = TASK_DATASETS[task]
        self.task_name = task
        self.spec_doc = load_task_spec(task) if spec is None else check_task_spec(spec, task)
        self.scene = make_scene(task, self.spec_doc)
        self._start = np.asarray(self.spec_doc["start"]["qpos"], dtype=float)
        if physics_dt is None:
            physics_dt = float(self.spec_doc["task"].get("physics_dt", 0.002))
        self._scene_info = {}
        super().__init__(render_mode, physics_dt=physics_dt, ik_iterations=ik_iterations,
                         width=width, height=height, limits=limits)

    # ------------------------------------------------------------------ hooks
    def camera(self) -> CameraSpec:
        """The task's view (`[camera]` of the spec: framing the demos' workspace), or a view of
        the robot and all the tasks' props."""
        cam = self.spec_doc.get("camera")
        if not cam:
            return CameraSpec(lookat=(0.4, -0.28, 0.2), distance=1.45, azimuth=155.0,
                              elevation=-22.0)
        return CameraSpec(lookat=tuple(float(v) for v in cam["lookat"]),
                          distance=float(cam["distance"]), azimuth=float(cam["azimuth"]),
                          elevation=float(cam["elevation"]))

    def _task_xml(self):
        return resource_path("tasks", f"{self.task_name}.xml")

    def _edit_spec(self, spec: mujoco.MjSpec) -> None:
        self.scene.edit_spec(spec)
        add_grasp_constraint(spec, self.scene.grasp_spec)

    def _bind(self) -> None:
        self.scene.bind(self.model)
        self.grasp = Grasp(self.model, self.scene.grasp_spec, control_dt=self.control_dt)

    @property
    def num_demos(self) -> int:
        return len(self._start)

    def _start_qpos(self, demo: int) -> np.ndarray:
        return self._start[demo].copy()

    def _reset_task(self, demo: int) -> None:
        self._scene_info: dict[str, Any] = {}
        mujoco.mj_kinematics(self.model, self.data)
        self.scene.reset(self.data, demo, self.grasp)
        mujoco.mj_kinematics(self.model, self.data)
        self.grasp.attach(self.data)
        self.data.qpos[self.robot.finger_qpos] = self.scene.grasp_spec.closed_opening
        self.scene.start_record(self.data, self.grasp)
        _, self._scene_info = self.scene.success(self.data, self.grasp)

    def _default_horizon(self, demo: int) -> int:
        return DEFAULT_HORIZON

    def _apply_gripper(self, command: float) -> None:
        closed = float(command) >= self.scene.grasp_spec.release_below
        opening = self.scene.grasp_spec.closed_opening if closed else FINGER_OPEN
        self.data.ctrl[self.robot.gripper_act] = gripper_ctrl(opening)
        if not closed and self.grasp.held(self.data):
            self.grasp.release(self.data, "opened")
            self.scene.on_release(self.data, self.grasp)

    def _task_observation_space(self) -> dict[str, spaces.Space]:
        return self.scene.observation_space()

    def _task_obs(self) -> dict[str, np.ndarray]:
        return self.scene.observation(self.data)

    def _after_step(self) -> None:
        if self.grasp.held(self.data):
            self.grasp.update(self.data)
            if not self.grasp.held(self.data):
                self.scene.on_release(self.data, self.grasp)
        self.scene.track(self.data, self.grasp)

    def _is_success(self, final: bool) -> bool:
        if self.scene.needs_release and self.grasp.held(self.data):
            # nothing is placed while the gripper holds it; on the last step the scene still
            # reports its checks (its `let_go` check fails), so a report can say what was measured
            if final:
                _, self._scene_info = self.scene.success(self.data, self.grasp)
            return False
        ok, self._scene_info = self.scene.success(self.data, self.grasp)
        return ok

    def evaluate(self) -> dict[str, Any]:
        """As `PandaEnv.evaluate`; a failed episode (a motion limit, a collision) reports the
        scene's measures and checks as they stand at its end, not as the last step before the
        failure left them (they are the same for a stepped and a planned rollout, which does
        not judge every step)."""
        if self._failure_reason is not None:
            _, self._scene_info = self.scene.success(self.data, self.grasp)
        return super().evaluate()

    def _task_info(self) -> dict[str, Any]:
        info = {"task": self.task_name, "held": self.grasp.held(self.data),
                "release_reason": self.grasp.release_reason,
                "slip_cause": self.grasp.slip_cause, "grip_load_max": self.grasp.max_load}
        info.update(self._scene_info)
        return info

    def _task_state(self) -> dict[str, Any]:
        return {"grasp": self.grasp.state(), "scene_info": dict(self._scene_info),
                "scene": self.scene.scene_state()}

    def _restore_task_state(self, state: dict[str, Any]) -> None:
        self.grasp.restore(state["grasp"])
        self._scene_info = dict(state["scene_info"])
        self.scene.restore_scene_state(state["scene"])

    def settle_actions(self, last_action: np.ndarray, steps: int) -> np.ndarray:
        """Actions [steps, 8] after the trajectory: hold the last pose, first `HOLD_STEPS` with
        the gripper closed (the arm comes to rest), then open (release) for the rest; tasks
        with `[task] release_after = false` (pouring: the cup is never let go) keep holding."""
        actions = np.repeat(np.asarray(last_action, dtype=float)[None], steps, axis=0)
        if self.spec_doc["task"].get("release_after", True):
            actions[min(HOLD_STEPS, steps):, 7] = 0.0
        return actions


RoboTaskEnv.__doc__ = env_docstring()
