"""Re-runs the measurement behind the executability bounds of `clfd_bench.sim.limits`.

`clfd_bench.sim.limits` states how its measured bounds came from the demonstrations (its module
docstring, "How the bounds were measured" and "The demos' orientation stream, and the input
filter"); this module is that procedure, runnable (`python eval/measure_limits.py`):

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
from clfd_bench.execution.replay import replay_trajectory
from clfd_bench.execution.rollout import DEFAULT_SETTLE_S, rollout
from clfd_bench.io import json_safe
from clfd_bench.sim import limits as L
from clfd_bench.sim.limits import (
    CollisionMonitor,
    MotionLimits,
    MotionMonitor,
    Violation,
    floor_height,
)
from clfd_bench.sim.robot import ARM_JOINTS, ROBOT_BODIES

__all__ = ["FAMILIES", "RTOL", "Calibration", "CommandStream", "Comparison", "Derived",
           "Extreme", "RolloutMeasurement", "calibration_env", "calibration_env_ids",
           "choose_cutoff", "compare", "differences", "grid_peaks", "measure",
           "measure_rollout", "stream_peaks", "unbounded_limits"]

#: The replay families of the measurement.
FAMILIES = ("demo", "slower", "faster")
#: Relative tolerance of `compare` (measured vs the constants of `sim.limits`).
RTOL = 0.02
_ROWS = ("velocity", "acceleration", "jerk")
_COLUMNS = ("cartesian", "rotation", *ARM_JOINTS)


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

    def check_tracking(self, pos_err: float, rot_err: float) -> Violation | None:
        self.tracking.append((float(pos_err), float(rot_err)))
        return super().check_tracking(pos_err, rot_err)

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
@dataclasses.dataclass
class RolloutMeasurement:
    """What one rollout measured (all over the trajectory and the settling).

    Attributes:
        env_id, demo, family: which replay.
        success, failure_reason: the env's decision (no limit can fail; a blow-up or the task
            can).
        steps: env steps run; trajectory_steps: of them the trajectory's.
        tracking_position, tracking_rotation: largest hand pose error after a step (m, rad);
        tracking_position_step, tracking_rotation_step: at which step (>= trajectory_steps:
            while settling).
        collision_force: largest normal force (N) of a (robot body, other geom) pair, 0 when the
            robot touched nothing; collision_detail ("link6 hit shelf_board") and
            collision_step.
        raw_peaks: [3, 9] peaks of the raw command (rows velocity, acceleration, jerk; columns
            translation, rotation, joints 1..7).
        rotation_peaks: [R, 3] rotation velocity, acceleration, jerk filtered at each cutoff of
            the rotation grid; joint_peaks: [J, 3, 7] likewise per joint for the joint grid.
        peak_reach: m, largest distance of a commanded position from the shoulder.
        lowest_height, floor_height: m, lowest commanded z and the scene's floor.
        wall_s: seconds of wall time.
    """

    env_id: str
    demo: int
    family: str
    success: bool
    failure_reason: str | None
    steps: int
    trajectory_steps: int
    tracking_position: float
    tracking_position_step: int
    tracking_rotation: float
    tracking_rotation_step: int
    collision_force: float
    collision_detail: str
    collision_step: int | None
    raw_peaks: np.ndarray
    rotation_peaks: np.ndarray
    joint_peaks: np.ndarray
    peak_reach: float
    lowest_height: float
    floor_height: float
    wall_s: float

    def to_json(self) -> dict[str, Any]:
        return json_safe(dataclasses.asdict(self))

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RolloutMeasurement:
        d = dict(d)
        for k in ("raw_peaks", "rotation_peaks", "joint_peaks"):
            d[k] = np.asarray(d[k], dtype=float)
        for k in ("lowest_height", "floor_height"):
            d[k] = -math.inf if d[k] is None else float(d[k])
        return cls(**d)


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


# --------------------------------------------------------------------------- the procedure
def choose_cutoff(grid: Sequence[float], worst_ratio: Sequence[float],
                  margin: float = L.FILTER_MARGIN) -> float | None:
    """The highest cutoff of `grid` whose worst peak ratio (peak / limit, `worst_ratio[i]` for
    `grid[i]`) stays under 1 / `margin`; None when none does."""
    ok = [float(f) for f, r in zip(grid, worst_ratio, strict=True) if r < 1.0 / margin]
    return max(ok) if ok else None


def _bounds(limits: MotionLimits) -> np.ndarray:
    """[3, 9] the limits as `MotionMonitor.bounds`."""
    return MotionMonitor(limits, 1.0, np.zeros(3)).bounds


@dataclasses.dataclass(frozen=True)
class Extreme:
    """The worst value of a quantity over the replays, and where.

    Attributes:
        value: in the quantity's unit; ratio: value / its limit (NaN when it has none).
        env_id, demo, family, step: the replay and the step (None: not recorded).
        quantity: e.g. "rotation acceleration", "joint2 acceleration", "link6 hit shelf".
    """

    value: float
    env_id: str = ""
    demo: int = -1
    family: str = ""
    quantity: str = ""
    ratio: float = math.nan
    step: int | None = None

    @property
    def where(self) -> str:
        """e.g. "Pouring-v3 demo 7 faster" ("-" when no replay)."""
        if not self.env_id:
            return "-"
        return f"{self.env_id.removeprefix('clfd/')} demo {self.demo} {self.family}"


@dataclasses.dataclass
class Derived:
    """The bounds as the procedure derives them from a `Calibration`.

    Attributes:
        n_rollouts, n_successes, failures: the rollouts, how many succeeded, the failures'
            "env demo family: reason".
        tracking_position_measured, tracking_rotation_measured: worst errors (m, rad).
        tracking_position, tracking_rotation: max(floor, TRACKING_FACTOR × worst).
        tracking_by_family: {family: (worst position Extreme, worst rotation Extreme)}
            (their `quantity` says whether the worst step was in the trajectory or settling).
        collision_force_measured: largest robot-scene pair force (N).
        translation_raw: [3] worst raw translation velocity, acceleration, jerk (ratio to the
            limits); translation_raw_passes: all under 1 / margin (so it stays unfiltered).
        rotation_raw, joint_raw: [3] worst raw rotation / joint (any joint) peaks per row.
        rotation_grid, joint_grid: the cutoffs tried; rotation_worst, joint_worst: the worst
            filtered peak (largest ratio over velocity, acceleration, jerk, and the joints) per
            cutoff; rotation_filter_hz, joint_filter_hz: `choose_cutoff` (None: none passes).
        peak_reach: largest distance of a command from the shoulder (m);
        floor_clearance: smallest height of a command above the scene's floor (m).
    """

    n_rollouts: int
    n_successes: int
    failures: list[str]
    tracking_position_measured: Extreme
    tracking_rotation_measured: Extreme
    tracking_position: float
    tracking_rotation: float
    tracking_by_family: dict[str, tuple[Extreme, Extreme]]
    collision_force_measured: Extreme
    translation_raw: list[Extreme]
    translation_raw_passes: bool
    rotation_raw: list[Extreme]
    joint_raw: list[Extreme]
    rotation_grid: tuple[float, ...]
    joint_grid: tuple[float, ...]
    rotation_worst: list[Extreme]
    joint_worst: list[Extreme]
    rotation_filter_hz: float | None
    joint_filter_hz: float | None
    peak_reach: Extreme
    floor_clearance: Extreme


@dataclasses.dataclass
class Calibration:
    """The measurements of many rollouts (`measure`), and what they derive.

    Attributes:
        records: one `RolloutMeasurement` per rollout.
        rotation_grid, joint_grid: the cutoffs of the records' `rotation_peaks` / `joint_peaks`.
        reference: the limits the peaks are judged against (the published ones; not saved
            by `to_json`).
        margin: the filter margin (`sim.limits.FILTER_MARGIN`).
        wall_s: seconds the measurement took.
    """

    records: list[RolloutMeasurement]
    rotation_grid: tuple[float, ...] = L.ROTATION_FILTER_GRID
    joint_grid: tuple[float, ...] = L.JOINT_FILTER_GRID
    reference: MotionLimits = dataclasses.field(default_factory=MotionLimits)
    margin: float = L.FILTER_MARGIN
    wall_s: float = 0.0

    def _extreme(self, values: np.ndarray, quantities: Sequence[str] | None = None,
                 ratios: np.ndarray | None = None, steps: Sequence[int | None] | None = None,
                 by_ratio: bool = False) -> Extreme:
        """The record with the largest value (or ratio) of `values` [N] (one per record)."""
        if not self.records:
            return Extreme(math.nan)
        key = ratios if by_ratio else values
        i = int(np.argmax(key))
        r = self.records[i]
        return Extreme(float(values[i]), r.env_id, r.demo, r.family,
                       quantities[i] if quantities is not None else "",
                       float(ratios[i]) if ratios is not None else math.nan,
                       steps[i] if steps is not None else None)

    def _tracking(self, records: list[RolloutMeasurement]) -> tuple[Extreme, Extreme]:
        sub = Calibration(records, self.rotation_grid, self.joint_grid, self.reference,
                          self.margin)
        pos = np.array([r.tracking_position for r in records])
        rot = np.array([r.tracking_rotation for r in records])

        def when(r: RolloutMeasurement, step: int) -> str:
            return "settling" if step >= r.trajectory_steps else "trajectory"

        return (sub._extreme(pos, [f"position error ({when(r, r.tracking_position_step)})"
                                   for r in records], pos / L.TRACKING_POSITION,
                             [r.tracking_position_step for r in records]),
                sub._extreme(rot, [f"rotation error ({when(r, r.tracking_rotation_step)})"
                                   for r in records], rot / L.TRACKING_ROTATION,
                             [r.tracking_rotation_step for r in records]))

    def _peak_extreme(self, ratios: np.ndarray, values: np.ndarray, names: list[str]
                      ) -> Extreme:
        """ratios, values: [N, K] per record and quantity; the worst ratio's record."""
        flat = ratios.reshape(len(ratios), -1)
        k = np.argmax(flat, axis=1)
        idx = np.arange(len(flat))
        return self._extreme(values.reshape(len(values), -1)[idx, k],
                             [names[j] for j in k], flat[idx, k], by_ratio=True)

    def derive(self) -> Derived:
        """The bounds the procedure derives from the records (`Derived`)."""
        if not self.records:
            raise ValueError("no rollouts measured")
        recs = self.records
        b = _bounds(self.reference)  # [3, 9]
        raw = np.stack([r.raw_peaks for r in recs])  # [N, 3, 9]
        rot = np.stack([r.rotation_peaks for r in recs])  # [N, R, 3]
        joints = np.stack([r.joint_peaks for r in recs])  # [N, J, 3, 7]
        raw_ratio = raw / b
        joint_names = [f"{j} {w}" for w in _ROWS for j in ARM_JOINTS]  # [3 * 7], row major

        translation = [self._extreme(raw[:, i, 0], [f"cartesian {w}"] * len(recs),
                                     raw_ratio[:, i, 0]) for i, w in enumerate(_ROWS)]
        rotation_raw = [self._extreme(raw[:, i, 1], [f"rotation {w}"] * len(recs),
                                      raw_ratio[:, i, 1]) for i, w in enumerate(_ROWS)]
        joint_raw = [self._peak_extreme(raw_ratio[:, i, 2:], raw[:, i, 2:],
                                        [f"{j} {w}" for j in ARM_JOINTS])
                     for i, w in enumerate(_ROWS)]
        rot_ratio = rot / b[None, None, :, 1]  # [N, R, 3]
        rot_worst = [self._peak_extreme(rot_ratio[:, g], rot[:, g],
                                        [f"rotation {w}" for w in _ROWS])
                     for g in range(len(self.rotation_grid))]
        joint_ratio = joints / b[None, None, :, 2:]  # [N, J, 3, 7]
        joint_worst = [self._peak_extreme(joint_ratio[:, g], joints[:, g], joint_names)
                       for g in range(len(self.joint_grid))]

        pos, rot_err = self._tracking(recs)
        by_family = {f: self._tracking([r for r in recs if r.family == f])
                     for f in dict.fromkeys(r.family for r in recs)}
        force = np.array([r.collision_force for r in recs])
        collision = (self._extreme(force, [r.collision_detail for r in recs],
                                   force / L.COLLISION_FORCE, [r.collision_step for r in recs])
                     if force.max() > 0 else Extreme(0.0, quantity="no robot-scene contact",
                                                     ratio=0.0))
        reach = np.array([r.peak_reach for r in recs])
        clearance = np.array([r.lowest_height - r.floor_height for r in recs])
        return Derived(
            n_rollouts=len(recs), n_successes=sum(r.success for r in recs),
            failures=[f"{r.env_id} demo {r.demo} {r.family}: {r.failure_reason or 'task failed'}"
                      for r in recs if not r.success],
            tracking_position_measured=pos, tracking_rotation_measured=rot_err,
            tracking_position=max(L.TRACKING_FLOOR_POSITION, L.TRACKING_FACTOR * pos.value),
            tracking_rotation=max(L.TRACKING_FLOOR_ROTATION, L.TRACKING_FACTOR * rot_err.value),
            tracking_by_family=by_family, collision_force_measured=collision,
            translation_raw=translation,
            translation_raw_passes=all(e.ratio < 1.0 / self.margin for e in translation),
            rotation_raw=rotation_raw, joint_raw=joint_raw,
            rotation_grid=tuple(self.rotation_grid), joint_grid=tuple(self.joint_grid),
            rotation_worst=rot_worst, joint_worst=joint_worst,
            rotation_filter_hz=choose_cutoff(self.rotation_grid, [e.ratio for e in rot_worst],
                                             self.margin),
            joint_filter_hz=choose_cutoff(self.joint_grid, [e.ratio for e in joint_worst],
                                          self.margin),
            peak_reach=self._extreme(reach, ["reach"] * len(recs), reach / L.MAX_REACH),
            floor_clearance=dataclasses.replace(
                self._extreme(-clearance, ["height above the floor"] * len(recs)),
                value=float(np.min(clearance))))

    def to_json(self) -> dict[str, Any]:
        """Everything (records, grids, margin) as JSON data; `from_json` reads it back."""
        return json_safe({"rotation_grid": self.rotation_grid, "joint_grid": self.joint_grid,
                          "margin": self.margin, "wall_s": self.wall_s,
                          "records": [r.to_json() for r in self.records]})

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Calibration:
        """Reads `to_json()` (the reference limits: the published ones)."""
        return cls([RolloutMeasurement.from_json(r) for r in d["records"]],
                   tuple(d["rotation_grid"]), tuple(d["joint_grid"]),
                   margin=float(d["margin"]), wall_s=float(d.get("wall_s", 0.0)))


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


# --------------------------------------------------------------------------- comparison
@dataclasses.dataclass(frozen=True)
class Comparison:
    """One derived value next to its constant in `sim.limits`.

    Attributes:
        name: the constant ("TRACKING_MEASURED_POSITION", ...).
        measured, constant: the derived and the stated value.
        ok: they agree (relative tolerance; cutoffs exactly).
        where: the replay of the worst value; note: what the value is.
    """

    name: str
    measured: Any
    constant: Any
    ok: bool
    where: str = ""
    note: str = ""


def _close(a: float, b: float, rtol: float) -> bool:
    return math.isclose(a, b, rel_tol=rtol, abs_tol=1e-9)


def compare(calibration: Calibration | Derived, rtol: float = RTOL) -> list[Comparison]:
    """Every derived value next to its constant in `clfd_bench.sim.limits`."""
    d = calibration.derive() if isinstance(calibration, Calibration) else calibration
    tp, tr, col = (d.tracking_position_measured, d.tracking_rotation_measured,
                   d.collision_force_measured)
    rot_at = dict(zip(d.rotation_grid, d.rotation_worst, strict=True))
    joint_at = dict(zip(d.joint_grid, d.joint_worst, strict=True))
    rot_e = rot_at.get(d.rotation_filter_hz)
    joint_e = joint_at.get(d.joint_filter_hz)
    worst_t = max(d.translation_raw, key=lambda e: e.ratio)
    return [
        Comparison("rollouts successful", d.n_successes, d.n_rollouts,
                   d.n_successes == d.n_rollouts, note="; ".join(d.failures[:5])),
        Comparison("TRACKING_MEASURED_POSITION", tp.value, L.TRACKING_MEASURED_POSITION,
                   _close(tp.value, L.TRACKING_MEASURED_POSITION, rtol), tp.where,
                   "m, worst hand position error"),
        Comparison("TRACKING_MEASURED_ROTATION", tr.value, L.TRACKING_MEASURED_ROTATION,
                   _close(tr.value, L.TRACKING_MEASURED_ROTATION, rtol), tr.where,
                   "rad, worst hand rotation error"),
        Comparison("TRACKING_POSITION", d.tracking_position, L.TRACKING_POSITION,
                   _close(d.tracking_position, L.TRACKING_POSITION, rtol),
                   note=f"max({L.TRACKING_FLOOR_POSITION}, {L.TRACKING_FACTOR} × worst)"),
        Comparison("TRACKING_ROTATION", d.tracking_rotation, L.TRACKING_ROTATION,
                   _close(d.tracking_rotation, L.TRACKING_ROTATION, rtol),
                   note=f"max({L.TRACKING_FLOOR_ROTATION}, {L.TRACKING_FACTOR} × worst)"),
        Comparison("COLLISION_MEASURED_FORCE", col.value, L.COLLISION_MEASURED_FORCE,
                   _close(col.value, L.COLLISION_MEASURED_FORCE, rtol),
                   col.where if col.value > 0 else "",
                   f"N, {col.quantity}" if col.value > 0 else "N, robot touched nothing"),
        Comparison("TRANSLATION_FILTER_HZ", None if d.translation_raw_passes else "raw fails",
                   L.TRANSLATION_FILTER_HZ,
                   d.translation_raw_passes == (L.TRANSLATION_FILTER_HZ is None),
                   worst_t.where, f"raw {worst_t.quantity} {worst_t.ratio:.2f} × limit"),
        Comparison("ROTATION_FILTER_HZ", d.rotation_filter_hz, L.ROTATION_FILTER_HZ,
                   d.rotation_filter_hz == L.ROTATION_FILTER_HZ,
                   rot_e.where if rot_e else "",
                   f"{rot_e.quantity} {rot_e.ratio:.2f} × limit" if rot_e else "none passes"),
        Comparison("JOINT_FILTER_HZ", d.joint_filter_hz, L.JOINT_FILTER_HZ,
                   d.joint_filter_hz == L.JOINT_FILTER_HZ,
                   joint_e.where if joint_e else "",
                   f"{joint_e.quantity} {joint_e.ratio:.2f} × limit" if joint_e
                   else "none passes"),
    ]


def differences(calibration: Calibration | Derived, rtol: float = RTOL) -> list[Comparison]:
    """The `compare` rows whose derived value disagrees with the constant (empty: the
    measurement reproduces `sim.limits`)."""
    return [c for c in compare(calibration, rtol) if not c.ok]
