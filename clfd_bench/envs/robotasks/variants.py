"""Trajectory edits the RoboTasks tasks build their own right and wrong trajectories from (each
task's `variants.py`: `VARIANTS`; run by `clfd_bench.execution.task_variants`). A variant takes
a demo's pose trajectory [T, 7] (position, quaternion w, x, y, z) and returns another.
Evaluation only: no env imports this module.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from clfd_bench.data.resample import min_jerk_profile

__all__ = ["Variant", "bumped", "lift_then_line", "over_the_top", "rolled_at_the_end",
           "shortened", "stop_at", "tilt_kept_from_lowest", "turned_extra", "turned_fraction",
           "turned_the_long_way", "up_then_across", "waypoints", "yaw_at_the_end", "yaw_kept",
           "yaw_mirrored"]

#: A demo's trajectory [T, 7] -> a variant of it [T, 7].
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
