"""Execution success: run predicted trajectories on the simulated Panda and score runs by it.

Two levels:

* :func:`execute_predictions` executes one task's predictions ``[N, T, D]`` (data units) in the
  task's Gymnasium env (``reset(options={"demo": d})`` then the whole trajectory through
  :func:`clfd_bench.sim.rollout.rollout`) and returns one :class:`ExecResult` per demo. Envs are
  made once per process and id and reused (:func:`get_env`).
* :func:`evaluate_run` re-scores a saved run without training: for every evaluation point
  (after task ``i``, task ``j <= i``, demo ``d``) it executes the saved prediction and writes
  ``success``, ``sim_accuracy``, ``sim_cl_metrics`` and a ``sim`` provenance block into the
  run's ``results.json`` (atomically, every other key kept).

Re-running is cheap: results are cached in ``RUN_DIR/sim_cache.json`` under a key made of the
env id, the demo and the prediction's bytes, valid for one simulator fingerprint (a hash of the
simulator's source, task files, robot assets and the mujoco / mink / gymnasium versions). A run
whose old tasks' predictions do not change (SG, HN, CHN) executes each distinct prediction once,
a killed evaluation resumes where it stopped, and any change to the simulator invalidates the
cache by itself. ``force=True`` ignores it.

Units: tracking errors are metres (position) and radians (rotation) of the tracked ``hand``
frame, measured after each trajectory step.
"""

from __future__ import annotations

import collections
import dataclasses
import datetime
import functools
import hashlib
import importlib.metadata
import json
import math
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.io import atomic_write_json, json_safe
from clfd_bench.progress import progress

__all__ = [
    "CACHE_FILE",
    "ENV_CACHE_SIZE",
    "clear_env_cache",
    "evaluate_run",
    "ExecResult",
    "execute",
    "execute_after_task",
    "execute_predictions",
    "FrameHook",
    "get_env",
    "load_run",
    "load_run_predictions",
    "read_results",
    "SavedRun",
    "sim_fields",
    "sim_fingerprint",
    "sim_provenance",
    "tool_path",
    "tool_site",
    "Trace",
]

CACHE_FILE = "sim_cache.json"
"""Name of the execution cache in a run directory."""
RESULTS_FILE = "results.json"
PREDICTIONS_DIR = "predictions"
_CACHE_SCHEMA = 1
#: info keys every env reports; the others are task-specific and explain a failure.
_BASE_INFO_KEYS = frozenset({"is_success", "tracking_error", "ik_error", "demo", "step",
                             "failure_reason"})


# ----------------------------------------------------------------------------- results
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


@dataclasses.dataclass
class ExecResult:
    """Outcome of executing one predicted trajectory.

    Attributes:
        demo: the demo whose start (and scene) the env was reset to.
        success: the env's physical success decision after the trajectory and settling.
        mean_tracking_error: mean position error (m) of the hand frame over the trajectory.
        max_tracking_error: its maximum (m).
        mean_rotation_error: mean rotation error (rad) of the hand frame.
        failure_reason: None on success; else why: a physics blow-up as the env reports it, or
            "task not achieved" with the env's task-specific info (e.g. DTW of the ink, ink
            fraction, lid angle).
        steps: env steps run (trajectory + settling).
        wall_s: wall-clock seconds of the rollout.
        info: the env's final info, JSON-safe (non-finite floats become None).
        trace: the step-by-step :class:`Trace` when requested, else None.
        frames: rendered frames ``[H, W, 3]`` uint8 when recorded, else None.
    """

    demo: int
    success: bool
    mean_tracking_error: float
    max_tracking_error: float
    mean_rotation_error: float
    failure_reason: str | None
    steps: int
    wall_s: float
    info: dict[str, Any]
    trace: Trace | None = None
    frames: list[np.ndarray] | None = None

    def summary(self) -> dict[str, Any]:
        """The scalar fields as a JSON-safe dict (what the cache stores)."""
        return {
            "demo": self.demo,
            "success": self.success,
            "mean_tracking_error": _finite_or_none(self.mean_tracking_error),
            "max_tracking_error": _finite_or_none(self.max_tracking_error),
            "mean_rotation_error": _finite_or_none(self.mean_rotation_error),
            "failure_reason": self.failure_reason,
            "steps": self.steps,
        }


def _finite_or_none(x: Any) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _failure_reason(success: bool, info: Mapping[str, Any]) -> str | None:
    if success:
        return None
    if info.get("failure_reason"):
        return str(info["failure_reason"])
    parts = []
    for key, value in info.items():
        if key in _BASE_INFO_KEYS:
            continue
        if isinstance(value, (bool, np.bool_)):
            parts.append(f"{key}={bool(value)}")
        elif isinstance(value, (int, float, np.integer, np.floating)):
            parts.append(f"{key}={float(value):.4g}")
        elif isinstance(value, (list, tuple)) and all(
                isinstance(v, (int, float, np.integer, np.floating)) for v in value):
            parts.append(f"{key}=[{', '.join(f'{float(v):.4g}' for v in value)}]")
    return "task not achieved" + (f" ({', '.join(parts)})" if parts else "")


# ----------------------------------------------------------------------------- envs
_ENV_CACHE: collections.OrderedDict[tuple, Any] = collections.OrderedDict()
ENV_CACHE_SIZE = 8
"""Most envs :func:`get_env` keeps (least recently used are closed): a writing env holds
~40 MB, so all 26 LASA shapes at once would take > 1 GB."""


def get_env(env_id: str, render: bool = False, **kwargs: Any):
    """The env ``env_id`` made with ``gymnasium.make`` (``render_mode="rgb_array"`` when
    ``render``), cached per process, id, render flag and ``kwargs`` (up to
    :data:`ENV_CACHE_SIZE`): building a scene and its IK takes a while, resetting it is cheap.

    Raises:
        gymnasium.error.Error: ``env_id`` is not registered (the message lists close ids).
    """
    import gymnasium as gym

    import clfd_bench  # noqa: F401  (registers the ids)

    key = (env_id, bool(render), tuple(sorted(kwargs.items())))
    env = _ENV_CACHE.get(key)
    if env is None:
        env = gym.make(env_id, render_mode="rgb_array" if render else None,
                       disable_env_checker=True, **kwargs)
        _ENV_CACHE[key] = env
        while len(_ENV_CACHE) > max(1, ENV_CACHE_SIZE):
            _ENV_CACHE.popitem(last=False)[1].close()
    _ENV_CACHE.move_to_end(key)
    return env


def clear_env_cache() -> None:
    """Closes and forgets every env made by :func:`get_env` (frees renderers and memory)."""
    for env in _ENV_CACHE.values():
        env.close()
    _ENV_CACHE.clear()


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


def _object_bodies(model) -> dict[str, int]:
    """Movable bodies outside the robot: name -> body id (bodies with joints whose kinematic
    tree is not the robot's)."""
    import mujoco

    robot = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "link0")
    robot_root = model.body_rootid[robot] if robot >= 0 else -1
    out = {}
    for b in range(1, model.nbody):
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
            self._objects = _object_bodies(base.model)
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


def execute(env, trajectory: np.ndarray | Sequence[np.ndarray], demo: int, *,
            record: bool = False, trace: bool = False, settle_s: float | None = None,
            fps: float = 30.0, frame_hook: FrameHook | None = None) -> ExecResult:
    """Executes one trajectory in ``env`` from demo ``demo``'s start.

    Args:
        env: a clfd-bench env (e.g. from :func:`get_env`; with ``record``, made with
            ``render=True``).
        trajectory: ``[T, D]`` in the dataset's units (see :func:`execute_predictions`); for
            ``clfd/HelloWorld-v0`` one ``[T_k, 2]`` array per letter.
        demo: the demo to reset to (``reset(options={"demo": demo})``).
        record: keep the env's own rendered frames in ``ExecResult.frames`` (``fps`` per
            simulated second).
        trace: keep the step-by-step :class:`Trace`.
        settle_s: seconds of settling after the trajectory (default: the rollout's).
        frame_hook: stream frames of a custom renderer (e.g. with paths drawn) to a sink
            instead; works with an env made without rendering.

    Returns:
        An :class:`ExecResult`.
    """
    from clfd_bench.sim.rollout import rollout

    tracer = _tracer_class()(env, frame_hook) if (trace or frame_hook is not None) else env
    kwargs: dict[str, Any] = {} if settle_s is None else {"settle_s": float(settle_s)}
    t0 = time.perf_counter()
    res = rollout(tracer, trajectory, demo=int(demo), record=record, fps=fps, **kwargs)
    wall = time.perf_counter() - t0
    err = res.tracking_error_pos[np.isfinite(res.tracking_error_pos)]
    rot = res.tracking_error_rot[np.isfinite(res.tracking_error_rot)]
    return ExecResult(
        demo=int(demo),
        success=bool(res.success),
        mean_tracking_error=float(err.mean()) if err.size else math.nan,
        max_tracking_error=float(err.max()) if err.size else math.nan,
        mean_rotation_error=float(rot.mean()) if rot.size else math.nan,
        failure_reason=_failure_reason(bool(res.success), res.info),
        steps=int(res.steps),
        wall_s=wall,
        info=json_safe(dict(res.info)),
        trace=tracer.trace() if trace else None,
        frames=res.frames,
    )


def _select(predictions: np.ndarray, demos: Sequence[int] | None, num_demos: int
            ) -> list[tuple[int, np.ndarray]]:
    """Pairs (demo, trajectory): ``predictions`` indexed by demo, or one per entry of ``demos``
    when their lengths match."""
    n = len(predictions)
    if demos is None:
        if n > num_demos:
            raise ValueError(f"{n} predictions but the env has only {num_demos} demos; pass one "
                             "prediction per demo (predictions[d] starts at demo d's start)")
        return [(d, predictions[d]) for d in range(n)]
    demos = [int(d) for d in demos]
    for d in demos:
        if not 0 <= d < num_demos:
            raise ValueError(f"demo {d} out of range: the env has demos 0..{num_demos - 1}")
    if n == len(demos):
        return list(zip(demos, predictions, strict=True))
    if n >= num_demos or max(demos) < n:
        return [(d, predictions[d]) for d in demos]
    raise ValueError(f"{n} predictions for demos {demos}: pass one prediction per demo of the "
                     "task (indexed by demo) or one per entry of `demos`")


def execute_predictions(dataset: str, task_name: str, predictions: np.ndarray,
                        demos: list[int] | None = None, record: bool = False, *,
                        trace: bool = False, settle_s: float | None = None,
                        fps: float = 30.0) -> list[ExecResult]:
    """Executes predicted trajectories of one task in its env, one rollout per demo.

    Args:
        dataset: "helloworld", "lasa", "robotasks" or "robotasks9".
        task_name: the data layer's task name ("h", "Angle", "openbox", ...).
        predictions: ``[N, T, D]`` in data units: HelloWorld ``D = 2`` metres, LASA ``D = 2``
            native units, RoboTasks ``D = 7`` poses (position m, quaternion w, x, y, z) of the
            ``hand`` frame. ``predictions[d]`` is the prediction from demo ``d``'s start.
        demos: execute only these demos (default: all ``N``). ``predictions`` is then either
            indexed by demo (``N`` = the task's demo count) or holds one trajectory per entry.
        record: render frames of every rollout (``ExecResult.frames``).
        trace: keep each rollout's step-by-step :class:`Trace`.
        settle_s: seconds of settling after the trajectory (default: the rollout's).
        fps: frame rate of recorded frames.

    Returns:
        One :class:`ExecResult` per executed demo, in order.

    Raises:
        KeyError: the task has no env (the message lists the tasks that do).
        ValueError: predictions of the wrong shape, or demos out of range.
    """
    from clfd_bench.envs.registration import env_id_for

    preds = np.asarray(predictions, dtype=np.float64)
    if preds.ndim != 3:
        raise ValueError(f"predictions must be [N, T, D], got shape {preds.shape}")
    if not np.isfinite(preds).all():
        bad = sorted({int(i) for i in np.argwhere(~np.isfinite(preds))[:, 0]})
        raise ValueError(f"predictions of demos {bad} contain NaN/inf (a diverged model?); "
                         "replace them before executing, or score them as failures")
    env = get_env(env_id_for(dataset, task_name), render=record)
    pairs = _select(preds, demos, env.unwrapped.num_demos)
    return [execute(env, traj, d, record=record, trace=trace, settle_s=settle_s, fps=fps)
            for d, traj in pairs]


# ----------------------------------------------------------------------------- provenance
def _version(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def _sim_files() -> Iterator[Path]:
    """Files that define the simulator: its code, the task scenes and specs, robot assets."""
    from clfd_bench.resources import resource_root

    pkg = Path(__file__).resolve().parent.parent
    for folder in (pkg / "sim", pkg / "envs"):
        yield from sorted(folder.glob("*.py"))
    for name in ("tasks", "assets"):
        root = resource_root(name)
        yield from sorted(p for p in root.rglob("*") if p.is_file() and p.suffix != ".md")


@functools.lru_cache(maxsize=1)
def sim_fingerprint() -> str:
    """sha256 (hex, first 16 digits) of the simulator: the contents of ``clfd_bench/sim``,
    ``clfd_bench/envs``, ``tasks/`` and ``assets/`` and the mujoco, mink, gymnasium versions.
    Execution results are reused only under the same fingerprint."""
    from clfd_bench.resources import resource_root

    roots = [Path(__file__).resolve().parent.parent, resource_root("tasks").parent,
             resource_root("assets").parent]
    digest = hashlib.sha256()
    for dist in ("mujoco", "mink", "gymnasium"):
        digest.update(f"{dist}={_version(dist)}\n".encode())
    for path in _sim_files():
        rel = next((str(path.relative_to(r)) for r in roots if path.is_relative_to(r)), path.name)
        digest.update(rel.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def sim_provenance(dataset: str, task_names: Sequence[str]) -> dict[str, Any]:
    """The ``sim`` block: env id and version of each task, library versions, fingerprint.

    Tasks without an env get ``None`` as id.
    """
    import gymnasium as gym

    from clfd_bench import __version__
    from clfd_bench.envs.registration import env_id_for

    env_ids: dict[str, str | None] = {}
    for name in task_names:
        try:
            env_ids[name] = env_id_for(dataset, name)
        except KeyError:
            env_ids[name] = None
    versions = {}
    for env_id in sorted({e for e in env_ids.values() if e}):
        spec = gym.spec(env_id)
        versions[env_id] = spec.version
    return {
        "env_ids": env_ids,
        "env_versions": versions,
        "clfd_bench": __version__,
        "mujoco": _version("mujoco"),
        "mink": _version("mink"),
        "gymnasium": _version("gymnasium"),
        "fingerprint": sim_fingerprint(),
    }


# ----------------------------------------------------------------------------- R matrix
def sim_fields(success: Sequence[Sequence[Sequence[bool] | None]],
               scored: Sequence[bool] | None = None) -> dict[str, Any]:
    """``success``, ``sim_accuracy`` and ``sim_cl_metrics`` of a run from its execution
    outcomes (what the training protocol and :func:`evaluate_run` write).

    Args:
        success: ``[M][<=M][N_j]``: ``success[i][j]`` the outcome of each demo of task ``j``
            after learning task ``i`` (``j <= i``; rows may be ragged or padded with None).
        scored: ``[M]`` whether task ``j`` was executed (False for tasks without an env); by
            default every task.

    Returns:
        ``{"success": [M][M] (lists of bools, None for j > i or unscored tasks),
        "sim_accuracy": [M][M] fraction of successful demos (None above the diagonal),
        "sim_cl_metrics": {"ACC", "REM", "BWT"} (:mod:`clfd_bench.metrics.cl`; None when
        undefined, e.g. BWT/REM with one task)}``. With unscored tasks the same formulas run
        over the scored tasks' columns ``j`` (every row ``i >= j``).
    """
    from clfd_bench.metrics.cl import acc, bwt, rem

    m = len(success)
    scored = [True] * m if scored is None else [bool(s) for s in scored]
    if len(scored) != m:
        raise ValueError(f"scored needs one flag per task ({m}), got {len(scored)}")
    out_success: list[list[list[bool] | None]] = []
    r = np.full((m, m), np.nan)
    for i in range(m):
        row: list[list[bool] | None] = []
        for j in range(m):
            cell = success[i][j] if (j <= i and j < len(success[i])) else None
            if cell is None or not scored[j]:
                row.append(None)
                continue
            flags = [bool(s) for s in cell]
            if not flags:
                raise ValueError(f"success[{i}][{j}] is empty: every executed task needs at "
                                 "least one demo")
            row.append(flags)
            r[i, j] = float(np.mean(flags))
        out_success.append(row)
    for i in range(m):
        for j in range(i + 1):
            if scored[j] and math.isnan(r[i, j]):
                raise ValueError(f"success[{i}][{j}] is missing: every scored task j <= i needs "
                                 "its outcomes")
    metrics: dict[str, float | None] = {"ACC": None, "REM": None, "BWT": None}
    if all(scored):
        metrics = {"ACC": acc(r), "REM": rem(r), "BWT": bwt(r)}
    elif any(scored):
        # The same formulas over the scored columns only (rows after unscored tasks count).
        low = [(i, j) for i in range(m) for j in range(i + 1) if scored[j]]
        back = [r[i, j] - r[j, j] for i, j in low if i > j]
        b = float(np.mean(back)) if back else math.nan
        metrics = {"ACC": float(np.mean([r[i, j] for i, j in low])),
                   "REM": math.nan if math.isnan(b) else 1.0 - abs(min(b, 0.0)), "BWT": b}
    accuracy = [[None if (j > i or math.isnan(r[i, j])) else float(r[i, j]) for j in range(m)]
                for i in range(m)]
    return {
        "success": out_success,
        "sim_accuracy": accuracy,
        "sim_cl_metrics": {k: _finite_or_none(v) if v is not None else None
                           for k, v in metrics.items()},
    }


# ----------------------------------------------------------------------------- saved runs
@dataclasses.dataclass(frozen=True)
class SavedRun:
    """What a run directory of ``clfd-bench train`` says about itself.

    Attributes:
        path: the run directory.
        results: its ``results.json``.
        dataset: the dataset name; order: the task order.
        task_names: names of every task of the run, in order.
        num_learned: tasks learned so far (evaluation rows present).
    """

    path: Path
    results: dict[str, Any]
    dataset: str
    order: int
    task_names: list[str]
    num_learned: int

    @property
    def learned(self) -> list[str]:
        """Names of the learned tasks."""
        return self.task_names[: self.num_learned]

    def demos(self) -> list[np.ndarray]:
        """The learned tasks' demonstrations ``[N, T, D]`` (data layer), in task order."""
        from clfd_bench.data import load_dataset

        ds = load_dataset(self.dataset, order=self.order)
        if list(ds.task_names[: len(self.task_names)]) != self.task_names:
            raise ValueError(f"{self.path}: results.json tasks {self.task_names} differ from "
                             f"{self.dataset} order {self.order} ({list(ds.task_names)})")
        return [np.asarray(ds.tasks[j].demos) for j in range(self.num_learned)]


def read_results(run_dir: str | Path) -> dict[str, Any]:
    """``RUN_DIR/results.json``.

    Raises:
        FileNotFoundError: it does not exist (the message says what RUN_DIR must be).
    """
    path = Path(run_dir) / RESULTS_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: RUN_DIR must be a directory written by "
                                "`clfd-bench train` (it holds results.json)")
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def load_run(run_dir: str | Path) -> SavedRun:
    """Reads a run directory's ``results.json`` into a :class:`SavedRun`."""
    run_dir = Path(run_dir)
    results = read_results(run_dir)
    tasks = results.get("tasks")
    if not tasks:
        raise ValueError(f"{run_dir / RESULTS_FILE} has no 'tasks'; was it written by "
                         "`clfd-bench train`?")
    names = [t["name"] if isinstance(t, Mapping) else str(t) for t in tasks]
    cfg = results.get("config") or {}
    dataset = cfg.get("dataset") or results.get("dataset")
    if not dataset:
        raise ValueError(f"{run_dir / RESULTS_FILE} names no dataset (config.dataset); cannot "
                         "pick envs")
    if isinstance(results.get("tasks_done"), int):
        done = int(results["tasks_done"])
    else:
        rows = [len(v) for v in (results.get("errors") or {}).values() if isinstance(v, list)]
        done = min(rows) if rows else len(results.get("train_time_s") or [])
    return SavedRun(path=run_dir, results=results, dataset=str(dataset),
                    order=int(cfg.get("order", 0)), task_names=names, num_learned=done)


def load_run_predictions(run_dir: str | Path, after_task: int) -> dict[int, np.ndarray]:
    """The saved predictions of a run after learning task ``after_task``.

    Reads ``RUN_DIR/predictions/after_task_{i}.npz`` (written by the training protocol).

    Returns:
        task index ``j`` (``j <= after_task``) -> ``[N, T, D]`` float64 in data units.

    Raises:
        FileNotFoundError: the file is missing (the message says how to regenerate it).
    """
    path = Path(run_dir) / PREDICTIONS_DIR / f"after_task_{after_task}.npz"
    if not path.is_file():
        raise FileNotFoundError(
            f"{path} not found: the run saved no predictions after task {after_task}; re-run "
            "`clfd-bench train` with the same arguments (it resumes and rewrites them)")
    out: dict[int, np.ndarray] = {}
    with np.load(path, allow_pickle=False) as npz:
        for key in npz.files:
            j = _task_key(key)
            if j is not None:
                out[j] = np.asarray(npz[key], dtype=np.float64)
    missing = [j for j in range(after_task + 1) if j not in out]
    if missing:
        raise ValueError(f"{path} holds no predictions of tasks {missing} (keys: {npz.files})")
    return out


def _task_key(key: str) -> int | None:
    """Task index of an npz key "task_{j}" (or "{j}")."""
    digits = key[5:] if key.startswith("task_") else key
    return int(digits) if digits.isdigit() else None


def _prediction_key(env_id: str, demo: int, settle_s: float | None,
                    trajectory: np.ndarray) -> str:
    digest = hashlib.sha256()
    digest.update(f"{env_id}|{demo}|{settle_s}|{trajectory.shape}|".encode())
    digest.update(np.ascontiguousarray(trajectory, dtype=np.float64).tobytes())
    return digest.hexdigest()[:32]


def _load_cache(path: Path, fingerprint: str) -> dict[str, dict[str, Any]]:
    if not path.is_file():
        return {}
    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)
    except (OSError, json.JSONDecodeError):
        return {}  # unreadable: start over (it is only a cache)
    if doc.get("schema") != _CACHE_SCHEMA or doc.get("fingerprint") != fingerprint:
        return {}
    return dict(doc.get("entries") or {})


def _save_cache(path: Path, fingerprint: str, entries: Mapping[str, Any]) -> None:
    atomic_write_json(path, {"schema": _CACHE_SCHEMA, "fingerprint": fingerprint,
                             "entries": dict(entries)}, indent=None)


def _nonfinite_summary(demo: int) -> dict[str, Any]:
    return {"demo": demo, "success": False, "mean_tracking_error": None,
            "max_tracking_error": None, "mean_rotation_error": None,
            "failure_reason": "prediction contains NaN/inf (diverged); not executed",
            "steps": 0}


def _run_job(job: tuple[str, str, int, np.ndarray, float | None]) -> tuple[str, dict, float]:
    """Worker side of :func:`evaluate_run`: (key, env id, demo, trajectory, settle) ->
    (key, summary, wall seconds)."""
    key, env_id, demo, traj, settle_s = job
    res = execute(get_env(env_id), traj, demo, settle_s=settle_s)
    return key, res.summary(), res.wall_s


def _worker_init() -> None:
    import os

    os.environ.setdefault("CLFD_NO_PROGRESS", "1")
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # pragma: no cover - torch is a dependency
        pass


def _env_ids(dataset: str, task_names: Sequence[str]) -> list[str | None]:
    from clfd_bench.envs.registration import env_id_for

    out: list[str | None] = []
    for name in task_names:
        try:
            out.append(env_id_for(dataset, name))
        except KeyError:
            out.append(None)
    return out


def execute_after_task(dataset: str, task_names: Sequence[str],
                       predictions: Sequence[np.ndarray], *, run_dir: str | Path | None = None,
                       settle_s: float | None = None) -> dict[str, list]:
    """Executes the predictions made after learning a task: the training protocol's hook.

    Args:
        dataset: the run's dataset.
        task_names: the names of the tasks ``0..i`` predicted (one per prediction).
        predictions: ``[i + 1]`` arrays ``[N, T, D]`` (data units), task ``j``'s predictions
            from each demo's start.
        run_dir: the run directory: results are looked up in and added to its execution
            cache (``sim_cache.json``), so a prediction that did not change since an earlier
            task (SG, HN, CHN) is not executed again and ``clfd-bench evaluate`` afterwards
            finds everything cached.
        settle_s: seconds of settling after each trajectory (default: the rollout's).

    Returns:
        ``{"success": [i + 1] lists of bools (None for a task without env),
        "tracking_error": same shape, mean hand position error (m) or None,
        "failure_reason": same shape, str or None}``; feed ``success`` rows to
        :func:`sim_fields`.
    """
    if len(task_names) != len(predictions):
        raise ValueError(f"one task name per prediction: {len(task_names)} names, "
                         f"{len(predictions)} predictions")
    fingerprint = sim_fingerprint()
    cache_path = Path(run_dir) / CACHE_FILE if run_dir is not None else None
    cache = _load_cache(cache_path, fingerprint) if cache_path is not None else {}
    out: dict[str, list] = {"success": [], "tracking_error": [], "failure_reason": []}
    for env_id, preds in zip(_env_ids(dataset, task_names), predictions, strict=True):
        if env_id is None:
            for v in out.values():
                v.append(None)
            continue
        cells = []
        for d, traj in enumerate(np.asarray(preds, dtype=np.float64)):
            key = _prediction_key(env_id, d, settle_s, traj)
            if key not in cache:
                cache[key] = (_nonfinite_summary(d) if not np.isfinite(traj).all()
                              else execute(get_env(env_id), traj, d, settle_s=settle_s).summary())
            cells.append(cache[key])
        out["success"].append([bool(c["success"]) for c in cells])
        out["tracking_error"].append([c["mean_tracking_error"] for c in cells])
        out["failure_reason"].append([c["failure_reason"] for c in cells])
    if cache_path is not None:
        _save_cache(cache_path, fingerprint, cache)
    return out


def evaluate_run(run_dir: str | Path, rerun_path: str | Path | None = None, *,
                 force: bool = False, settle_s: float | None = None,
                 workers: int = 1) -> dict[str, Any]:
    """Scores a saved run by execution, without training.

    For every evaluation point (after task ``i``, task ``j <= i``, demo ``d``) the saved
    prediction (``predictions/after_task_{i}.npz``) is executed in task ``j``'s env; then
    ``results.json`` gains (or has replaced) ``success``, ``sim_accuracy``, ``sim_cl_metrics``
    (see :func:`sim_fields`) and ``sim`` (see :func:`sim_provenance`, plus ``tracking_error``
    ``[i][j][d]`` mean hand position error in m, ``failure_reason`` ``[i][j][d]``, counts and
    wall time). Every other key of ``results.json`` is kept as it is. Tasks without an env
    (RoboTasks9's extra tasks) get None and are left out of ``sim_cl_metrics``; a prediction
    with NaN/inf counts as a failure without being executed.

    Each distinct (env, demo, prediction) is executed once: identical predictions of a task
    after later tasks (SG, HN, CHN keep them) and points already in ``RUN_DIR/sim_cache.json``
    under the same :func:`sim_fingerprint` are reused. The cache is saved as rollouts finish,
    so an interrupted evaluation resumes.

    Args:
        run_dir: a directory written by ``clfd-bench train``.
        rerun_path: also log every rollout to this ``.rrd`` file (rerun-sdk); every point is
            then executed in this process (cached ones too, to have their paths).
        force: ignore the execution cache.
        settle_s: seconds of settling after each trajectory (default: the rollout's).
        workers: processes executing rollouts in parallel (1: in this process).

    Returns:
        The fields written into ``results.json``.
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    run = load_run(run_dir)
    run_dir, dataset, names, m = run.path, run.dataset, run.task_names, run.num_learned
    if m == 0:
        raise ValueError(f"{run_dir / RESULTS_FILE} has no finished task to evaluate; train "
                         "at least one task first")
    env_ids = _env_ids(dataset, names[:m])
    if not any(env_ids):
        raise ValueError(f"no task of {dataset} {names[:m]} has a simulated env; nothing to "
                         "execute")

    fingerprint = sim_fingerprint()
    cache_path = run_dir / CACHE_FILE
    cache = {} if force else _load_cache(cache_path, fingerprint)
    # Every evaluation point -> its key; the distinct keys still to execute -> their job.
    points: list[tuple[int, int, int, str, np.ndarray]] = []
    jobs: dict[str, tuple[str, str, int, np.ndarray, float | None]] = {}
    for i in range(m):
        preds = load_run_predictions(run_dir, i)
        for j in range(i + 1):
            env_id = env_ids[j]
            if env_id is None:
                continue
            for d, traj in enumerate(preds[j]):
                key = _prediction_key(env_id, d, settle_s, traj)
                points.append((i, j, d, key, traj))
                if not np.isfinite(traj).all():
                    cache[key] = _nonfinite_summary(d)
                elif (key not in cache or rerun_path is not None) and key not in jobs:
                    jobs[key] = (key, env_id, d, traj, settle_s)

    # One task's env after the other: each env is built once (the env cache is bounded).
    first_seen = {env_id: k for k, env_id in enumerate(dict.fromkeys(e for e in env_ids if e))}
    jobs = dict(sorted(jobs.items(), key=lambda kv: (first_seen[kv[1][1]], kv[1][2])))
    t_start = time.perf_counter()
    wall = 0.0
    last_save = time.monotonic()

    def done(key: str, summary: dict[str, Any], seconds: float) -> None:
        nonlocal wall, last_save
        cache[key] = summary
        wall += seconds
        if time.monotonic() - last_save > 5.0:
            _save_cache(cache_path, fingerprint, cache)
            last_save = time.monotonic()

    bar = progress(total=len(jobs), desc=f"sim {run_dir.name}", unit="rollout")
    try:
        if rerun_path is not None:
            _execute_logged(run, points, jobs, env_ids, rerun_path, done, bar)
        elif workers == 1 or len(jobs) <= 1:
            for job in jobs.values():
                done(*_run_job(job))
                bar.update(1)
        else:
            import concurrent.futures
            import multiprocessing

            ctx = multiprocessing.get_context("spawn")  # no inherited GL / torch threads
            with concurrent.futures.ProcessPoolExecutor(
                    max_workers=min(workers, len(jobs)), mp_context=ctx,
                    initializer=_worker_init) as pool:
                for result in pool.map(_run_job, jobs.values(), chunksize=1):
                    done(*result)
                    bar.update(1)
    finally:
        bar.close()
        _save_cache(cache_path, fingerprint, cache)

    success: list[list[list[bool] | None]] = [[None] * m for _ in range(m)]
    track: list[list[list[float | None] | None]] = [[None] * m for _ in range(m)]
    reasons: list[list[list[str | None] | None]] = [[None] * m for _ in range(m)]
    for i, j, _, key, _ in points:
        hit = cache[key]
        for table, value in ((success, bool(hit["success"])),
                             (track, hit["mean_tracking_error"]),
                             (reasons, hit["failure_reason"])):
            if table[i][j] is None:
                table[i][j] = []
            table[i][j].append(value)

    fields = sim_fields(success, scored=[e is not None for e in env_ids])
    sim = sim_provenance(dataset, names[:m])
    sim.update({
        "evaluated_tasks": m,
        "settle_s": settle_s,
        "rollouts": len(points),
        "rollouts_executed": len(jobs),
        "rollouts_cached": len(points) - len(jobs),
        "rollout_wall_s": round(wall, 3),
        "wall_s": round(time.perf_counter() - t_start, 3),
        "evaluated_at": datetime.datetime.now(datetime.timezone.utc).isoformat(
            timespec="seconds"),
        "tracking_error": track,
        "failure_reason": reasons,
    })
    fields["sim"] = sim
    # Re-read just before writing, so keys another process updated meanwhile are kept.
    latest = read_results(run_dir)
    latest.update(fields)
    atomic_write_json(run_dir / RESULTS_FILE, latest)
    return fields


def _execute_logged(run: SavedRun, points, jobs, env_ids, rerun_path, done, bar) -> None:
    """Executes ``jobs`` in this process with traces and logs every point to a rerun file."""
    from clfd_bench.viz.rerun_log import RolloutLogger

    demos = run.demos()
    executed: dict[str, tuple[ExecResult, Any]] = {}
    with RolloutLogger(rerun_path, recording_name=f"evaluate {run.path.name}") as logger:
        # Task by task, so each env is built once (the env cache is bounded).
        for i, j, d, key, traj in sorted(points, key=lambda p: (p[1], p[0], p[2])):
            if key not in jobs:  # not executable (NaN/inf): nothing to show
                continue
            if key not in executed:
                env = get_env(env_ids[j])
                res = execute(env, traj, d, trace=True, settle_s=jobs[key][4])
                executed[key] = (res, env.unwrapped)
                done(key, res.summary(), res.wall_s)
                bar.update(1)
            res, base = executed[key]
            logger.log_rollout(f"after_task_{i}/{run.task_names[j]}/demo_{d}", base, res,
                               prediction=traj, demonstration=demos[j][d])
