"""`PandaEnv`: the shared Gymnasium environment of every clfd-bench task.

One class runs the loop every task shares; tasks (RoboTasks scenes, writing) are subclasses that
fill in hooks. Per `step`:

1. the action is checked (NaN/inf raise a ValueError naming the entries: bad input is an
   error, not a failure) and mapped to a target pose of the tracked frame (`_action_to_target`);
2. mink IK (`clfd_bench.sim.ik.PoseTracker`, on the robot-only model; posture task gain
   `IK_POSTURE_GAIN`) moves its joint solution towards the target: one control step at the data
   rate (60 Hz);
3. the command (target pose, IK joint reference) is checked as the real Panda's controller
   would (`clfd_bench.sim.limits.MotionMonitor`): a target beyond the reach or below the floor
   is "unreachable"; a joint reference outside the joint ranges, or a velocity, acceleration or
   jerk of the commanded pose or joint reference over libfranka's limits (finite differences at
   60 Hz from the robot at rest at its reset pose, after the input filter that
   `clfd_bench.sim.limits` documents) is a "reflex". A refused command is not executed;
4. the Menagerie joint position servos follow the IK solution through `n_substeps` physics steps
   (~2 ms each), the reference interpolated linearly within the control period with velocity
   feed-forward (the command leads by kv/kp × the reference velocity, which removes the servo's
   steady lag);
5. a physics blow-up (MuJoCo bad qpos/qvel/qacc warnings or non-finite state) is a "blowup";
   then a robot link, hand or finger pushing a non-robot geom harder than the collision bound
   (`CollisionMonitor`; the pen and a held prop touch the scene by design and do not count) is
   a "collision"; then a hand pose error to the command over the tracking bound is "tracking";
6. task hooks run (`_after_step`); the observation, sparse reward (1.0 when `_is_success`) and
   info are returned.

**Failures.** Any of the failures of steps 3 and 5 ends the episode: `terminated=True`, reward
0, `info["failure_reason"]` a sentence naming the limit and the step (e.g. ``reflex: cartesian
velocity 3.2 m/s > 1.7 m/s at step 0``, ``collision: link6 hit shelf_board with 85 N > 20 N at
step 412``) and `info["failure"]` = {kind: "reflex" | "tracking" | "unreachable" | "collision" |
"blowup", limit, value, bound, unit, step} (steps count from 0). The robot stops as the real
one does: from then on it holds the joint configuration it had when the failure was detected,
whatever is commanded, and every further step returns `terminated=True` again. The limits are
`clfd_bench.sim.limits.panda_limits()` (constructor argument `limits`: "panda" default, a
`MotionLimits` instance, or None to switch every check but the blow-up off, for debugging).

Hooks for subclasses (all optional except those marked *):

- `tool` (class attribute): None or "pen".
- `_task_xml() -> Path | None`: the task scene MJCF (from `tasks/`), attached to the world.
- `_edit_spec(spec)`: edit the composed `MjSpec` before compiling (options, attachments).
- `_bind()`: after compiling; look up ids of task objects.
- `num_demos` (property)*: number of demos `reset(options={"demo": j})` accepts.
- `_start_qpos(demo) -> [7]`: arm start configuration (default `home`).
- `_reset_task(demo)`: place objects / set task state for demo j (robot already placed).
- `_default_horizon(demo) -> int`: episode length in steps (truncation).
- `_action_space() -> Box` and `_action_to_target(action) -> (pos [3], quat [4], gripper)`:
  default: 7-D pose (+1 gripper command in [0, 1], 1 = closed, when `gripper_action`).
- `_apply_gripper(cmd)`: default sets the Menagerie gripper actuator (1 = closed, 0 = open).
- `_task_observation_space() -> dict[str, Space]` and `_task_obs() -> dict[str, ndarray]`.
- `_on_command(action)`: the action reaches the controller (once per command, refused or not).
- `_after_step()`: after the physics of each step (e.g. record ink, update attachments).
- `_is_success(final: bool) -> bool`: `final` is True on the episode's last step and in
  `evaluate()`; cheap checks may ignore it, expensive ones may only run when it is True.
- `_task_info() -> dict`: extra info entries.
- `decided_failure() -> dict | None`: a failure the task's criterion has already decided,
  whatever the rest of the episode does (default: never; see the method).
- `trajectory_to_actions(traj [T, D]) -> [T, A]`: dataset units -> actions (default: 7-D
  poses, gripper closed).
- `dataset`, `task_name` (class/instance attributes) and `demo_trajectory(j)`: the demos
  `clfd-bench replay` executes (default: the data layer's task demos).
- `settle_actions(last_action [A], steps) -> [steps, A]`: actions after the trajectory
  (default: hold the last action; RoboTasks: open the gripper).
- `_task_state() -> dict` / `_restore_task_state(state)`: extra episode state for pickling.
- `camera() -> CameraSpec` and `_decorate(scene)`: what `render()` shows.

Envs pickle: the constructor arguments and the episode state are stored and the model is rebuilt
on unpickling. Envs are deterministic per seed (the only randomness is the demo drawn when
`reset` gets no `options["demo"]`).
"""

from __future__ import annotations

import pathlib
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from clfd_bench.envs.control import _BLOWUP_WARNINGS, CommandExecution, check_finite_action
from clfd_bench.sim.collisions import CollisionMonitor, floor_height
from clfd_bench.sim.ik import PoseTracker
from clfd_bench.sim.limits import MotionLimits, MotionMonitor, panda_limits
from clfd_bench.sim.render import CameraSpec, OffscreenRenderer
from clfd_bench.sim.robot import (
    FINGER_OPEN,
    HOME_QPOS,
    ROBOT_BODIES,
    SHOULDER_JOINT,
    RobotIndex,
    attach_spec,
    gripper_ctrl,
    panda_spec,
    robot_model,
)

CONTROL_HZ = 60.0
#: Gain of the IK's posture task in the envs (`PoseTracker(posture_gain=...)`): the posture
#: error is corrected by 10 % per control step, so the arm's null-space motion stays slow. With
#: the full correction (gain 1) the arm swings through its null space at the joint velocity
#: limits while the wrist turns (Pouring demo 7: joints 2 and 5 at 2.175 / 2.61 rad/s for a
#: hand turning at 0.4 rad/s, even 2× slower), and the servos' lag puts the hand up to 12 mm off
#: the command; with 0.1 the same replays' joints stay under 1.3 rad/s and the 2× slower one
#: within 5.5 mm. The hand's path is the same (the IK error stays under 0.5 mm either way).
IK_POSTURE_GAIN = 0.1
_STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION


def _resolve_limits(limits: str | MotionLimits | None) -> MotionLimits | None:
    if limits is None or isinstance(limits, MotionLimits):
        return limits
    if limits == "panda":
        return panda_limits()
    raise ValueError(f"limits must be 'panda', a MotionLimits or None, got {limits!r}")


class PandaEnv(CommandExecution, gym.Env):
    """Base class of the clfd-bench Panda environments (see the module docstring for the hooks).

    Args:
        render_mode: None or "rgb_array" (offscreen, EGL when MUJOCO_GL=egl).
        physics_dt: target physics step, seconds; the control period (1/60 s) is split into
            round(control_dt / physics_dt) substeps.
        ik_iterations: mink QP iterations per control step (their dt splits the control period).
        width, height: rendered image size.
        limits: "panda" (default: `clfd_bench.sim.limits.panda_limits()`), a `MotionLimits`, or
            None (no reflex, reach, tracking or collision checks; physics blow-ups still end the
            episode). Subclasses forward it.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": int(CONTROL_HZ)}
    #: the data layer dataset and task this env executes (used by replay and the harness).
    dataset: str = ""
    task_name: str = ""
    #: None or "pen": the tool the robot holds.
    tool: str | None = None
    #: whether the default action has a gripper command (8-D instead of 7-D).
    gripper_action: bool = False
    #: default workspace bounds of the default pose action's position, metres.
    workspace_low = np.array([-1.0, -1.0, 0.0])
    workspace_high = np.array([1.0, 1.0, 1.3])

    def __new__(cls, *args: Any, **kwargs: Any):
        obj = super().__new__(cls)
        obj._ctor_args = (args, dict(kwargs))
        return obj

    def __init__(self, render_mode: str | None = None, *, physics_dt: float = 0.002,
                 ik_iterations: int = 1, width: int = 640, height: int = 480,
                 limits: str | MotionLimits | None = "panda"):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}"
                             f", got {render_mode!r}")
        if not physics_dt > 0:
            raise ValueError(f"physics_dt must be > 0, got {physics_dt}")
        self.render_mode = render_mode
        self.control_dt = 1.0 / CONTROL_HZ
        self.n_substeps = max(1, int(round(self.control_dt / physics_dt)))
        self._substep_fractions = np.arange(1, self.n_substeps + 1) / self.n_substeps
        self.width, self.height = int(width), int(height)

        spec = panda_spec(self.tool)
        xml = self._task_xml()
        if xml is not None:
            attach_spec(spec, mujoco.MjSpec.from_file(str(xml)))
        self._edit_spec(spec)
        self.model = spec.compile()
        self.model.opt.timestep = self.control_dt / self.n_substeps
        self.data = mujoco.MjData(self.model)
        #: live views of the blow-up warning counters (read every step)
        self._warn_numbers = self.data.warning.number
        self._qpos, self._qvel = self.data.qpos, self.data.qvel
        self.robot = RobotIndex(self.model)
        self.tracker = PoseTracker(robot_model(self.tool), iterations=ik_iterations,
                                   dt=self.control_dt / ik_iterations,
                                   posture_gain=IK_POSTURE_GAIN)
        self._bind()
        self.limits = _resolve_limits(limits)
        self.motion_monitor: MotionMonitor | None = None
        self.collision_monitor: CollisionMonitor | None = None
        if self.limits is not None:
            mujoco.mj_kinematics(self.model, self.data)
            shoulder = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, SHOULDER_JOINT)
            self.motion_monitor = MotionMonitor(
                self.limits, self.control_dt, shoulder=self.data.xanchor[shoulder],
                floor_height=floor_height(self.model))
            self.collision_monitor = CollisionMonitor(self.model, ROBOT_BODIES,
                                                      self.limits.collision_force)

        self.action_space = self._action_space()
        obs_spaces: dict[str, spaces.Space] = {
            "ee_pos": spaces.Box(-np.inf, np.inf, (3,), np.float64),
            "ee_quat": spaces.Box(-1.0, 1.0, (4,), np.float64),
            "qpos": spaces.Box(-np.inf, np.inf, (7,), np.float64),
            "qvel": spaces.Box(-np.inf, np.inf, (7,), np.float64),
        }
        obs_spaces.update(self._task_observation_space())
        self.observation_space = spaces.Dict(obs_spaces)

        self._renderer: OffscreenRenderer | None = None
        self.demo = 0
        self.horizon = 0
        self._step_count = 0
        self._q_ref_prev = HOME_QPOS.copy()
        self._failure_reason: str | None = None
        self._failure: dict[str, Any] | None = None
        self._hold_q: np.ndarray | None = None
        self._last_success = False
        self._tracking_error = (0.0, 0.0)
        self._ik_error = (0.0, 0.0)
        self._target_pos = np.zeros(3)
        self._target_quat = np.array([1.0, 0.0, 0.0, 0.0])
        #: the blow-up warning counters at the reset ([3] ints)
        self._warn_base = [0] * len(_BLOWUP_WARNINGS)
        #: seconds spent in MuJoCo's physics steps since construction (`_drive`)
        self.physics_s = 0.0
        self._reset_robot(0, HOME_QPOS)

    # ------------------------------------------------------------------ hooks (override)
    def _task_xml(self) -> pathlib.Path | None:
        return None

    def _edit_spec(self, spec: mujoco.MjSpec) -> None:
        pass

    def _bind(self) -> None:
        pass

    @property
    def num_demos(self) -> int:
        raise NotImplementedError(f"{type(self).__name__} must define num_demos")

    def _start_qpos(self, demo: int) -> np.ndarray:
        return HOME_QPOS.copy()

    def _reset_task(self, demo: int) -> None:
        pass

    def _default_horizon(self, demo: int) -> int:
        return 1200

    def _action_space(self) -> spaces.Box:
        low = np.concatenate([self.workspace_low, -np.ones(4)])
        high = np.concatenate([self.workspace_high, np.ones(4)])
        if self.gripper_action:
            low, high = np.append(low, 0.0), np.append(high, 1.0)
        return spaces.Box(low, high, dtype=np.float64)

    def _action_to_target(self, action: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, float | None]:
        quat = action[3:7]
        if np.linalg.norm(quat) < 1e-9:
            quat = self._target_quat  # a zero quaternion carries no orientation: keep the last
        return action[:3], quat, (float(action[7]) if self.gripper_action else None)

    def _apply_gripper(self, command: float) -> None:
        """command in [0, 1]: 1 = closed, 0 = fully open."""
        self.data.ctrl[self.robot.gripper_act] = gripper_ctrl(
            (1.0 - min(max(float(command), 0.0), 1.0)) * FINGER_OPEN)

    def _task_observation_space(self) -> dict[str, spaces.Space]:
        return {}

    def _task_obs(self) -> dict[str, np.ndarray]:
        return {}

    def _after_step(self) -> None:
        pass

    def _is_success(self, final: bool) -> bool:
        return False

    def _task_info(self) -> dict[str, Any]:
        return {}

    def _task_state(self) -> dict[str, Any]:
        return {}

    def _restore_task_state(self, state: dict[str, Any]) -> None:
        pass

    def camera(self) -> CameraSpec:
        """The camera `render()` uses."""
        return CameraSpec()

    def _decorate(self, scene: mujoco.MjvScene) -> None:
        """Adds visual-only geoms to a rendered frame (e.g. the ink of the writing tasks)."""

    def trajectory_to_actions(self, trajectory: np.ndarray) -> np.ndarray:
        """Dataset trajectory [T, D] (data units) -> actions [T, A].

        Default: 7-D poses (position m, quaternion w,x,y,z), plus gripper closed (1.0) when the
        action has a gripper command.
        """
        traj = np.asarray(trajectory, dtype=float)
        if traj.ndim != 2 or traj.shape[1] != 7:
            raise ValueError(f"{type(self).__name__} expects a pose trajectory [T, 7] "
                             f"(px, py, pz in m, qw, qx, qy, qz), got shape {traj.shape}")
        if self.gripper_action:
            traj = np.concatenate([traj, np.ones((len(traj), 1))], axis=1)
        return traj

    def demo_trajectory(self, demo: int) -> np.ndarray:
        """Demo `demo` of the env's task in data units ([T, D]), as `rollout` takes it.
        Default: from the data layer via (`dataset`, `task_name`)."""
        if not self.dataset or not self.task_name:
            raise NotImplementedError(f"{type(self).__name__} sets no dataset/task_name")
        from clfd_bench.data import load_task

        return np.asarray(load_task(self.dataset, self.task_name).demos[demo], dtype=float)

    def settle_actions(self, last_action: np.ndarray, steps: int) -> np.ndarray:
        """Actions [steps, A] run after the trajectory (release, settle): default holds the last
        action."""
        return np.repeat(np.asarray(last_action, dtype=float)[None], steps, axis=0)

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Resets to demo `options["demo"]`'s start (default: a demo drawn with the seed).

        Options:
            demo: int, the demo whose start configuration and scene to use.
            horizon: int, episode length in steps (default: the task's).
        """
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - {"demo", "horizon"}
        if unknown:
            raise ValueError(f"unknown reset options {sorted(unknown)}; valid: ['demo', 'horizon']")
        n = self.num_demos
        if options.get("demo") is None:
            demo = int(self.np_random.integers(n))
        else:
            demo = int(options["demo"])
            if not 0 <= demo < n:
                raise ValueError(f"demo must be in [0, {n}), got {demo}")
        self.demo = demo
        self._reset_robot(demo, self._start_qpos(demo))
        self._reset_task(demo)
        mujoco.mj_forward(self.model, self.data)
        horizon = options.get("horizon")
        self.horizon = int(horizon) if horizon is not None else self._default_horizon(demo)
        if self.horizon < 1:
            raise ValueError(f"horizon must be >= 1, got {self.horizon}")
        return self._get_obs(), self._info()

    def _reset_robot(self, demo: int, q0: np.ndarray) -> None:
        q0 = np.asarray(q0, dtype=float).reshape(7)
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self.robot.arm_qpos] = q0
        self.data.ctrl[self.robot.arm_act] = q0
        self.data.qpos[self.robot.finger_qpos] = 0.0
        self._apply_gripper(1.0)
        self.tracker.reset(q0)
        self._q_ref_prev = q0.copy()
        hand = self.robot.hand_body
        mujoco.mj_kinematics(self.model, self.data)
        self._target_pos = self.data.xpos[hand].copy()
        self._target_quat = self.data.xquat[hand].copy()
        self._step_count = 0
        self._failure_reason = None
        self._failure = None
        self._hold_q = None
        self._last_success = False
        self._tracking_error = (0.0, 0.0)
        self._ik_error = (0.0, 0.0)
        self._warn_base = [int(self.data.warning[w].number) for w in _BLOWUP_WARNINGS]
        if self.motion_monitor is not None:
            self.motion_monitor.reset(self._target_pos, self._target_quat, q0)
            self.collision_monitor.reset()

    def step(self, action: np.ndarray):
        action = np.asarray(action, dtype=np.float64)
        if action.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, "
                             f"got {action.shape}")
        check_finite_action(action)
        if self._hold_q is not None:  # stopped after a failure: hold, ignore the command
            self._drive(self._hold_q)
            self._step_count += 1
            return self._end_step(terminated=True)

        pos, quat, grip = self._action_to_target(action)
        q_ref, ik_pe, ik_re = self.tracker.track(pos, quat)
        pos = np.asarray(pos, dtype=float).copy()
        quat = self.tracker._target_quat.copy()
        monitor = self.motion_monitor
        refused = monitor.check_command(pos, quat, q_ref) if monitor is not None else None
        if self._execute_command(action, pos, quat, grip, q_ref, (ik_pe, ik_re), refused):
            return self._end_step(terminated=True)
        truncated_now = self._step_count >= self.horizon
        self._last_success = bool(self._is_success(final=truncated_now))
        return self._end_step(terminated=False)

    def _end_step(self, terminated: bool):
        if terminated:
            self._last_success = False
        truncated = self._step_count >= self.horizon and not terminated
        obs = self._get_obs()
        if self.render_mode == "rgb_array" and self._renderer is None:
            self._make_renderer()
        return obs, (1.0 if self._last_success else 0.0), terminated, truncated, self._info()

    def evaluate(self) -> dict[str, Any]:
        """Decides success now (as at the episode's end) and returns the info dict."""
        if self._failure_reason is None:
            self._last_success = bool(self._is_success(final=True))
        return self._info()

    def decided_failure(self) -> dict[str, Any] | None:
        """A task failure already certain, whatever the remaining steps of the episode do, or
        None.

        Lets a harness stop a rollout as soon as its outcome is known
        (`clfd_bench.execution.rollout.rollout(stop_when_decided=True)`): once this is not
        None, `_is_success(final=True)` is False at every later step up to the horizon, so
        stopping changes no success decision. It assumes the episode runs to `horizon` (as a
        rollout does) and stays set until the next `reset`. Default: None (the task decides at
        the end); tasks with a monotone check override it (the writing envs: ink outside the
        shape's tolerance, too many steps with the pen off the board).

        Returns:
            None, or {check: the criterion's check that failed, step: the step it was decided
            at (from 0), value, bound (the measured value and the bound it broke, the
            criterion's units), reason: a sentence}.
        """
        return None

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called with render_mode=None; pass render_mode='rgb_array'")
            return None
        if self._renderer is None:
            self._make_renderer()
        return self._renderer.render(self.data, self._decorate)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ------------------------------------------------------------------ internals
    def _make_renderer(self) -> None:
        self._renderer = OffscreenRenderer(self.model, self.width, self.height, self.camera())

    def _get_obs(self) -> dict[str, np.ndarray]:
        hand = self.robot.hand_body
        obs = {
            "ee_pos": self.data.xpos[hand].copy(),
            "ee_quat": np.minimum(np.maximum(self.data.xquat[hand], -1.0), 1.0),
            "qpos": self.data.qpos[self.robot.arm_qpos].copy(),
            "qvel": self.data.qvel[self.robot.arm_dof].copy(),
        }
        obs.update(self._task_obs())
        return obs

    def _info(self) -> dict[str, Any]:
        info = {
            "is_success": self._last_success,
            "tracking_error": self._tracking_error,
            "ik_error": self._ik_error,
            "demo": self.demo,
            "step": self._step_count,
            "failure_reason": self._failure_reason,
            "failure": None if self._failure is None else dict(self._failure),
        }
        info.update(self._task_info())
        return info

    # ------------------------------------------------------------------ pickling
    def __getstate__(self) -> dict[str, Any]:
        size = mujoco.mj_stateSize(self.model, _STATE_SPEC)
        physics = np.empty(size)
        mujoco.mj_getState(self.model, self.data, physics, _STATE_SPEC)
        return {
            "ctor_args": self._ctor_args,
            "np_random": self._np_random.bit_generator.state if self._np_random else None,
            "np_random_seed": self._np_random_seed,
            "physics": physics,
            "warnings": np.array([[w.number, w.lastinfo] for w in self.data.warning]),
            "tracker_q": self.tracker.configuration.q.copy(),
            "tracker_posture": self.tracker.posture_task.target_q.copy(),
            "episode": {k: getattr(self, k) for k in (
                "demo", "horizon", "_step_count", "_q_ref_prev", "_failure_reason", "_failure",
                "_hold_q", "_last_success", "_tracking_error", "_ik_error", "_target_pos",
                "_target_quat", "_warn_base")},
            "monitor": (self.motion_monitor.state() if self.motion_monitor is not None
                        else None),
            "collision_peak": (self.collision_monitor.peak if self.collision_monitor is not None
                               else 0.0),
            "task": self._task_state(),
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        args, kwargs = state["ctor_args"]
        self._ctor_args = (args, kwargs)
        self.__init__(*args, **kwargs)
        if state["np_random"] is not None:
            self._np_random = np.random.Generator(np.random.PCG64())
            self._np_random.bit_generator.state = state["np_random"]
            self._np_random_seed = state["np_random_seed"]
        mujoco.mj_setState(self.model, self.data, state["physics"], _STATE_SPEC)
        for w, (number, lastinfo) in zip(self.data.warning, state["warnings"], strict=True):
            w.number, w.lastinfo = int(number), int(lastinfo)
        mujoco.mj_forward(self.model, self.data)
        self.tracker.configuration.update(state["tracker_q"])
        self.tracker.posture_task.set_target(state["tracker_posture"])
        for k, v in state["episode"].items():
            setattr(self, k, v)
        self.tracker.set_target(self._target_pos, self._target_quat)
        if self.motion_monitor is not None and state.get("monitor") is not None:
            self.motion_monitor.set_state(state["monitor"])
            self.collision_monitor.peak = state["collision_peak"]
        self._restore_task_state(state["task"])
