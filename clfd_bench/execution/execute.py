"""Execute one trajectory, or one task's predictions, on the simulated Panda.

:func:`execute` runs a trajectory through :func:`clfd_bench.execution.rollout.rollout` from a
demo's start and returns an :class:`ExecResult`; :func:`execute_predictions` does it for every
demo of a task's predictions ``[N, T, D]`` in the task's env (made once per process,
:func:`clfd_bench.execution.env_pool.get_env`).

Units: tracking errors are metres (position) and radians (rotation) of the tracked ``hand``
frame, measured after each trajectory step.

Every failure has a kind (:data:`FAILURE_KINDS`): the env's executability checks (``reflex``,
``tracking``, ``unreachable``, ``collision``), a physics ``blowup``, a prediction that
``diverged`` (NaN/inf, not executed), or ``task`` (the task's success criterion said no: at
the end, or as soon as the env decided it, :meth:`clfd_bench.envs.base.PandaEnv.decided_failure`;
a rollout that stops there does not meet a motion limit it would have broken later). An
execution counts its first failure.

Every env reports the checks behind its success decision in ``info["checks"]``
(:class:`clfd_bench.envs.checks.Check` as JSON); :meth:`ExecResult.summary` keeps them, and a
task failure's reason names every failed check, its value and its bound (``"task not achieved:
goal 11.2 mm > 10 mm allowed (last ink point to the task's end point)"``,
:func:`explain_check`). An env that reports none keeps the older text (its task-specific info
values).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from clfd_bench.envs.checks import Check, check_from_json
from clfd_bench.execution.env_pool import get_env
from clfd_bench.execution.trace import FrameHook, Trace, tracer
from clfd_bench.io import json_safe

__all__ = ["FAILURE_KINDS", "ExecResult", "checks_reason", "execute", "execute_predictions",
           "explain_check", "failure_kind", "failure_reason"]

#: Kinds of failure, in the order reports list them.
FAILURE_KINDS = ("reflex", "tracking", "unreachable", "collision", "blowup", "diverged", "task")
#: info keys every env reports; the others are task-specific and explain a failure.
_BASE_INFO_KEYS = frozenset({"is_success", "tracking_error", "ik_error", "demo", "step",
                             "failure_reason", "failure", "stopped_early"})


@dataclasses.dataclass
class ExecResult:
    """Outcome of executing one predicted trajectory.

    Attributes:
        demo: the demo whose start (and scene) the env was reset to.
        success: the env's physical success decision after the trajectory and settling.
        mean_tracking_error: mean position error (m) of the hand frame over the trajectory.
        max_tracking_error: its maximum (m).
        mean_rotation_error: mean rotation error (rad) of the hand frame.
        failure_reason: None on success; else why: the env's own reason for ending the episode
            (a motion limit, tracking, reach, collision or physics blow-up, naming the limit
            and the step), or "task not achieved: " and the failed checks
            (:meth:`Check.describe`, e.g. "goal 0.0112 m > 0.01 m") followed by the env's
            task-specific info (e.g. DTW of the ink, ink fraction, lid angle), or "task failed,
            decided after k of H steps" when the rollout stopped on a decided failure
            (``stop_when_decided``).
        failure_kind: None on success; else one of :data:`FAILURE_KINDS`.
        steps: env steps run (trajectory + settling; fewer when the rollout stopped on a
            decided failure, see ``execute``).
        wall_s: wall-clock seconds of the rollout.
        info: the env's final info, JSON-safe (non-finite floats become None); its
            ``checks`` (when the env reports them) are the criterion's checks, see
            :meth:`checks`.
        trace: the step-by-step :class:`Trace` when requested, else None.
        frames: rendered frames ``[H, W, 3]`` uint8 when recorded, else None.
    """

    demo: int
    success: bool
    mean_tracking_error: float
    max_tracking_error: float
    mean_rotation_error: float
    failure_reason: str | None
    failure_kind: str | None
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
            "failure_kind": self.failure_kind,
            "steps": self.steps,
            "stopped_early": self.stopped_early,
            "checks": self.checks_json(),
        }

    @property
    def stopped_early(self) -> bool:
        """True when the rollout stopped on a decided failure before its horizon (its checks
        then describe the partial episode; see :func:`execute`)."""
        return isinstance(self.info.get("stopped_early"), Mapping)

    def checks_json(self) -> list[dict[str, Any]] | None:
        """The env's final ``info["checks"]`` (:meth:`clfd_bench.envs.checks.Check.to_json`
        dicts, in the env's order), or None when the env reports none."""
        checks = self.info.get("checks")
        return None if checks is None else [dict(c) for c in checks]

    def checks(self) -> list[Check] | None:
        """The env's final checks as :class:`Check` objects, or None when it reports none."""
        raw = self.checks_json()
        return None if raw is None else [check_from_json(c) for c in raw]


def _finite_or_none(x: Any) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _quantity(value: float, unit: str, scale: float) -> str:
    """``value`` in a unit a reader takes in at once: metres below 0.1 m (by ``scale``, the
    larger of value and bound) as mm, below 1 m as cm; degrees with the degree sign."""
    if unit == "m":
        if scale < 0.1:
            return f"{value * 1000:.3g} mm"
        if scale < 1.0:
            return f"{value * 100:.3g} cm"
        return f"{value:.3g} m"
    if unit == "deg":
        return f"{value:.3g}°"
    return f"{value:.3g}" + (f" {unit}" if unit else "")


def explain_check(check: Check) -> str:
    """A failed (or passed) check in words, naming it: ``"goal 10.6 mm > 10 mm allowed (last
    ink point to the task's end point)"``, ``"beans_in_scoop 0 < 3 needed"``,
    ``"held not met (the scoop never slipped)"``, ``"coverage not measured (no ink)"``."""
    note = f" ({check.note})" if check.note else ""
    if check.value is None or not math.isfinite(float(check.value)):
        return f"{check.name} not measured{note}"
    value = float(check.value)
    if check.op == ">=" and check.bound == 1.0 and check.unit == "" and value in (0.0, 1.0):
        return f"{check.name} {'met' if check.passed else 'not met'}{note}"  # a yes/no flag
    scale = max(abs(value), abs(check.bound))
    v, b = _quantity(value, check.unit, scale), _quantity(check.bound, check.unit, scale)
    if check.op == "<=":
        return f"{check.name} {v} {'<=' if check.passed else '>'} {b} allowed{note}"
    return f"{check.name} {v} {'>=' if check.passed else '<'} {b} needed{note}"


def checks_reason(checks: Sequence[Check]) -> str | None:
    """``"task not achieved: "`` and every failed check in words (:func:`explain_check`), or
    None when every check passed (or there are none)."""
    failed = [explain_check(c) for c in checks if not c.passed]
    return "task not achieved: " + "; ".join(failed) if failed else None


def failure_reason(success: bool, info: Mapping[str, Any]) -> str | None:
    """None on success; else why, in words (see :attr:`ExecResult.failure_reason`): the env's
    own reason for ending the episode, the decided failure a rollout stopped on, or "task not
    achieved" and the failed checks of ``info["checks"]`` (:func:`explain_check`); an env
    that reports no checks gets its other scalar info values instead."""
    if success:
        return None
    if info.get("failure_reason"):
        return str(info["failure_reason"])
    stopped = info.get("stopped_early")
    if isinstance(stopped, Mapping):
        return (f"task failed, decided after {stopped['stopped_at']} of {stopped['horizon']} "
                f"steps (the rollout stopped there): {stopped['reason']}")
    named = checks_reason(_info_checks(info))
    if named is not None:
        return named
    parts = []
    for key, value in info.items():
        if key in _BASE_INFO_KEYS or key == "checks":
            continue
        if isinstance(value, (bool, np.bool_)):
            parts.append(f"{key}={bool(value)}")
        elif isinstance(value, (int, float, np.integer, np.floating)):
            parts.append(f"{key}={float(value):.4g}")
        elif isinstance(value, (list, tuple)) and all(
                isinstance(v, (int, float, np.integer, np.floating)) for v in value):
            parts.append(f"{key}=[{', '.join(f'{float(v):.4g}' for v in value)}]")
    return "task not achieved" + (f" ({', '.join(parts)})" if parts else "")


def _info_checks(info: Mapping[str, Any]) -> list[Check]:
    """``info["checks"]`` as :class:`Check` objects (empty when the env reports none)."""
    raw = info.get("checks")
    if not isinstance(raw, (list, tuple)):
        return []
    return [check_from_json(c) for c in raw if isinstance(c, Mapping)]


def failure_kind(success: bool, info: Mapping[str, Any]) -> str | None:
    """None on success; else the failure's kind (:data:`FAILURE_KINDS`): what the env reports
    in ``info["failure"]["kind"]``, ``blowup`` for a physics blow-up without one, else
    ``task``."""
    if success:
        return None
    failure = info.get("failure")
    if isinstance(failure, Mapping) and failure.get("kind") in FAILURE_KINDS:
        return str(failure["kind"])
    if info.get("failure_reason"):
        return "blowup"
    return "task"


def execute(env, trajectory: np.ndarray | Sequence[np.ndarray], demo: int, *,
            record: bool = False, trace: bool = False, settle_s: float | None = None,
            fps: float = 30.0, frame_hook: FrameHook | None = None,
            stop_when_decided: bool | None = None) -> ExecResult:
    """Executes one trajectory in ``env`` from demo ``demo``'s start.

    Args:
        env: a clfd-bench env (e.g. from :func:`get_env`; with ``record``, made with
            ``render=True``).
        trajectory: ``[T, D]`` in the dataset's units (see :func:`execute_predictions`); for
            ``clfd/HelloWorld-v3`` one ``[T_k, 2]`` array per letter.
        demo: the demo to reset to (``reset(options={"demo": demo})``).
        record: keep the env's own rendered frames in ``ExecResult.frames`` (``fps`` per
            simulated second).
        trace: keep the step-by-step :class:`Trace`.
        settle_s: seconds of settling after the trajectory (default: the rollout's).
        frame_hook: stream frames of a custom renderer (e.g. with paths drawn) to a sink
            instead; works with an env made without rendering.
        stop_when_decided: stop the rollout once the env has decided a failure (see
            :func:`clfd_bench.execution.rollout.rollout`): same success, fewer steps; its
            failure kind is then ``task``. Default: on, except when recording, tracing or
            streaming frames (those show the whole rollout).

    Returns:
        An :class:`ExecResult`.
    """
    from clfd_bench.execution.rollout import rollout

    wrapped = tracer(env, frame_hook) if (trace or frame_hook is not None) else env
    kwargs: dict[str, Any] = {} if settle_s is None else {"settle_s": float(settle_s)}
    t0 = time.perf_counter()
    if stop_when_decided is None:
        stop_when_decided = not (record or trace or frame_hook is not None)
    res = rollout(wrapped, trajectory, demo=int(demo), record=record, fps=fps,
                  stop_when_decided=stop_when_decided, **kwargs)
    wall = time.perf_counter() - t0
    err = res.tracking_error_pos[np.isfinite(res.tracking_error_pos)]
    rot = res.tracking_error_rot[np.isfinite(res.tracking_error_rot)]
    return ExecResult(
        demo=int(demo),
        success=bool(res.success),
        mean_tracking_error=float(err.mean()) if err.size else math.nan,
        max_tracking_error=float(err.max()) if err.size else math.nan,
        mean_rotation_error=float(rot.mean()) if rot.size else math.nan,
        failure_reason=failure_reason(bool(res.success), res.info),
        failure_kind=failure_kind(bool(res.success), res.info),
        steps=int(res.steps),
        wall_s=wall,
        info=json_safe(dict(res.info)),
        trace=wrapped.trace() if trace else None,
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
