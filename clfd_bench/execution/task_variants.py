"""Task-specific wrong and right trajectories for the RoboTasks9 scenes, beyond the generic
families of `clfd_bench.execution.perturb` (which every env gets).

A success criterion is only as good as the wrong trajectories it rejects and the good ones it
keeps; the generic families cannot know a task's valid alternatives (a glass lifted first and
then carried straight) or its typical mistakes (a box carried unturned and turned at the end).
`VARIANTS` lists them per env with what an observer would say ("succeed", "fail", or "either":
an observer could accept it or not); `run_variants` executes each on every demo.
`python eval/own_variants.py` prints the table (docs/execution.md).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import gymnasium as gym
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from clfd_bench.data.resample import min_jerk_profile
from clfd_bench.execution.rollout import rollout

__all__ = ["VARIANTS", "VariantRow", "run_variants"]

Variant = Callable[[np.ndarray], np.ndarray]


def _wxyz(r: Rotation) -> np.ndarray:
    q = r.as_quat()
    return np.concatenate([q[..., 3:], q[..., :3]], -1)


def _rot(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(np.concatenate([q[..., 1:], q[..., :1]], -1))


def _mj(n: int) -> np.ndarray:
    return min_jerk_profile(np.linspace(0.0, 1.0, n))


def _turn(traj: np.ndarray) -> np.ndarray:
    """The rotation vector from the first to the last orientation (start frame)."""
    return (_rot(traj[0, 3:]).inv() * _rot(traj[-1, 3:])).as_rotvec()


def stop_at(frac: float) -> Variant:
    def fn(traj):
        k = int(len(traj) * frac)
        out = traj.copy()
        out[k:] = traj[k]
        return out
    return fn


def lift_then_line(lift: float = 0.08) -> Variant:
    """Straight up by `lift` (orientation held), then a straight line slerping to the end."""
    def fn(traj):
        n, a = len(traj), len(traj) // 5
        p0, p1 = traj[0, :3], traj[-1, :3]
        up = p0 + [0.0, 0.0, lift]
        pos = np.concatenate([p0 + _mj(a)[:, None] * (up - p0),
                              up + _mj(n - a)[:, None] * (p1 - up)])
        sl = Slerp([0, 1], _rot(np.stack([traj[0, 3:], traj[-1, 3:]])))
        q = np.concatenate([np.repeat(traj[:1, 3:], a, 0), _wxyz(sl(_mj(n - a)))])
        return np.concatenate([pos, q], 1)
    return fn


def waypoints(offsets: Callable[[np.ndarray, np.ndarray], list[np.ndarray]]) -> Variant:
    """Min-jerk segments through waypoints; the orientation held on the first segment, slerped
    on the middle ones (on the second of two), held on the last (of three or more)."""
    def fn(traj):
        pts = [traj[0, :3], *offsets(traj[0, :3], traj[-1, :3]), traj[-1, :3]]
        n, k = len(traj), len(pts) - 1
        sizes = [n // k] * (k - 1) + [n - (n // k) * (k - 1)]
        pos = np.concatenate([u + _mj(m)[:, None] * (v - u)
                              for u, v, m in zip(pts[:-1], pts[1:], sizes, strict=True)])
        first, last = sizes[0], (sizes[-1] if k >= 3 else 0)
        mid = n - first - last
        sl = Slerp([0, 1], _rot(np.stack([traj[0, 3:], traj[-1, 3:]])))
        q = np.concatenate([np.repeat(traj[:1, 3:], first, 0), _wxyz(sl(_mj(mid))),
                            np.repeat(traj[-1:, 3:], last, 0)])
        return np.concatenate([pos, q], 1)
    return fn


def turned_extra(deg: float) -> Variant:
    """The demo's orientation, turned a further `deg` about its own start-to-end axis."""
    def fn(traj):
        rv = _turn(traj)
        extra = np.radians(deg) * rv / np.linalg.norm(rv)
        out = traj.copy()
        out[:, 3:] = _wxyz(_rot(traj[:, 3:]) * Rotation.from_rotvec(
            _mj(len(traj))[:, None] * extra))
        return out
    return fn


def turned_fraction(frac: float) -> Variant:
    """Each pose turned only `frac` of the way from the start orientation."""
    def fn(traj):
        r0 = _rot(traj[0, 3:])
        rel = (r0.inv() * _rot(traj[:, 3:])).as_rotvec()
        out = traj.copy()
        out[:, 3:] = _wxyz(r0 * Rotation.from_rotvec(rel * frac))
        return out
    return fn


def turned_the_long_way(traj: np.ndarray) -> np.ndarray:
    """From the start to the end orientation the other way round the same axis."""
    rv = _turn(traj)
    ang = np.linalg.norm(rv)
    other = -rv / ang * (2 * np.pi - ang)
    out = traj.copy()
    out[:, 3:] = _wxyz(_rot(traj[0, 3:]) * Rotation.from_rotvec(_mj(len(traj))[:, None] * other))
    return out


def yaw_mirrored(traj: np.ndarray) -> np.ndarray:
    """The demo's turns about the world's vertical mirrored (the other way round)."""
    r0 = _rot(traj[0, 3:])
    rv = (_rot(traj[:, 3:]) * r0.inv()).as_rotvec()
    rv[:, 2] *= -1
    out = traj.copy()
    out[:, 3:] = _wxyz(Rotation.from_rotvec(rv) * r0)
    return out


def yaw_kept(traj: np.ndarray) -> np.ndarray:
    """The demo's turn about the vertical, never turned back (held from its peak)."""
    x = _rot(traj[:, 3:]).apply([1.0, 0.0, 0.0])
    heading = np.unwrap(np.arctan2(x[:, 1], x[:, 0]))
    k = int(np.argmax(np.abs(heading - heading[0])))
    out = traj.copy()
    out[k:, 3:] = traj[k, 3:]
    return out


def yaw_at_the_end(traj: np.ndarray) -> np.ndarray:
    """Carried unturned; turned 65 deg about the vertical and back in the last 30 %."""
    out = traj.copy()
    out[:, 3:] = traj[0, 3:]
    a = int(len(traj) * 0.7)
    s = np.sin(np.linspace(0.0, np.pi, len(traj) - a)) ** 2
    out[a:, 3:] = _wxyz(Rotation.from_rotvec(-np.radians(65.0) * s[:, None] * [0.0, 0.0, 1.0])
                        * _rot(traj[0, 3:]))
    return out


def over_the_top(lift: float = 0.28) -> Variant:
    """Straight across seen from above, rising to `lift` mid-way; the demo's orientations."""
    def fn(traj):
        n = len(traj)
        out = traj.copy()
        bump = np.sin(np.linspace(0.0, np.pi, n)) ** 2
        out[:, 2] = np.maximum(out[:, 2], traj[0, 2] + (lift - traj[0, 2]) * bump)
        out[:, :2] = traj[0, :2] + _mj(n)[:, None] * (traj[-1, :2] - traj[0, :2])
        return out
    return fn


def bumped(height: float) -> Variant:
    """The demo's path raised by `height` (m; negative: lowered) mid-way, a sine bump (the
    start and end poses unchanged); the demo's orientations."""
    def fn(traj):
        out = traj.copy()
        out[:, 2] += height * np.sin(np.linspace(0.0, np.pi, len(traj)))
        return out
    return fn


def up_then_across(rise: float = 0.08) -> Variant:
    """The demo to its lowest point, then straight up by `rise`, then straight across to its
    end (min-jerk segments); the demo's orientations from the lowest point on, re-timed."""
    def fn(traj):
        k = int(np.argmin(traj[:, 2]))
        n = len(traj) - k
        a = n // 2
        p0, p1 = traj[k, :3], traj[-1, :3]
        up = np.r_[p0[:2], max(p0[2] + rise, p1[2])]
        pos = np.concatenate([p0 + _mj(a)[:, None] * (up - p0),
                              up + _mj(n - a)[:, None] * (p1 - up)])
        idx = np.linspace(k, len(traj) - 1, n)
        sl = Slerp(np.arange(k, len(traj)), _rot(traj[k:, 3:]))
        out = traj.copy()
        out[k:, :3] = pos
        out[k:, 3:] = _wxyz(sl(idx))
        return out
    return fn


def tilt_kept_from_lowest(traj: np.ndarray) -> np.ndarray:
    """The demo's path, its orientation held from the lowest point on (never levelled)."""
    k = int(np.argmin(traj[:, 2]))
    out = traj.copy()
    out[k:, 3:] = traj[k, 3:]
    return out


def rolled_at_the_end(deg: float = 120.0) -> Variant:
    """The demo, its hand rolled `deg` about its own x axis over the last quarter (a scoop's
    bowl turned over)."""
    def fn(traj):
        n, a = len(traj), 3 * len(traj) // 4
        roll = np.radians(deg) * np.minimum(1.0, np.arange(n - a) / max(1, n // 8))
        out = traj.copy()
        out[a:, 3:] = _wxyz(_rot(traj[a:, 3:]) * Rotation.from_rotvec(
            roll[:, None] * [1.0, 0.0, 0.0]))
        return out
    return fn


def shortened(frac: float) -> Variant:
    """The demo's path scaled about its start to `frac` of its horizontal extent (a fold laid
    down short of the far edge)."""
    def fn(traj):
        out = traj.copy()
        out[:, :2] = traj[0, :2] + frac * (traj[:, :2] - traj[0, :2])
        return out
    return fn


#: env -> [(variant, expect, build)]; expect: "succeed", "fail".
VARIANTS: dict[str, list[tuple[str, str, Variant]]] = {
    "clfd/WineGlass-v3": [
        ("lift 8 cm, then a straight line, turning on it", "succeed", lift_then_line(0.08)),
        ("turned the other way round (bowl down on the way)", "fail", turned_the_long_way),
        ("turned 30 deg too far", "fail", turned_extra(30.0)),
        ("stopped at 90 % (upright, over the shelf)", "either", stop_at(0.9)),
        ("stopped at 75 %", "either", stop_at(0.75)),
    ],
    "clfd/PanToStove-v3": [
        ("pull back 12 cm, rise, carry above the stove, descend", "succeed", waypoints(
            lambda p0, p1: [p0 + [0.12, 0.0, 0.0], np.r_[p0[:2] + [0.12, 0.0], p1[2] + 0.1],
                            p1 + [0.0, 0.0, 0.1]])),
        ("pull back 12 cm, lift 6 cm, then a straight line down to the stove", "fail",
         waypoints(lambda p0, p1: [p0 + [0.12, 0.0, 0.06]])),
        ("turned the other way round", "fail", turned_the_long_way),
        ("turned 30 deg too far", "fail", turned_extra(30.0)),
        ("turned half as far", "fail", turned_fraction(0.5)),
        ("stopped at 90 %", "either", stop_at(0.9)),
        ("stopped at 75 %", "either", stop_at(0.75)),
    ],
    "clfd/ObstacleRotate-v3": [
        ("the turn about the vertical mirrored", "fail", yaw_mirrored),
        ("turned as the demo, never back", "fail", yaw_kept),
        ("carried unturned, turned and back over the shelf", "fail", yaw_at_the_end),
        ("straight across, over the obstacle's top", "either", over_the_top(0.28)),
    ],
    "clfd/MatFolding-v3": [
        ("the arc 2 cm higher", "succeed", bumped(0.02)),
        ("the arc 5 cm higher", "succeed", bumped(0.05)),
        ("laid down at 80 % of the way (short of the far edge)", "fail", shortened(0.8)),
        ("the arc 10 cm lower (the edge dragged over the mat)", "fail", bumped(-0.10)),
        ("stopped at 90 %", "either", stop_at(0.9)),
        ("stopped at 75 %", "either", stop_at(0.75)),
    ],
    "clfd/Scoop-v3": [
        ("from the lowest point straight up 8 cm, then across to the end", "succeed",
         up_then_across(0.08)),
        ("carried 12 cm over the beans", "fail", bumped(0.12)),
        ("the dip's tilt kept to the end (never levelled)", "fail", tilt_kept_from_lowest),
        ("the bowl turned over at the end (hand rolled 120 deg)", "fail",
         rolled_at_the_end(120.0)),
        ("stopped at 90 %", "either", stop_at(0.9)),
        ("stopped at 75 %", "either", stop_at(0.75)),
    ],
}


def _why(info: dict) -> str:
    """The kind of a failed rollout's failure."""
    reason = info.get("failure_reason")
    if reason:
        return str(reason).split(" with")[0].split(" at step")[0].split(":")[0]
    if info.get("release_reason") == "slipped":
        return "slipped"
    return "task"



@dataclasses.dataclass(frozen=True)
class VariantRow:
    """One variant on every demo of an env: how many succeeded and why the others failed
    ({reason: count}: "reflex", "collision", "tracking", ..., "slipped", "task")."""

    env_id: str
    name: str
    expect: str
    succeeded: int
    demos: int
    failures: dict[str, int]


def run_variants(env_id: str, names: list[str] | None = None,
                 demos: list[int] | None = None) -> list[VariantRow]:
    """Executes the variants of `env_id` (all, or those named) on its demos (all, or those
    given), with the env's motion-limit checks.

    Raises:
        KeyError: no variants for `env_id`, or an unknown variant name (lists the valid ones).
    """
    import clfd_bench.envs  # noqa: F401 - registers the ids

    if env_id not in VARIANTS:
        raise KeyError(f"no variants for {env_id!r}; valid: {list(VARIANTS)}")
    known = {name: (expect, build) for name, expect, build in VARIANTS[env_id]}
    for name in names or []:
        if name not in known:
            raise KeyError(f"{env_id} has no variant {name!r}; valid: {list(known)}")
    env = gym.make(env_id, disable_env_checker=True)
    rows = []
    try:
        base = env.unwrapped
        demo_ids = list(range(base.num_demos)) if demos is None else list(demos)
        for name in names or list(known):
            expect, build = known[name]
            ok, why = 0, {}
            for j in demo_ids:
                r = rollout(env, build(base.demo_trajectory(j)), demo=j)
                ok += bool(r.success)
                if not r.success:
                    key = _why(r.info)
                    why[key] = why.get(key, 0) + 1
            rows.append(VariantRow(env_id, name, expect, ok, len(demo_ids), why))
    finally:
        env.close()
    return rows
