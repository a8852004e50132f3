"""Step-by-step traces of a rollout and the tool point of an env.

:class:`Trace` is what happened in one rollout; :class:`FrameHook` streams rendered frames
during it; :func:`tracer` wraps an env to record both; :func:`tool_site` / :func:`tool_path`
say where the tool point is and where a trajectory asks it to go.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["FrameHook", "Trace", "object_bodies", "tool_path", "tool_site", "tracer"]


@dataclasses.dataclass
class Trace:
    """What happened in one rollout, step by step (``K`` = steps run + 1: the reset state first).

    Attributes:
        time: ``[K]`` simulated seconds since the reset.
        hand_pos: ``[K, 3]`` position (m) of the tracked ``hand`` frame.
        hand_quat: ``[K, 4]`` its orientation (w, x, y, z).
        tool_pos: ``[K, 3]`` the tool point (m): the pen tip for writing envs, the grasp point
            between the fingertips otherwise.
        tool_down: ``[K]`` whether the pen touched the board (writing envs), else None.
        objects: body name -> ``[K, 7]`` pose (position m, quaternion w, x, y, z) of every
            movable body that is not part of the robot (props, lid, beans).
        tracking_error: ``[K]`` the env's hand position error (m) to its target (0 at reset).
    """

    time: np.ndarray
    hand_pos: np.ndarray
    hand_quat: np.ndarray
    tool_pos: np.ndarray
    tool_down: np.ndarray | None
    objects: dict[str, np.ndarray]
    tracking_error: np.ndarray


def tool_site(base) -> int:
    """Site id of the tool point of a clfd-bench env: ``pen_tip`` for writing envs, else
    ``grasp`` (between the fingertips)."""
    import mujoco

    from clfd_bench.sim.robot import GRASP_SITE, PEN_TIP_SITE

    name = PEN_TIP_SITE if getattr(base, "tool", None) == "pen" else GRASP_SITE
    sid = mujoco.mj_name2id(base.model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid < 0:
        raise ValueError(f"{type(base).__name__}'s model has no site {name!r}; is it built with "
                         "clfd_bench.sim.robot.panda_spec()?")
    return int(sid)


def tool_path(base, trajectory: np.ndarray | Sequence[np.ndarray]) -> np.ndarray:
    """Where a trajectory (data units) asks the tool point to go, in the world frame.

    Args:
        base: the unwrapped clfd-bench env (``env.unwrapped``).
        trajectory: what :func:`execute` takes for this env: ``[T, 2]`` for a shape, one
            ``[T_k, 2]`` per letter for the HelloWorld text, ``[T, 7]`` hand poses otherwise.

    Returns:
        ``[T', 3]`` metres: writing envs, the pen point on the board (lifted by the pen lift
        between letters); pose envs, the grasp point ``GRASP_OFFSET`` along the hand's z axis.
    """
    import mujoco

    from clfd_bench.sim.robot import GRASP_OFFSET

    if hasattr(base, "to_surface") and hasattr(base, "wspec"):  # one letter or LASA shape
        xy = base.to_surface(np.asarray(trajectory, dtype=float))
        return np.column_stack([xy, np.full(len(xy), base.wspec.surface_height)])
    if hasattr(base, "letter_to_surface") and hasattr(base, "wspec"):  # HelloWorld text
        act = base.trajectory_to_actions(trajectory)
        z = base.wspec.surface_height + np.clip(act[:, 2], 0.0, 1.0) * base.wspec.lift_height
        return np.column_stack([act[:, :2], z])
    poses = np.asarray(base.trajectory_to_actions(trajectory), dtype=float)[:, :7]
    out = np.empty((len(poses), 3))
    offset = np.array([0.0, 0.0, GRASP_OFFSET])
    for t, pose in enumerate(poses):
        quat = pose[3:7] / max(np.linalg.norm(pose[3:7]), 1e-12)
        mujoco.mju_rotVecQuat(out[t], offset, quat)
        out[t] += pose[:3]
    return out


def object_bodies(model, present_only: bool = False) -> dict[str, int]:
    """Movable bodies outside the robot: name -> body id (bodies with joints whose kinematic
    tree is not the robot's). With `present_only`, only those that can collide now: a body
    whose contacts are all off, as Scoop's beans waiting in their pool 10 m under the floor, is
    not in the scene."""
    import mujoco

    robot = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "link0")
    robot_root = model.body_rootid[robot] if robot >= 0 else -1
    out = {}
    for b in range(1, model.nbody):
        if present_only and not (model.body_contype[b] or model.body_conaffinity[b]):
            continue
        if model.body_jntnum[b] > 0 and model.body_rootid[b] != robot_root:
            out[mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}"] = b
    return out


class FrameHook:
    """Renders frames during a rollout and hands them to ``sink`` one by one (nothing is kept,
    so long rollouts cost no memory): the state after reset, then every ``every``-th step.

    Args:
        render: ``(base_env, tracer) -> frame [H, W, 3] uint8``; ``tracer`` is the recording
            wrapper (its ``tool_positions`` / ``tool_down_flags`` hold the steps so far).
        sink: receives each frame.
        every: render every this many env steps (e.g. 3 for 20 frames per simulated second).
    """

    def __init__(self, render: Callable[[Any, Any], np.ndarray],
                 sink: Callable[[np.ndarray], None], every: int = 1):
        if every < 1:
            raise ValueError(f"every must be >= 1, got {every}")
        self.render, self.sink, self.every = render, sink, int(every)


def _tracer_class():
    """A ``gymnasium.Wrapper`` recording a :class:`Trace` (defined lazily: gymnasium is heavy)."""
    import gymnasium as gym

    class _Tracer(gym.Wrapper):
        """Records the state after reset and after every step; renders frames through a
        :class:`FrameHook` when given."""

        def __init__(self, env, hook: FrameHook | None = None):
            super().__init__(env)
            base = env.unwrapped
            self._base = base
            self._tool = tool_site(base)
            self._objects = object_bodies(base.model)
            self.hook = hook
            self._rows: list[tuple] = []
            self.tool_positions: list[np.ndarray] = []
            self.tool_down_flags: list[bool | None] = []

        def _record(self, obs, info) -> None:
            d = self._base.data
            hand = self._base.robot.hand_body
            down = obs.get("pen_down") if isinstance(obs, Mapping) else None
            tool = d.site_xpos[self._tool].copy()
            flag = None if down is None else bool(np.asarray(down).reshape(-1)[0] > 0.5)
            self.tool_positions.append(tool)
            self.tool_down_flags.append(flag)
            self._rows.append((
                float(d.time), d.xpos[hand].copy(), d.xquat[hand].copy(), tool, flag,
                {name: np.concatenate([d.xpos[b], d.xquat[b]])
                 for name, b in self._objects.items()},
                float(np.asarray(info.get("tracking_error", (np.nan,)))[0]),
            ))
            hook = self.hook
            if hook is not None and (len(self._rows) - 1) % hook.every == 0:
                hook.sink(hook.render(self._base, self))

        def reset(self, **kwargs):
            obs, info = self.env.reset(**kwargs)
            self._rows, self.tool_positions, self.tool_down_flags = [], [], []
            self._record(obs, {"tracking_error": (0.0, 0.0)})
            return obs, info

        def step(self, action):
            out = self.env.step(action)
            self._record(out[0], out[4])
            return out

        def close(self):  # the wrapped env belongs to the cache; do not close it here
            pass

        def trace(self) -> Trace:
            rows = self._rows
            if not rows:
                raise RuntimeError("no steps recorded; reset the env first")
            downs = [r[4] for r in rows]
            return Trace(
                time=np.array([r[0] for r in rows]),
                hand_pos=np.array([r[1] for r in rows]),
                hand_quat=np.array([r[2] for r in rows]),
                tool_pos=np.array([r[3] for r in rows]),
                tool_down=None if downs[0] is None else np.array(downs, dtype=bool),
                objects={name: np.array([r[5][name] for r in rows]) for name in rows[0][5]},
                tracking_error=np.array([r[6] for r in rows]),
            )

    return _Tracer



def tracer(env, hook: FrameHook | None = None):
    """``env`` wrapped to record a :class:`Trace` (its ``trace()``) and, with ``hook``, to
    stream rendered frames."""
    return _tracer_class()(env, hook)
