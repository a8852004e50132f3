"""Trajectory edits the RoboTasks tasks build their own right and wrong trajectories from (each
task's `variants.py`: `VARIANTS`; run by `clfd_bench.execution.task_variants`). A variant takes
a demo's pose trajectory [T, 7] (position, quaternion w, x, y, z) and returns another.
Evaluation only: no env imports this module.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from clfd_bench.data.resample import min_jerk_profile, slerp

__all__ = [
    "NEARBY",
    "and_back",
    "bumped",
    "end_raised",
    "lift_then_line",
    "over_the_top",
    "placing_mistakes",
    "rolled_at_the_end",
    "shifted",
    "shortened",
    "stop_at",
    "tilt_kept_from_lowest",
    "time_warped",
    "tool_tilted",
    "turned_extra",
    "turned_fraction",
    "turned_the_long_way",
    "up_then_across",
    "Variant",
    "waypoints",
    "yaw_at_the_end",
    "yaw_kept",
    "yaw_mirrored",
    "yawed",
]

#: A demo's trajectory [T, 7] -> a variant of it [T, 7].
Variant = Callable[[np.ndarray], np.ndarray]


def _wxyz(r: Rotation) -> np.ndarray:
    q = r.as_quat()
    return np.concatenate([q[..., 3:], q[..., :3]], -1)


def _rot(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(np.concatenate([q[..., 1:], q[..., :1]], -1))


def _mj(n: int) -> np.ndarray:
    return min_jerk_profile(np.linspace(0.0, 1.0, n))


def _blend_in(n: int, share: float = 0.1) -> np.ndarray:
    """[n] weights rising from 0 to 1 (min-jerk) over the first ``share`` of the samples, then
    1: a whole-path edit applied this way starts where the robot stands (the demo's start),
    as the ``start-offset`` family's move does."""
    k = max(2, int(round(n * share)))
    w = np.ones(n)
    w[:k] = _mj(k)
    return w


def _at(traj: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``traj`` [T, 7] at fractional sample indices ``s`` [n] in [0, T - 1]: positions
    interpolated linearly, orientations slerped. Returns [n, 7]."""
    i0 = np.minimum(np.floor(s).astype(int), len(traj) - 2)
    a = s - i0
    out = traj[i0] + a[:, None] * (traj[i0 + 1] - traj[i0])
    out[:, 3:] = [slerp(traj[k, 3:], traj[k + 1, 3:], float(x))
                  for k, x in zip(i0, a, strict=True)]
    return out


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


# -- nearby: the same task done slightly otherwise (an observer's "the same") ------------------
def shifted(offset: tuple[float, float, float]) -> Variant:
    """The whole path moved by ``offset`` (m), blended in over its first 10 %."""
    def fn(traj):
        out = traj.copy()
        out[:, :3] += _blend_in(len(traj))[:, None] * np.asarray(offset, dtype=float)
        return out
    return fn


def yawed(deg: float) -> Variant:
    """The whole path and its orientations turned ``deg`` about the vertical through the path's
    centroid (blended in over its first 10 %)."""
    def fn(traj):
        w = _blend_in(len(traj))
        turn = Rotation.from_rotvec(np.radians(deg) * w[:, None] * [0.0, 0.0, 1.0])
        centre = traj[:, :3].mean(0)
        out = traj.copy()
        out[:, :3] = centre + turn.apply(traj[:, :3] - centre)
        out[:, 3:] = _wxyz(turn * _rot(traj[:, 3:]))
        return out
    return fn


def tool_tilted(deg: float, axis: tuple[float, float, float]) -> Variant:
    """Every orientation turned a further ``deg`` about the hand's own ``axis`` (blended in
    over the first 10 %); positions unchanged."""
    def fn(traj):
        w = _blend_in(len(traj))
        unit = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        out = traj.copy()
        out[:, 3:] = _wxyz(_rot(traj[:, 3:]) * Rotation.from_rotvec(
            np.radians(deg) * w[:, None] * unit))
        return out
    return fn


def time_warped(gamma: float) -> Variant:
    """The same path on another clock: sample k of n is the demo at phase (k / (n-1))^gamma
    (gamma > 1: a slow start and a fast end); positions interpolated, orientations slerped."""
    def fn(traj):
        n = len(traj)
        return _at(traj, np.linspace(0.0, 1.0, n) ** gamma * (n - 1))
    return fn


#: Edits every scene must survive: an observer sees the same task done (a few millimetres or
#: degrees off, on another clock). The 1 cm noise and start-offset families are rougher.
NEARBY: list[tuple[str, str, Variant]] = [
    ("the whole path 5 mm aside (x)", "succeed", shifted((0.005, 0.0, 0.0))),
    ("the whole path 5 mm aside (y)", "succeed", shifted((0.0, 0.005, 0.0))),
    ("the whole path 5 mm higher", "succeed", shifted((0.0, 0.0, 0.005))),
    ("turned 3 deg about the vertical", "succeed", yawed(3.0)),
    ("turned -3 deg about the vertical", "succeed", yawed(-3.0)),
    ("the hand tilted 3 deg about its x axis", "succeed", tool_tilted(3.0, (1.0, 0.0, 0.0))),
    ("the hand tilted 3 deg about its y axis", "succeed", tool_tilted(3.0, (0.0, 1.0, 0.0))),
    ("slow start, fast end (phase u^1.4)", "succeed", time_warped(1.4)),
    ("fast start, slow end (phase u^0.8)", "succeed", time_warped(0.8)),
]


# -- wrong: the task's own mistakes ----------------------------------------------------------
def end_raised(height: float) -> Variant:
    """The path raised linearly to ``height`` (m) at its end: the object let go that much
    higher than the demo lets it go."""
    def fn(traj):
        out = traj.copy()
        out[:, 2] += height * np.linspace(0.0, 1.0, len(traj))
        return out
    return fn


def and_back(share: float = 0.3) -> Variant:
    """The demo in the first ``1 - share`` of its duration, then back along its own path to its
    start in the rest: the task done, then undone (a lid shut again, an object carried back)."""
    def fn(traj):
        n = len(traj)
        k = n - int(round(n * share))
        ahead = np.linspace(0.0, n - 1.0, k)
        back = np.linspace(n - 1.0, 0.0, n - k + 1)[1:]
        return _at(traj, np.concatenate([ahead, back]))
    return fn


def placing_mistakes(prop: str, support: str) -> list[tuple[str, str, Variant]]:
    """A placing task's typical mistakes (its prop carried to ``support`` and let go there):
    the task undone, the prop dropped from 10 cm higher, the prop turned only half way."""
    return [
        (f"carried to the {support}, then back to the start and let go there", "fail",
         and_back(0.3)),
        ("let go 10 cm higher than the demo (dropped)", "fail", end_raised(0.10)),
        (f"turned only half way (the {prop} let go tilted)", "fail", turned_fraction(0.5)),
    ]
