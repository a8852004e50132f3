"""Re-runs the measurement behind the executability bounds of `clfd_bench.sim.limits`.

`clfd_bench.sim.limits` states how its measured bounds came from the demonstrations (its module
docstring, "How the bounds were measured" and "The demos' orientation stream, and the input
filter"); this module is that procedure, runnable (`python eval/measure_limits.py`): it
measures (steps 1 and 2); what the measurement derives and its comparison with the constants
(steps 3 and 4) are `clfd_bench.execution.limit_derivation`.

1. Every demo of every env (RoboTasks, HelloWorld letters, LASA shapes; `calibration_env_ids`)
   is replayed as recorded and as the `slower` (2×) and `faster` (1.5×) families
   (`clfd_bench.execution.replay.replay_trajectory`) with `clfd_bench.execution.rollout.rollout`
   (1 s of settling), in an env whose monitors have every bound infinite (`unbounded_limits`;
   the floor check off too) and record, per step, the command (`CommandStream`), the hand's
   pose error and the robot-scene contacts (`calibration_env`, `measure_rollout`).
2. Each recorded command stream is passed again through `MotionMonitor` (the env's own filter
   and finite differences, `stream_peaks`) at every cutoff of `ROTATION_FILTER_GRID` and
   `JOINT_FILTER_GRID`; the translation is judged raw.
3. `Calibration.derive()`: tracking bounds = max(floor, `TRACKING_FACTOR` × the worst error);
   the rotation / joint cutoff = the highest grid value whose worst filtered peak stays under
   1 / `FILTER_MARGIN` of every limit of the channel (`choose_cutoff`); the translation stays
   raw if its raw peaks do; the largest robot-scene contact force.
4. `compare` / `differences`: the derived values next to the constants of `sim.limits`
   (relative tolerance `RTOL`).

Peaks are [3, 9] arrays as `MotionMonitor.peaks`: rows velocity, acceleration, jerk; columns
translation, rotation, joints 1..7. Ratios are peaks divided by the published limits.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from clfd_bench.envs.base import PandaEnv
from clfd_bench.execution.limit_derivation import Calibration, RolloutMeasurement
from clfd_bench.execution.replay import replay_trajectory
from clfd_bench.execution.rollout import DEFAULT_SETTLE_S, rollout
from clfd_bench.sim import limits as L
from clfd_bench.sim.collisions import CollisionMonitor, floor_height
from clfd_bench.sim.limits import MotionLimits, MotionMonitor, Violation
from clfd_bench.sim.robot import ROBOT_BODIES

__all__ = ["FAMILIES", "CommandStream", "calibration_env", "calibration_env_ids", "grid_peaks",
           "measure", "measure_rollout", "stream_peaks", "unbounded_limits"]

#: The replay families of the measurement.
FAMILIES = ("demo", "slower", "faster")


# --------------------------------------------------------------------------- envs and streams
def unbounded_limits(translation_filter_hz: float | None = None,
                     rotation_filter_hz: float | None = None,
                     joint_filter_hz: float | None = None) -> MotionLimits:
    """`MotionLimits` with every bound infinite (velocity, acceleration, jerk, joint ranges,
    reach, tracking, collision force) and the given input-filter cutoffs (default: raw)."""
    inf = math.inf
    return MotionLimits(
        cartesian_velocity=inf, cartesian_acceleration=inf, cartesian_jerk=inf,
        rotation_velocity=inf, rotation_acceleration=inf, rotation_jerk=inf,
        joint_velocity=(inf,) * 7, joint_acceleration=(inf,) * 7, joint_jerk=(inf,) * 7,
        joint_position_low=(-inf,) * 7, joint_position_high=(inf,) * 7, max_reach=inf,
        tracking_position=inf, tracking_rotation=inf, collision_force=inf,
        translation_filter_hz=translation_filter_hz, rotation_filter_hz=rotation_filter_hz,
        joint_filter_hz=joint_filter_hz)


@dataclasses.dataclass
class CommandStream:
    """The commands a `MotionMonitor` saw in one episode.

    Attributes:
        start_pos, start_quat, start_q: [3], [4] (w, x, y, z), [7]: the robot at rest at reset.
        pos: [T, 3] commanded hand positions (m), one per control step.
        quat: [T, 4] commanded hand orientations (w, x, y, z).
        q: [T, 7] joint references (rad).
        control_dt: s between commands.
    """

    start_pos: np.ndarray
    start_quat: np.ndarray
    start_q: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    q: np.ndarray
    control_dt: float

    def __len__(self) -> int:
        return len(self.pos)


def stream_peaks(stream: CommandStream, translation_hz: float | None = None,
                 rotation_hz: float | None = None, joint_hz: float | None = None) -> np.ndarray:
    """[3, 9] the peaks (`MotionMonitor.peaks`: rows velocity, acceleration, jerk; columns
    translation, rotation, joints 1..7) of `stream` after the input filter at the given cutoffs
    (None: raw), computed by a `MotionMonitor` with unbounded limits, so by the env's own
    filter and finite differences."""
    monitor = MotionMonitor(unbounded_limits(translation_hz, rotation_hz, joint_hz),
                            stream.control_dt, np.zeros(3))
    monitor.reset(stream.start_pos, stream.start_quat, stream.start_q)
    for p, r, q in zip(stream.pos, stream.quat, stream.q, strict=True):
        bad = monitor.check_command(p, r, q)
        if bad is not None:  # pragma: no cover - unbounded limits
            raise AssertionError(f"unbounded monitor refused a command: {bad.reason}")
    return monitor.peaks


def grid_peaks(stream: CommandStream,
               rotation_grid: Sequence[float] = L.ROTATION_FILTER_GRID,
               joint_grid: Sequence[float] = L.JOINT_FILTER_GRID
               ) -> tuple[np.ndarray, np.ndarray]:
    """Filtered peaks of `stream` at every cutoff of the grids.

    Returns:
        rotation: [R, 3] rotation velocity, acceleration, jerk at `rotation_grid[i]`;
        joints: [J, 3, 7] joint velocity, acceleration, jerk (joints 1..7) at `joint_grid[j]`.
        (The channels are filtered independently, so one monitor pass serves one cutoff of
        each grid.)
    """
    nr, nj = len(rotation_grid), len(joint_grid)
    rot = np.zeros((nr, 3))
    joints = np.zeros((nj, 3, 7))
    for i in range(max(nr, nj)):
        peaks = stream_peaks(stream, None, rotation_grid[min(i, nr - 1)],
                             joint_grid[min(i, nj - 1)])
        if i < nr:
            rot[i] = peaks[:, 1]
        if i < nj:
            joints[i] = peaks[:, 2:]
    return rot, joints


class _RecordingMotionMonitor(MotionMonitor):
    """A `MotionMonitor` that also keeps the commands and the tracking errors since `reset`."""

    def reset(self, pos: np.ndarray, quat: np.ndarray, q: np.ndarray) -> None:
        super().reset(pos, quat, q)
        quat = np.asarray(quat, dtype=float).reshape(4)
        self.start = (np.array(pos, dtype=float).reshape(3), quat / np.linalg.norm(quat),
                      np.array(q, dtype=float).reshape(7))
        self.commands: list[np.ndarray] = []
        self.tracking: list[tuple[float, float]] = []

    def check_command(self, pos: np.ndarray, quat: np.ndarray, q_ref: np.ndarray
                      ) -> Violation | None:
        self.commands.append(np.concatenate([pos, quat, q_ref]))
        return super().check_command(pos, quat, q_ref)

    def check_tracking(self, pos_err: float, rot_err: float, step: int | None = None
                       ) -> Violation | None:
        self.tracking.append((float(pos_err), float(rot_err)))
        return super().check_tracking(pos_err, rot_err, step)

    def stream(self) -> CommandStream:
        c = np.asarray(self.commands, dtype=float).reshape(-1, 14)
        return CommandStream(*self.start, pos=c[:, :3], quat=c[:, 3:7], q=c[:, 7:],
                             control_dt=self.control_dt)


class _RecordingCollisionMonitor(CollisionMonitor):
    """A `CollisionMonitor` with bound 0 whose `check` keeps the hardest robot-scene contact
    (`worst`, a `Violation` naming the pair) and lets the episode go on."""

    def __init__(self, model: mujoco.MjModel):
        super().__init__(model, ROBOT_BODIES, force_bound=0.0)
        self.worst: Violation | None = None

    def reset(self) -> None:
        super().reset()
        self.worst = None

    def check(self, data: mujoco.MjData, step: int) -> Violation | None:
        hit = super().check(data, step)
        if hit is not None and (self.worst is None or hit.value > self.worst.value):
            self.worst = hit
        return None


def _added_after_calibration() -> dict[str, str]:
    from clfd_bench.envs.robotasks.registry import TASKS, task_module

    notes = ((t.env_name, task_module(t.name, "doc").CALIBRATION) for t in TASKS)
    return {name: note for name, note in notes if note}


#: Envs registered after the bounds of `clfd_bench.sim.limits` were measured: not part of the
#: full measurement (so that it still reproduces the constants), each checked against the
#: bounds with `eval/measure_limits.py --envs ID` instead (its worst values as a fraction of
#: each bound). Name -> what that check found (the task's `doc.CALIBRATION`,
#: `clfd_bench.envs.robotasks.registry`).
ADDED_AFTER_CALIBRATION: dict[str, str] = _added_after_calibration()


def calibration_env_ids() -> list[str]:
    """The envs of the measurement: RoboTasks, the HelloWorld letters, the LASA shapes (not the
    HelloWorld text env, which writes the letters' demos, nor the envs of
    `ADDED_AFTER_CALIBRATION`)."""
    from clfd_bench.envs.registration import env_specs, register_envs

    register_envs()
    later = {f"clfd/{name}-" for name in ADDED_AFTER_CALIBRATION}
    return [i for i, (entry, _) in env_specs().items()
            if not entry.endswith("TextEnv") and not any(i.startswith(p) for p in later)]


def calibration_env(env_id: str, **env_kwargs: Any) -> gym.Env:
    """`gym.make(env_id)` with `unbounded_limits()` and recording monitors (the floor check off
    too), for `measure_rollout`."""
    from clfd_bench.envs.registration import register_envs

    register_envs()
    env = gym.make(env_id, limits=unbounded_limits(), **env_kwargs)
    base = env.unwrapped
    if not isinstance(base, PandaEnv):
        raise TypeError(f"{env_id} is not a clfd-bench env")
    old = base.motion_monitor
    base.motion_monitor = _RecordingMotionMonitor(old.limits, old.control_dt, old.shoulder,
                                                  floor_height=-math.inf)
    base.collision_monitor = _RecordingCollisionMonitor(base.model)
    return env


# --------------------------------------------------------------------------- one rollout
def measure_rollout(env: gym.Env, trajectory: np.ndarray | list[np.ndarray], demo: int,
                    env_id: str = "", family: str = "", settle_s: float = DEFAULT_SETTLE_S,
                    rotation_grid: Sequence[float] = L.ROTATION_FILTER_GRID,
                    joint_grid: Sequence[float] = L.JOINT_FILTER_GRID) -> RolloutMeasurement:
    """Runs `trajectory` ([T, D] data units, as `rollout`) from demo `demo`'s start in `env`
    (made by `calibration_env`) and measures it (`RolloutMeasurement`)."""
    base = env.unwrapped
    monitor, contacts = base.motion_monitor, base.collision_monitor
    if not isinstance(monitor, _RecordingMotionMonitor):
        raise TypeError("measure_rollout needs an env made by calibration_env()")
    t0 = time.perf_counter()
    result = rollout(env, trajectory, demo=demo, settle_s=settle_s)
    stream = monitor.stream()
    rot, joints = grid_peaks(stream, rotation_grid, joint_grid)
    err = np.asarray(monitor.tracking, dtype=float).reshape(-1, 2)
    ip, ir = (int(np.argmax(err[:, 0])), int(np.argmax(err[:, 1]))) if len(err) else (0, 0)
    hit = contacts.worst
    return RolloutMeasurement(
        env_id=env_id or (env.spec.id if env.spec is not None else ""), demo=int(demo),
        family=family, success=result.success,
        failure_reason=result.info.get("failure_reason"), steps=result.steps,
        trajectory_steps=len(result.tracking_error_pos),
        tracking_position=float(err[ip, 0]) if len(err) else 0.0, tracking_position_step=ip,
        tracking_rotation=float(err[ir, 1]) if len(err) else 0.0, tracking_rotation_step=ir,
        collision_force=float(contacts.peak), collision_detail=hit.detail if hit else "",
        collision_step=hit.step if hit else None, raw_peaks=monitor.peaks.copy(),
        rotation_peaks=rot, joint_peaks=joints, peak_reach=monitor.peak_reach,
        lowest_height=monitor.lowest_height, floor_height=floor_height(base.model),
        wall_s=time.perf_counter() - t0)


# --------------------------------------------------------------------------- every rollout
def measure(env_ids: Sequence[str] | None = None, families: Sequence[str] = FAMILIES,
            demos: Sequence[int] | None = None, progress: bool = True,
            settle_s: float = DEFAULT_SETTLE_S,
            rotation_grid: Sequence[float] = L.ROTATION_FILTER_GRID,
            joint_grid: Sequence[float] = L.JOINT_FILTER_GRID) -> Calibration:
    """Replays every demo (or `demos`) of every env of `env_ids` (default
    `calibration_env_ids()`) as each family, with all bounds infinite, and measures each
    rollout (`measure_rollout`).

    Args:
        env_ids: gymnasium ids ("clfd/Pouring-v3", ...).
        families: replay families (`clfd_bench.execution.perturb.FAMILIES` names).
        demos: demo indices per env (None: all; indices an env does not have are skipped).
        progress: a tqdm bar (`clfd_bench.progress`, which also honours CLFD_NO_PROGRESS).
        settle_s: seconds of settling after each trajectory.
        rotation_grid, joint_grid: the cutoffs (Hz) to measure the filtered peaks at.

    Returns:
        A `Calibration` (its `derive()` gives the bounds).
    """
    from clfd_bench.progress import progress as bar

    t0 = time.perf_counter()
    ids = list(calibration_env_ids() if env_ids is None else env_ids)
    envs = [(i, calibration_env(i)) for i in ids]  # first, to count the rollouts
    plan: list[list[tuple[int, str]]] = []
    for _, env in envs:
        n = env.unwrapped.num_demos
        js = range(n) if demos is None else [j for j in demos if 0 <= j < n]
        plan.append([(j, f) for j in js for f in families])
    records: list[RolloutMeasurement] = []
    pbar = bar(total=sum(len(p) for p in plan), desc="limits",
               **({} if progress else {"disable": True}))
    try:
        for (env_id, env), jobs in zip(envs, plan, strict=True):
            for j, f in jobs:
                pbar.set_postfix_str(f"{env_id.removeprefix('clfd/')} {j} {f}", refresh=False)
                traj = replay_trajectory(env.unwrapped, j, f)
                records.append(measure_rollout(env, traj, j, env_id, f, settle_s,
                                               rotation_grid, joint_grid))
                pbar.update(1)
            env.close()
    finally:
        pbar.close()
        for _, env in envs:
            env.close()
    return Calibration(records, tuple(rotation_grid), tuple(joint_grid),
                       wall_s=time.perf_counter() - t0)
