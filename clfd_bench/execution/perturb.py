"""Perturbation families: trajectories a success criterion must accept, and ones it must reject.

A success criterion is only as good as the wrong trajectories it rejects and the good ones it
keeps. Each family turns a demonstration `[T, D]` (data units: 7-D poses px, py, pz m,
qw, qx, qy, qz for RoboTasks; 2-D points for writing) into a variant that an observer would
judge the same way every time:

| family | expect | what it is |
|---|---|---|
| `demo` | succeed | the demonstration itself |
| `slower` | succeed | time-stretched 2× (positions linear, orientations slerped) |
| `faster` | succeed | time-compressed 1.5× |
| `noise` | succeed | smooth, zero-mean noise on the positions (poses 1 cm, pen 3 mm on the board) |
| `start-offset` | succeed | 0.5 s min-jerk move 1 cm off the start, back on the demo by mid-way |
| `reverse` | fail | the demonstration backwards in time |
| `other-task` | fail | demo j of the dataset's next task |
| `stop-early` | fail | the first half, then nothing |
| `shortcut` | fail | a straight min-jerk line start → end over the demo's duration |
| `rush-wait` | fail | the same line in 10 % of the duration, then waiting at the end |
| `mirror` | fail | the path reflected about its start → end chord, p' = 2·chord(t) − p |
| `drift` | fail | an offset growing linearly to 5 cm (poses), 15 % of the size ≥ 2 cm (pen) |
| `overrun` | fail | (pen only) the demo, then on past its end by the drift's distance (below) |
| `teleport` | fail | the end pose commanded from the first step |
| `frozen-orientation` | fail | (poses only) the orientation held at its first value |

`overrun` is `stop-early`'s other side: a pen that runs on past the end of the letter by as
much as `drift` ends off it, in the direction the demo's last stretch of that length runs (its
chord), at the pace the demo took for that stretch (a min-jerk move from rest to rest). The
letter itself is the demo's, so only where the ink ends tells it from the demo. It applies to
pen trajectories only: the ink is the outcome a writing env judges and a stroke past the end
is part of it, while in a scene the hand's motion after the task is done leaves the outcome
unchanged (the scene judges the objects, not where the hand stops).

Random families (`noise`, `start-offset`, `drift`) draw from a generator seeded with the family
name and the demo index, so a table is reproducible. Distances are physical (metres on the
robot): `units_per_m` converts them to data units (LASA: 1 / 0.003).
"""

from __future__ import annotations

import dataclasses
import zlib
from collections.abc import Callable

import numpy as np

from clfd_bench.data.resample import min_jerk_profile, resample, slerp

__all__ = ["FAMILIES", "Family", "PerturbContext", "family_names", "min_jerk", "perturb",
           "resample"]


@dataclasses.dataclass(frozen=True)
class PerturbContext:
    """What a family may use besides the trajectory.

    Attributes:
        demo: demo index (seeds the random families).
        units_per_m: data units per metre on the robot (1 for poses and HelloWorld; LASA 333.3).
        other: [T', D] the same demo of the dataset's next task (for `other-task`), or None.
    """

    demo: int = 0
    units_per_m: float = 1.0
    other: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class Family:
    """One perturbation family: `expect` is "succeed" or "fail"; `poses_only` families apply
    to 7-D pose trajectories only, `pen_only` ones to pen (point) trajectories only."""

    name: str
    expect: str
    description: str
    fn: Callable[[np.ndarray, PerturbContext], np.ndarray]
    poses_only: bool = False
    pen_only: bool = False


# ----------------------------------------------------------------------------- helpers
def _is_pose(traj: np.ndarray) -> bool:
    return traj.shape[1] == 7


def min_jerk(n: int) -> np.ndarray:
    """[n] the minimum-jerk profile 10s³ − 15s⁴ + 6s⁵ from 0 to 1 over n samples."""
    return min_jerk_profile(np.linspace(0.0, 1.0, int(n)))


def _line(start: np.ndarray, end: np.ndarray, n: int) -> np.ndarray:
    """[n, D] a min-jerk straight move from `start` to `end` (quaternions slerped)."""
    p = min_jerk(n)
    out = start + p[:, None] * (end - start)
    if len(start) == 7:
        out[:, 3:] = [slerp(start[3:], end[3:], w) for w in p]
    return out


def _rng(name: str, demo: int) -> np.random.Generator:
    return np.random.default_rng([zlib.crc32(name.encode()), int(demo)])


def _unit(rng: np.random.Generator, dim: int) -> np.ndarray:
    v = rng.normal(size=dim)
    return v / np.linalg.norm(v)


def _pos(traj: np.ndarray) -> slice:
    return slice(0, 3) if _is_pose(traj) else slice(0, traj.shape[1])


# ----------------------------------------------------------------------------- families
def _demo(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    return traj.copy()


def _slower(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    return resample(traj, 2 * len(traj) - 1)


def _faster(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    return resample(traj, int(np.ceil(len(traj) / 1.5)))


def _noise(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    amp_m = 0.01 if _is_pose(traj) else 0.003
    rng = _rng("noise", ctx.demo)
    T, sl = len(traj), _pos(traj)
    dim = sl.stop - sl.start
    t = np.arange(T) / max(T - 1, 1)
    noise = np.zeros((T, dim))
    for _ in range(3):  # three sinusoids of 1.5-4 cycles over the trajectory per axis
        cycles = rng.uniform(1.5, 4.0, size=dim)
        phase = rng.uniform(0, 2 * np.pi, size=dim)
        noise += np.sin(2 * np.pi * cycles * t[:, None] + phase)
    noise -= noise[0]  # starts where the demo starts: no jump at the first command
    ramp = np.clip(t / 0.1, 0.0, 1.0)
    noise *= (ramp * ramp * (3 - 2 * ramp))[:, None]
    noise *= amp_m * ctx.units_per_m / np.abs(noise).max()
    out = traj.copy()
    out[:, sl] += noise
    return out


def _start_offset(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    T, sl = len(traj), _pos(traj)
    dim = sl.stop - sl.start
    offset = 0.01 * ctx.units_per_m * _unit(_rng("start-offset", ctx.demo), dim)
    half = max(T // 2, 2)
    w = np.zeros(T)
    w[:half] = 0.5 * (1 + np.cos(np.pi * np.arange(half) / (half - 1)))
    out = traj.copy()
    out[:, sl] += w[:, None] * offset
    away = _line(traj[0], out[0], 30)  # 0.5 s at 60 Hz: leave the start to the offset point
    return np.concatenate([away, out[1:]])


def _reverse(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    return traj[::-1].copy()


def _other_task(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    if ctx.other is None:
        raise ValueError("family 'other-task' needs PerturbContext.other (the next task's demo)")
    return np.asarray(ctx.other, dtype=float).copy()


def _stop_early(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    return traj[: max(1, len(traj) // 2)].copy()


def _shortcut(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    return _line(traj[0], traj[-1], len(traj))


def _rush_wait(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    n = max(2, len(traj) // 10)
    rush = _line(traj[0], traj[-1], n)
    return np.concatenate([rush, np.repeat(traj[-1:], len(traj) - n, axis=0)])


def _mirror(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    sl = _pos(traj)
    p = traj[:, sl]
    a = np.linspace(0.0, 1.0, len(traj))[:, None]
    chord = p[0] + a * (p[-1] - p[0])
    out = traj.copy()
    out[:, sl] = 2 * chord - p
    return out


def _end_miss(traj: np.ndarray, ctx: PerturbContext) -> float:
    """How far (data units) `drift` and `overrun` end from the demo's end: 5 cm for poses; for
    the pen 15 % of the demo's bounding-box diagonal, at least 2 cm."""
    if _is_pose(traj):
        return 0.05 * ctx.units_per_m
    p = traj[:, _pos(traj)]
    diag = float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))
    return max(0.15 * diag, 0.02 * ctx.units_per_m)


def _drift(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    sl = _pos(traj)
    p = traj[:, sl]
    size = _end_miss(traj, ctx)
    direction = _unit(_rng("drift", ctx.demo), p.shape[1])
    out = traj.copy()
    out[:, sl] += np.linspace(0.0, 1.0, len(traj))[:, None] * size * direction
    return out


def _overrun(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    p = traj[:, _pos(traj)]
    size = _end_miss(traj, ctx)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    if arc[-1] <= 0.0:
        raise ValueError("family 'overrun' needs a trajectory that moves (its last stretch "
                         "gives the direction to run on in); this one stays at one point")
    k = max(int(np.searchsorted(arc, arc[-1] - size, side="right")) - 1, 0)
    chord = p[-1] - p[k]
    if not np.linalg.norm(chord) > 0.0:  # the last stretch closes on itself: its last step
        k = int(np.flatnonzero(arc < arc[-1])[-1])
        chord = p[-1] - p[k]
    step = chord / np.linalg.norm(chord) * size
    run_on = p[-1] + min_jerk(max(len(p) - k, 2))[1:, None] * step
    return np.concatenate([traj, run_on])


def _teleport(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    return np.repeat(traj[-1:], len(traj), axis=0)


def _frozen_orientation(traj: np.ndarray, ctx: PerturbContext) -> np.ndarray:
    out = traj.copy()
    out[:, 3:] = traj[0, 3:]
    return out


_ALL = (
    Family("demo", "succeed", "the demonstration itself", _demo),
    Family("slower", "succeed", "time-stretched 2x", _slower),
    Family("faster", "succeed", "time-compressed 1.5x", _faster),
    Family("noise", "succeed", "smooth zero-mean noise, 1 cm (poses) / 3 mm (pen)", _noise),
    Family("start-offset", "succeed", "0.5 s move 1 cm off the start, back on the demo by "
           "mid-way", _start_offset),
    Family("reverse", "fail", "the demo backwards", _reverse),
    Family("other-task", "fail", "demo j of the next task", _other_task),
    Family("stop-early", "fail", "the first half only", _stop_early),
    Family("shortcut", "fail", "straight min-jerk line start -> end, demo duration", _shortcut),
    Family("rush-wait", "fail", "straight line in 10 % of the time, then waiting", _rush_wait),
    Family("mirror", "fail", "path reflected about its start -> end chord", _mirror),
    Family("drift", "fail", "offset growing to 5 cm (poses) / 15 % of the size, >= 2 cm (pen)",
           _drift),
    Family("overrun", "fail", "the demo, then on past its end along its last stretch by the "
           "drift's distance", _overrun, pen_only=True),
    Family("teleport", "fail", "the end pose commanded from the first step", _teleport),
    Family("frozen-orientation", "fail", "orientation held at its first value",
           _frozen_orientation, poses_only=True),
)
#: Every family by name, in table order.
FAMILIES: dict[str, Family] = {f.name: f for f in _ALL}


def family_names(poses: bool | None = None) -> list[str]:
    """Family names in table order; `poses=False` leaves out the pose-only ones, `poses=True`
    the pen-only ones, None leaves out none."""
    return [f.name for f in _ALL
            if not (poses is False and f.poses_only) and not (poses is True and f.pen_only)]


def perturb(family: str, trajectory: np.ndarray, ctx: PerturbContext | None = None
            ) -> np.ndarray:
    """Applies family `family` to a trajectory [T, D] (data units). Returns [T', D].

    Raises:
        ValueError: unknown family (lists the valid ones), a pose-only family on a 2-D
            trajectory, a pen-only family on a pose trajectory, `overrun` on a trajectory that
            does not move, or `other-task` without `ctx.other`.
    """
    if family not in FAMILIES:
        raise ValueError(f"unknown perturbation family {family!r}; valid: {list(FAMILIES)}")
    fam = FAMILIES[family]
    traj = np.asarray(trajectory, dtype=float)
    if traj.ndim != 2 or len(traj) < 2:
        raise ValueError(f"trajectory must be [T >= 2, D], got shape {traj.shape}")
    if fam.poses_only and not _is_pose(traj):
        raise ValueError(f"family {family!r} applies to 7-D pose trajectories only, got D = "
                         f"{traj.shape[1]}")
    if fam.pen_only and _is_pose(traj):
        raise ValueError(f"family {family!r} applies to pen (point) trajectories only, got a "
                         "7-D pose trajectory")
    return fam.fn(traj, ctx or PerturbContext())
