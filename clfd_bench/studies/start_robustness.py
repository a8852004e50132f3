"""Robustness to the starting position (the paper's appendix study), with execution in simulation.

For each task one demonstration is chosen (seeded); ``n`` start positions are drawn uniformly
from the *volume* of a ball of radius ``R`` around that demo's start position (the same starts
for every method); the orientation start is the demo's start quaternion. Every trained run
predicts, with the demo's time steps (``horizon`` times as many with the same step: 1 is the
paper's), from each start and from the demo's own start (the reference, start Δ = 0). Per
start we record the start Δ (m), the end-position Δ to the task's goal position (m; a
prediction that is not finite counts as infinitely far, i.e. "Large": end Δ > :data:`LARGE_M`),
when the prediction settles (enters the goal's :data:`SETTLE_M` ball and stays in it, in
multiples of the demo's duration; with ``horizon`` > 1 this shows how long a stable model
takes to converge) and whether the prediction succeeds when executed in the task's simulated
scene.

**Datasets** (:data:`STUDY_DATASETS`). RoboTasks (the paper's study): 3-D positions in metres,
executed. LASA: the planar shapes as laid on the simulated table (``Task.sim_scale`` metres
per LASA unit, 1 cm = 3.33 units), starts uniform in the *disc* of radius ``R`` (metres,
converted to units), distances reported in metres like RoboTasks'. LASA runs are not executed
(``execute=False`` is required): the writing envs' success test compares the written path
with the demo's, which a prediction from another start does not reproduce by design, so only
the end Δ (does the skill still reach its goal?) is meaningful there.

**Execution from a perturbed start.** The scene (props, grasp) is the chosen demo's: the robot
starts at that demo's start configuration, holding the prop as in the demo (this is what the
env's ``reset`` does, and the only start for which the props are consistent with the grasp:
the box lid's handle, the plate in its rack). The hand then first moves to the prediction's
first pose along a straight line (minimum-jerk-like cosine profile, mean speed
``approach_speed``, 0.1 m/s by default, about the demos' speed), carrying the prop, and then
executes the prediction sample by sample (:func:`clfd_bench.execution.rollout.rollout`, which also
decides success after the settling time). At start Δ = 0 there is no approach, so the
reference is exactly the harness's execution of the prediction from the demo's start. No
action is ever a jump: the IK tracker's joint velocity limits would bound it anyway, but a jump
would yank the held prop. A prediction that is not finite, or leaves a 10 m box around the robot
(:data:`DIVERGED_M`), is not executed and counts as a failure; a prediction the robot cannot
reach is tracked as closely as the IK allows and fails on the task's own success test.

Results are cached per (label, task) in ``<out>/cache/<label>/<task>.json``, keyed by the run's
checkpoint, the demo, the seed, the radius and the approach speed; start ``i`` is drawn from its
own seeded generator, so raising ``n`` keeps the first starts and reruns only execute new
ones. Tables and figures: :mod:`clfd_bench.studies.start_robustness_plots`.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.io import atomic_write_json
from clfd_bench.runs import RunDir, RunFileError

__all__ = [
    "BINS_CM", "DIVERGED_M", "LARGE_M", "SETTLE_M", "STUDY_DATASETS", "StartRecord",
    "StudyConfig", "approach_path", "check_executable", "choose_demo", "draw_starts",
    "end_deltas", "execute", "horizon_times", "run_label", "run_start_study", "sample_ball",
    "settle_times", "study_dataset",
]

#: Start-Δ bins of the summary and the figure, centimetres.
BINS_CM = (0.0, 5.0, 10.0, 15.0, 20.0)
#: End Δ above this (metres) is "Large" (the paper's band above 100 cm).
LARGE_M = 1.0
#: A prediction has settled once it stays within this distance of the goal position (metres;
#: on LASA the shape's distance as laid on the simulated table).
SETTLE_M = 0.01
#: A prediction with any position coordinate beyond this (metres) has diverged: not executed.
DIVERGED_M = 10.0
#: Reference record's start index (the prediction from the demo's own start, start Δ = 0).
REFERENCE = -1
DATASET = "robotasks"
#: Datasets the study runs on: dataset -> position dimensions (the rest is orientation).
STUDY_DATASETS = {"robotasks": 3, "lasa": 2}
_CACHE_VERSION = 2
#: A prediction's first position this close to the demo's start (float32 rounding) needs no
#: approach, metres.
_SAME_START_M = 1e-4


@dataclass(frozen=True)
class StudyConfig:
    """Settings of one study.

    Attributes:
        seed: seeds the demo choice and the starts (the same for every method).
        starts: number of start positions per task.
        radius: radius of the ball the starts are drawn from, metres.
        approach_speed: mean speed of the move from the demo's start pose to a prediction's
            first pose before it is executed, m/s.
        execute: run the rollouts (False: only the trajectory-level numbers).
        horizon: prediction length as a multiple of the demo's duration (same time step);
            1 is the paper's study, more asks whether predictions settle at the goal.
    """

    seed: int = 0
    starts: int = 100
    radius: float = 0.20
    approach_speed: float = 0.1
    execute: bool = True
    horizon: float = 1.0

    def __post_init__(self) -> None:
        if self.starts < 1:
            raise ValueError(f"starts must be >= 1, got {self.starts}")
        if not self.radius > 0:
            raise ValueError(f"radius must be > 0 (metres), got {self.radius}")
        if not self.approach_speed > 0:
            raise ValueError(f"approach_speed must be > 0 (m/s), got {self.approach_speed}")
        if not 1.0 <= self.horizon <= 100.0:
            raise ValueError(f"horizon must be in [1, 100] (times the demo's duration), got "
                             f"{self.horizon}")


@dataclass
class StartRecord:
    """One (label, task, start): the row of ``records.csv``.

    ``start_index`` is :data:`REFERENCE` (-1) for the prediction from the demo's own start.
    ``end_delta_m`` is ``inf`` for a non-finite prediction; ``success`` None when not executed.
    ``settle_time``: when the prediction entered the goal's :data:`SETTLE_M` ball for good, in
    multiples of the demo's duration (:func:`settle_times`; ``inf``: not within the horizon).
    ``max_tracking_error_m``: the largest distance (m) between the hand and its commanded pose
    during the execution (large when the hand was blocked or the pose out of reach);
    ``outcome``: the env's final task quantities (e.g. ``lid_angle_deg``,
    ``blocks_in_place``, ``bean_fraction``).
    """

    method: str
    task: str
    demo: int
    start_index: int
    start_delta_m: float
    end_delta_m: float
    large: bool
    settle_time: float = math.inf
    success: bool | None = None
    failure: str | None = None
    approach_steps: int = 0
    max_tracking_error_m: float | None = None
    outcome: dict[str, Any] = field(default_factory=dict)
    start: list[float] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        for key in ("end_delta_m", "settle_time"):
            if not math.isfinite(d[key]):
                d[key] = None  # JSON has no inf: None = diverged / not settled
        return d

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> StartRecord:
        d = dict(d)
        for key in ("end_delta_m", "settle_time"):
            if d.get(key, math.inf) is None:
                d[key] = math.inf
        return cls(**d)


# --------------------------------------------------------------------------- sampling
def sample_ball(rng: np.random.Generator, n: int, radius: float,
                centre: np.ndarray | None = None, dim: int = 3) -> np.ndarray:
    """``n`` points uniform in the volume of a ball in ``dim`` dimensions -> ``[n, dim]``.

    Direction: a normalised Gaussian vector; distance ``radius * u**(1/dim)`` with u ~ U(0, 1)
    (the volume inside distance r grows as r^dim), so the mean distance is ``dim / (dim + 1)``
    of the radius (3/4 in a ball, 2/3 in a disc). ``centre`` (if given) sets ``dim``.
    """
    if centre is not None:
        dim = len(centre)
    direction = rng.standard_normal((n, dim))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    r = radius * rng.random(n) ** (1.0 / dim)
    centre = np.zeros(dim) if centre is None else np.asarray(centre, dtype=float)
    return centre + direction * r[:, None]


def draw_starts(seed: int, task: str, centre: np.ndarray, n: int, radius: float) -> np.ndarray:
    """The study's start positions for ``task`` -> ``[n, len(centre)]`` (``centre``'s units).

    Start i comes from its own generator (seeded by seed, the task's name and i), so the first
    starts do not change when ``n`` grows and every method gets the same starts."""
    key = [int(seed), *task.encode()]
    return np.concatenate([sample_ball(np.random.default_rng([*key, 1, i]), 1, radius, centre)
                           for i in range(n)])


def choose_demo(seed: int, task: str, num_demos: int) -> int:
    """The demo (seeded by seed and the task's name) whose start the study perturbs."""
    return int(np.random.default_rng([int(seed), *task.encode(), 0]).integers(num_demos))


def end_deltas(predictions: np.ndarray, goal: np.ndarray, pos_dim: int = 3,
               scale: float = 1.0) -> np.ndarray:
    """Distance of each prediction's last position to the goal position.

    Args:
        predictions: ``[N, T, D]`` (D >= pos_dim; positions first).
        goal: ``[D]`` or ``[pos_dim]`` goal (positions first).
        pos_dim: position dimensions (3 for RoboTasks, 2 for LASA).
        scale: metres per data unit (1 for RoboTasks, ``Task.sim_scale`` for LASA).

    Returns:
        ``[N]`` metres; ``inf`` where the last position is not finite (diverged).
    """
    last = np.asarray(predictions, dtype=float)[:, -1, :pos_dim]
    with np.errstate(over="ignore", invalid="ignore"):
        d = np.linalg.norm(last - np.asarray(goal, dtype=float)[:pos_dim], axis=1) * scale
    return np.where(np.isfinite(d), d, np.inf)


def settle_times(predictions: np.ndarray, goal: np.ndarray, times: np.ndarray,
                 duration: float, pos_dim: int = 3, scale: float = 1.0,
                 tol_m: float = SETTLE_M) -> np.ndarray:
    """When each prediction enters the goal's ``tol_m`` ball for good.

    Args:
        predictions: ``[N, T, D]`` (D >= pos_dim; positions first).
        goal: ``[D]`` or ``[pos_dim]`` goal (positions first).
        times: ``[T]`` the predictions' time stamps (seconds).
        duration: the demo's duration (seconds), the unit of the result.
        pos_dim: position dimensions.
        scale: metres per data unit.
        tol_m: the ball's radius, metres.

    Returns:
        ``[N]``: ``(times[i] - times[0]) / duration`` for the first ``i`` from which every
        position is within ``tol_m`` of the goal (0 when all are); ``inf`` when the last one
        is not (the prediction did not settle within its horizon, or is not finite).
    """
    p = np.asarray(predictions, dtype=float)[:, :, :pos_dim]
    times = np.asarray(times, dtype=float)
    if p.shape[1] != len(times) or not duration > 0:
        raise ValueError(f"settle_times: {p.shape[1]} samples against {len(times)} times, "
                         f"duration {duration}")
    with np.errstate(over="ignore", invalid="ignore"):
        d = np.linalg.norm(p - np.asarray(goal, dtype=float)[:pos_dim], axis=2) * scale
    outside = ~(d <= tol_m)  # NaN counts as outside
    last_out = p.shape[1] - 1 - np.argmax(outside[:, ::-1], axis=1)
    first_in = np.where(outside.any(axis=1), last_out + 1, 0)
    settled = first_in < p.shape[1]
    index = np.minimum(first_in, p.shape[1] - 1)
    return np.where(settled, (times[index] - times[0]) / duration, np.inf)


def diverged(prediction: np.ndarray, pos_dim: int = 3, scale: float = 1.0) -> bool:
    """True when ``prediction`` ``[T, D]`` is not finite or leaves a ``DIVERGED_M`` box
    (positions first, ``scale`` metres per unit)."""
    p = np.asarray(prediction, dtype=float)
    return bool(not np.isfinite(p).all() or np.abs(p[:, :pos_dim]).max() * scale > DIVERGED_M)


def horizon_times(times: np.ndarray, horizon: float) -> np.ndarray:
    """``times`` ``[T]`` continued with their step to ``horizon`` times the duration:
    ``[round((T - 1) * horizon) + 1]`` (``times`` itself for 1)."""
    times = np.asarray(times, dtype=float)
    if horizon == 1.0:
        return times
    n = int(round((len(times) - 1) * horizon)) + 1
    return times[0] + (times[1] - times[0]) * np.arange(n)


# --------------------------------------------------------------------------- execution
def approach_path(start_pose: np.ndarray, first_pose: np.ndarray, speed: float,
                  rate_hz: float = 60.0) -> np.ndarray:
    """Poses ``[K, 7]`` from ``start_pose`` towards ``first_pose`` (exclusive), K >= 0.

    Straight line in position with a cosine speed profile (zero speed at both ends), mean speed
    ``speed`` m/s, one pose per control step (none when the two positions are within 0.1 mm);
    orientation by normalised linear interpolation
    (the study's starts share the demo's start quaternion, so it rarely moves).
    """
    a, b = np.asarray(start_pose, dtype=float), np.asarray(first_pose, dtype=float)
    dist = float(np.linalg.norm(b[:3] - a[:3]))
    if dist <= _SAME_START_M:
        return np.empty((0, 7))
    k = int(math.ceil(dist / speed * rate_hz))
    if k == 0:
        return np.empty((0, 7))
    s = 0.5 * (1.0 - np.cos(np.pi * np.arange(k) / k))[:, None]  # [K, 1] in [0, 1)
    qb = b[3:] if np.dot(a[3:], b[3:]) >= 0 else -b[3:]
    quat = (1 - s) * a[3:] + s * qb
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    return np.concatenate([(1 - s) * a[:3] + s * b[:3], quat], axis=1)


_INFO_SKIP = ("is_success", "tracking_error", "ik_error", "demo", "step", "failure_reason",
              "task")


def _plain(value: Any) -> Any:
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return None if value is None else str(value)


def execute(env, demo: int, demo_start: np.ndarray, prediction: np.ndarray,
            approach_speed: float) -> dict[str, Any]:
    """Run ``prediction`` ``[T, 7]`` in ``env`` from ``demo``'s start (see the module doc).

    Returns:
        ``{"success", "failure" (reason or None), "approach_steps", "max_tracking_error_m",
        "outcome" (the env's final task quantities)}``.
    """
    from clfd_bench.execution.rollout import rollout

    if diverged(prediction):
        return {"success": False, "approach_steps": 0, "max_tracking_error_m": None,
                "failure": "diverged prediction (not finite or beyond 10 m): not executed",
                "outcome": {}}
    approach = approach_path(demo_start, prediction[0], approach_speed)
    result = rollout(env, np.concatenate([approach, prediction]), demo=demo)
    info = result.info
    reason = None
    if not result.success:
        reason = info.get("failure_reason")
        if reason is None and info.get("release_reason") == "slipped":
            reason = "prop slipped out of the grasp"
        reason = str(reason or "task success test not met")
    err = result.tracking_error_pos
    return {"success": bool(result.success), "failure": reason,
            "approach_steps": len(approach),
            "max_tracking_error_m": float(np.nanmax(err)) if np.isfinite(err).any() else None,
            "outcome": {k: _plain(v) for k, v in info.items() if k not in _INFO_SKIP}}


# --------------------------------------------------------------------------- the study
def _cache_key(run_dir: Path, task: str, demo: int, cfg: StudyConfig) -> dict[str, Any]:
    key = {"version": _CACHE_VERSION, "run": str(run_dir.resolve()),
           "checkpoint_sha256": RunDir(run_dir).checkpoint_sha256(), "task": task,
           "demo": demo, "seed": cfg.seed, "radius": cfg.radius,
           "approach_speed": cfg.approach_speed}
    if cfg.horizon != 1.0:  # absent at the paper's 1: caches made before it stay valid
        key["horizon"] = cfg.horizon
    return key


def _load_cache(path: Path, key: dict[str, Any]) -> dict[int, StartRecord]:
    try:
        doc = json.loads(path.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return {}
    if doc.get("key") != key:
        return {}  # another run, demo, seed, radius or speed: start over
    return {int(i): StartRecord.from_json(r) for i, r in doc["records"].items()}


def _save_cache(path: Path, key: dict[str, Any], cached: dict[int, StartRecord]) -> None:
    atomic_write_json(path, {"key": key, "records": {str(i): r.to_json()
                                                     for i, r in sorted(cached.items())}})


def check_executable(dataset: str, execute: bool) -> None:
    """Only RoboTasks runs are executed in this study (the module docstring); raises
    ValueError saying what to do otherwise."""
    if execute and dataset != DATASET:
        raise ValueError(f"{dataset} runs are not executed in this study (the writing test "
                         "compares with the demo's path, which another start does not "
                         "reproduce); add --no-exec: the end Δ is the measure there")


def study_dataset(runs: dict[str, Path]) -> str:
    """The one dataset every run was trained on (raises ValueError naming the mix)."""
    datasets = {label: _run_config(d)["dataset"] for label, d in runs.items()}
    if len(set(datasets.values())) > 1:
        raise ValueError("the runs were trained on different datasets ("
                         + ", ".join(f"{k}: {v}" for k, v in datasets.items())
                         + "); study one dataset at a time")
    return next(iter(datasets.values()), DATASET)


def study_tasks(runs: dict[str, Path]) -> list[str]:
    """The tasks every run learned, in the dataset's order 0."""
    from clfd_bench.data import load_dataset

    names = list(load_dataset(study_dataset(runs)).task_names)
    learned = [set(run_tasks(d)) for d in runs.values()]
    return [t for t in names if all(t in s for s in learned)]


def run_label(run_dir: Path) -> str:
    """How the study names a run: its method, with the NODE variant unless NODE^T
    (``hn``, ``hn (sNODE)``, ``sg (NODE^I)``)."""
    from clfd_bench.node_variants import node_label

    config = _run_config(run_dir)
    node = str(config.get("node") or "t")
    return str(config["method"]) + ("" if node == "t" else f" ({node_label(node)})")


def _run_config(run_dir: Path) -> dict[str, Any]:
    run_tasks(run_dir)  # raises ValueError saying what is wrong
    return RunDir(run_dir).read_results()["config"]


def run_tasks(run_dir: Path) -> list[str]:
    """The tasks a finished run learned, in its order (raises ValueError naming the problem)."""
    run = RunDir(run_dir)
    try:
        results = run.read_results()
    except RunFileError as exc:
        raise ValueError(str(exc)) from None
    if results is None or not run.has_checkpoint():
        datasets = "|".join(STUDY_DATASETS)
        raise ValueError(f"{run_dir} is not a trained run (no results.json/checkpoint.pt); train "
                         f"it with `clfd-bench train --method M --dataset {datasets} --profile "
                         f"fast --no-sim --out {run_dir}` or pass --methods to train here")
    dataset = results["config"]["dataset"]
    if dataset not in STUDY_DATASETS:
        raise ValueError(f"{run_dir} was trained on {dataset!r}; the start study needs runs on "
                         f"{' or '.join(STUDY_DATASETS)}")
    done = int(results.get("tasks_done", len(results.get("train_time_s", []))))
    return list(results["tasks"])[:done]


def run_start_study(runs: dict[str, Path], out: Path, cfg: StudyConfig,
                    tasks: list[str] | None = None) -> list[StartRecord]:
    """Run the study for every labelled run and task; returns every record (cached ones too).

    Args:
        runs: ``{label: run_dir}`` of trained runs on one of :data:`STUDY_DATASETS`
            (label: usually :func:`run_label`).
        out: output directory (the cache lives in ``out/cache``).
        cfg: the study's settings (LASA: ``execute=False``, see the module docstring).
        tasks: task names (default: those every run learned).
    """
    from clfd_bench.data import load_dataset
    from clfd_bench.envs.registration import env_id_for
    from clfd_bench.execution.env_pool import get_env
    from clfd_bench.harness.protocol import load_learner
    from clfd_bench.progress import progress

    dataset = study_dataset(runs)
    check_executable(dataset, cfg.execute)
    pos_dim = STUDY_DATASETS[dataset]
    ds = load_dataset(dataset)
    by_name = {t.name: t for t in ds.tasks}
    tasks = study_tasks(runs) if tasks is None else list(tasks)
    if not tasks:
        raise ValueError(f"the runs have no learned {dataset} task in common")
    records: list[StartRecord] = []
    total = len(runs) * len(tasks) * (cfg.starts + 1)
    bar = progress(total=total, desc="start study")
    try:
        for label, run_dir in runs.items():
            run_dir = Path(run_dir)
            order = run_tasks(run_dir)
            learner, _ = load_learner(run_dir)
            for name in tasks:
                task = by_name[name]
                scale = 1.0 if dataset == DATASET else float(task.sim_scale)  # m per unit
                demo = choose_demo(cfg.seed, name, task.demos.shape[0])
                demo_start = task.demos[demo, 0]
                positions = draw_starts(cfg.seed, name, demo_start[:pos_dim], cfg.starts,
                                        cfg.radius / scale)
                starts = np.concatenate([demo_start[None], np.concatenate(
                    [positions, np.repeat(demo_start[None, pos_dim:], cfg.starts, axis=0)],
                    axis=1)])
                goals = learner.demo_goals(task)
                goals = None if goals is None else np.repeat(goals[demo][None], len(starts), 0)
                times = horizon_times(task.times, cfg.horizon)
                with np.errstate(all="ignore"):
                    preds = learner.predict(order.index(name), starts, times, goals)
                ends = end_deltas(preds, task.goal, pos_dim, scale)
                settle = settle_times(preds, task.goal, times,
                                      float(task.times[-1] - task.times[0]), pos_dim, scale)
                cache_path = out / "cache" / label / f"{name}.json"
                key = _cache_key(run_dir, name, demo, cfg)
                cached = _load_cache(cache_path, key)
                env = get_env(env_id_for(dataset, name)) if cfg.execute else None
                for k in range(len(starts)):
                    index = REFERENCE if k == 0 else k - 1
                    rec = cached.get(index)
                    if rec is None or not np.allclose(rec.start, starts[k], atol=1e-12) or (
                            cfg.execute and rec.success is None):
                        rec = StartRecord(
                            method=label, task=name, demo=demo, start_index=index,
                            start_delta_m=float(np.linalg.norm(
                                starts[k, :pos_dim] - demo_start[:pos_dim]) * scale),
                            end_delta_m=float(ends[k]), large=bool(ends[k] > LARGE_M),
                            settle_time=float(settle[k]),
                            start=[float(v) for v in starts[k]])
                        if cfg.execute:
                            for attr, value in execute(env, demo, demo_start, preds[k],
                                                       cfg.approach_speed).items():
                                setattr(rec, attr, value)
                        cached[index] = rec
                        _save_cache(cache_path, key, cached)
                    else:  # a cached record: its settle time from this prediction
                        rec.settle_time = float(settle[k])
                    records.append(rec)
                    bar.update(1)
    finally:
        bar.close()
    return records
