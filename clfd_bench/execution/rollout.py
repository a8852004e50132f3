"""Execute a whole trajectory in a clfd-bench environment and decide success."""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym
import numpy as np

from clfd_bench.envs.base import CONTROL_HZ, PandaEnv
from clfd_bench.sim.collisions import CollisionMonitor
from clfd_bench.sim.limits import MotionMonitor

#: Default time the scene settles after the trajectory (release, objects coming to rest), s.
DEFAULT_SETTLE_S = 1.0


@dataclasses.dataclass
class RolloutResult:
    """Outcome of one `rollout`.

    Attributes:
        success: the env's success decision after the trajectory and settling.
        tracking_error_pos: [T] position error (m) of the tracked frame after each trajectory
            step (NaN after an early end).
        tracking_error_rot: [T] rotation error (rad), likewise.
        info: the env's final info dict (with `failure_reason`, None when no failure).
        frames: rendered frames [H, W, 3] uint8 when `record=True`, else None.
        ee_path: [T, 3] tracked frame position after each trajectory step (NaN after an
            early end).
        steps: number of env steps run (trajectory + settling).
        stopped_early: with `stop_when_decided`, the env's `decided_failure()` when the rollout
            stopped on it before the horizon, else None.
        timing: lean rollouts: {"ik_s": seconds of IK, "physics_s": seconds in MuJoCo's
            physics steps}; None when stepped through `env.step`.
    """

    success: bool
    tracking_error_pos: np.ndarray
    tracking_error_rot: np.ndarray
    info: dict[str, Any]
    frames: list[np.ndarray] | None
    ee_path: np.ndarray
    steps: int
    stopped_early: dict[str, Any] | None = None
    timing: dict[str, float] | None = None


def _unwrap(env: gym.Env) -> PandaEnv:
    base = env.unwrapped
    if not isinstance(base, PandaEnv):
        raise TypeError(f"rollout needs a clfd-bench env (PandaEnv), got {type(base).__name__}")
    return base


def rollout(env: gym.Env, trajectory: np.ndarray, demo: int | None = None,
            settle_s: float = DEFAULT_SETTLE_S, record: bool = False, fps: float = 30.0,
            seed: int | None = None, stop_when_decided: bool = False,
            lean: bool | None = None) -> RolloutResult:
    """Runs `trajectory` through `env` at the data rate (one sample per 60 Hz step), then the
    env's settle actions for `settle_s` (RoboTasks: gripper opens; writing: pen holds), then
    decides success.

    Args:
        env: a clfd-bench env (from `gymnasium.make("clfd/...")` or the class).
        trajectory: [T, D] in the data units of the env's dataset: 7-D poses (px, py, pz m,
            qw, qx, qy, qz) for RoboTasks, 2-D points for writing (HelloWorld: m, LASA: native
            units); for `clfd/HelloWorld-v3`, see its docstring.
        demo: the demo whose start configuration and scene to reset to (writing: whose
            trajectory is the target); None draws one with `seed`.
        settle_s: seconds after the trajectory.
        record: render frames (needs `render_mode="rgb_array"`).
        fps: frame rate of the recording (every round(60 / fps)-th step is rendered).
        seed: reset seed.
        stop_when_decided: stop as soon as the env reports a failure its criterion has
            already decided (`PandaEnv.decided_failure`, e.g. writing: ink outside the shape's
            tolerance). The success decision is the one the full rollout would give (False);
            `info` then holds the partial episode's measures and `decided_failure`, and the
            failure kind is the task's even if the full rollout would have hit a motion limit
            later. Ignored with `record` (a video shows the whole rollout).
        lean: drive the env's core directly (`PandaEnv.plan_commands`, `run_plan`: the IK
            and the controller's checks for the whole stream first, then the physics; no
            observation or info per step) instead of calling `env.step` per action. Same
            verdicts, reasons and final state, to the last bit. None (default): lean unless
            recording or the env is wrapped beyond Gymnasium's defaults (`plain_env`).

    Returns:
        A `RolloutResult`.
    """
    base = _unwrap(env)
    actions = base.trajectory_to_actions(trajectory)
    if len(actions) < 1:
        raise ValueError("trajectory is empty; pass at least one sample")
    if record and base.render_mode != "rgb_array":
        raise ValueError("record=True needs an env made with render_mode='rgb_array'")
    settle_steps = max(0, int(round(settle_s * CONTROL_HZ)))
    horizon = len(actions) + settle_steps
    T = len(actions)
    stop = stop_when_decided and not record
    if lean is None:
        lean = not record and plain_env(env)
    if lean:
        if record:
            raise ValueError("lean=True does not render frames; pass lean=None to record")
        stream = actions
        if settle_steps:
            stream = np.concatenate([actions, base.settle_actions(actions[-1], settle_steps)])
        stream = base.check_actions(stream)  # a bad action is an error before anything runs
        env.reset(seed=seed, options={"demo": demo, "horizon": horizon})
        steps, decided, ee, tracking, timing = _run_planned(base, stream, stop)
        frames = None
        err_pos, err_rot, ee_path = tracking[:T, 0].copy(), tracking[:T, 1].copy(), ee[:T]
    else:
        steps, decided, frames, err_pos, err_rot, ee_path = _step_through(
            env, base, actions, settle_steps, horizon, demo, seed, record, fps, stop)
        timing = None
    info = base.evaluate()
    if decided is not None:
        info["is_success"] = False  # decided: the full rollout's answer (the env's own too)
        info["stopped_early"] = dict(decided, horizon=horizon, stopped_at=steps)
    return RolloutResult(success=bool(info["is_success"]), tracking_error_pos=err_pos,
                         tracking_error_rot=err_rot, info=info, frames=frames, ee_path=ee_path,
                         steps=steps, stopped_early=decided, timing=timing)


#: Commands planned at a time by a lean rollout: a rollout that stops early (a failure, a
#: decided failure) wastes the IK of at most this many commands.
PLAN_CHUNK = 128


def _run_planned(base: PandaEnv, stream: np.ndarray, stop: bool) -> tuple:
    """The lean rollout: plans (`PandaEnv.plan_commands`) and runs (`run_plan`) the stream
    `PLAN_CHUNK` commands at a time, until it ends or stops. Returns (steps, decided,
    ee_pos [N, 3], tracking [N, 2] (NaN for steps not run), timing)."""
    n = len(stream)
    ee = np.full((n, 3), np.nan)
    tracking = np.full((n, 2), np.nan)
    steps, ik_s, physics_s = 0, 0.0, 0.0
    decided: dict[str, Any] | None = None
    for start in range(0, n, PLAN_CHUNK):
        plan = base.plan_commands(stream[start:start + PLAN_CHUNK])
        run = base.run_plan(plan, stop_when_decided=stop)
        ee[start:start + run.steps] = run.ee_pos[:run.steps]
        tracking[start:start + run.steps] = run.tracking[:run.steps]
        steps += run.steps
        ik_s += plan.ik_s
        physics_s += run.physics_s
        if run.ended or run.decided is not None:
            decided = run.decided
            break
    return steps, decided, ee, tracking, {"ik_s": ik_s, "physics_s": physics_s}


def _step_through(env: gym.Env, base: PandaEnv, actions: np.ndarray, settle_steps: int,
                  horizon: int, demo: int | None, seed: int | None, record: bool, fps: float,
                  stop: bool) -> tuple:
    """The rollout through Gymnasium's `step`, one action at a time (wrappers see every
    step). Returns (steps, decided, frames, err_pos [T], err_rot [T], ee_path [T, 3])."""
    env.reset(seed=seed, options={"demo": demo, "horizon": horizon})
    every = max(1, int(round(CONTROL_HZ / fps)))
    frames: list[np.ndarray] | None = [env.render()] if record else None
    T = len(actions)
    err_pos = np.full(T, np.nan)
    err_rot = np.full(T, np.nan)
    ee_path = np.full((T, 3), np.nan)
    steps = 0
    ended = False
    decided: dict[str, Any] | None = None
    for t in range(T):
        obs, _, terminated, truncated, info = env.step(actions[t])
        steps += 1
        err_pos[t], err_rot[t] = info["tracking_error"]
        ee_path[t] = obs["ee_pos"]
        if record and steps % every == 0:
            frames.append(env.render())
        if terminated or truncated:
            ended = True
            break
        if stop and (decided := base.decided_failure()) is not None:
            ended = True
            break
    if not ended and settle_steps:
        for action in base.settle_actions(actions[-1], settle_steps):
            _, _, terminated, truncated, info = env.step(action)
            steps += 1
            if record and steps % every == 0:
                frames.append(env.render())
            if terminated or truncated:
                break
            if stop and (decided := base.decided_failure()) is not None:
                break
    return steps, decided, frames, err_pos, err_rot, ee_path


#: Wrappers that do not change what a step does (Gymnasium's defaults of `gym.make`).
_PLAIN_WRAPPERS = (gym.wrappers.OrderEnforcing, gym.wrappers.PassiveEnvChecker)


def plain_env(env: gym.Env) -> bool:
    """Whether `rollout` may drive `env`'s core directly (`PandaEnv.plan_commands` /
    `run_plan`) and give what stepping it gives: only Gymnasium's default wrappers around a
    `PandaEnv` whose `step` and monitors are the library's own. Any other wrapper (e.g. a
    tracer that records every step) or a replaced monitor gets `step` called per action."""
    while isinstance(env, gym.Wrapper):
        if type(env) not in _PLAIN_WRAPPERS:
            return False
        env = env.env
    base = env
    return (isinstance(base, PandaEnv) and type(base).step is PandaEnv.step
            and type(base.motion_monitor) in (MotionMonitor, type(None))
            and type(base.collision_monitor) in (CollisionMonitor, type(None)))
