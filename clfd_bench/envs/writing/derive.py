"""Derives the writing envs' per-task success tolerances from the demonstrations.

A letter or a LASA shape is judged by its ink (see `clfd_bench.envs.writing`): the ink must
lie close to the target demo everywhere (symmetric Hausdorff distance), cover most of it (arc
length within a radius), and the pen must not spend more of the episode resting at its end
point than the demos do. How close, how much and how long follows from how much the task's own
demonstrations differ from one another, by the procedure below; the constants it uses (factors,
floors, quantiles) are in `tasks/writing.toml` [tolerances] with their reasons, and
`python eval/make_task_specs.py` writes the results to `tasks/writing_tolerances.toml`.

For a task with demos D_1..D_N ([T, 2] each, data units; the board is `sim_scale` m per unit):

- `hausdorff` = max(hausdorff_floor / sim_scale, hausdorff_factor × max over the pairs
  i < j of H(D_i, D_j)), H the symmetric Hausdorff distance: the ink may deviate from the
  target as far as another demonstration of the task does, and never less than the floor
  (what the must-succeed variants need: a 1 cm start offset, 3 mm of noise, tracking). The
  same spread decides which variants of a shape family are wrong at all
  (`clfd_bench.execution.replay.is_distinct`), so the two rules agree: a trajectory within the
  demos' spread is the task's shape, one beyond it is not.
- `coverage_radius` = max(coverage_floor / sim_scale, coverage_factor × max over the
  ordered pairs i != j of r_q(D_j | D_i)), where r_q(D_j | D_i) is the smallest radius within
  which D_i passes along a fraction `coverage_fraction` (q) of D_j's arc length; and
  `min_coverage` = q: the ink must pass within that radius along q of the target, as every
  other demo does.
- `goal_tolerance` = max(goal_floor / sim_scale, min(goal_size_fraction × demo_size,
  coverage_radius)), where demo_size is the median over the demos of their bounding-box
  diagonal: the last ink point must lie within it of the task's end point. All demos of a
  task end at the same point (spread 0 there), so the bound is sized by what an observer
  compares an end gap with, the letter: a stroke stopping short of (or running past) the end
  by a tenth of the letter's size still finishes the letter, while a letter cut short or
  drifting away (`drift`: 15 % of the size, >= 2 cm) ends outside (1.1x the bound at the
  least). It is never more than the coverage radius (an end farther from the target's end
  than the demonstrators' strokes lie from one another is another stroke), and never less
  than the floor (1 cm on the board: 3 mm of noise and tracking error must pass).
- `max_dwell` = min(dwell_cap, dwell_factor × max over k of dwell(D_k)), where dwell(D_k) is
  the fraction of the samples of D_k, followed by the 1 s (60 samples) the pen holds its last
  point in a default rollout, that lie within `dwell_radius` (1 cm on the board) of the last
  point: the pen may rest at its end point for longer than any demo did, by the factor, but
  not for most of the episode. `dwell_radius` says "at rest", not "at the goal", so it is
  its own constant, not the end bound (`tasks/writing.toml` [tolerances]).
"""

from __future__ import annotations

import pathlib

import numpy as np

from clfd_bench.envs.writing.spec import TOLERANCE_KEYS
from clfd_bench.metrics.trajectory import hausdorff, nearest_distances

__all__ = [
    "PROCEDURE_KEYS",
    "covering_radius",
    "demo_dwell",
    "derive_task_tolerances",
    "derive_tolerances",
    "demo_size",
    "dumps_tolerances",
    "tolerances_path",
]

#: The keys of `tasks/writing.toml` [tolerances] the procedure reads.
PROCEDURE_KEYS = TOLERANCE_KEYS
#: The datasets whose tasks the writing envs execute.
DATASETS = ("helloworld", "lasa")


def tolerances_path() -> pathlib.Path:
    """Path of the generated table, `tasks/<[tolerances] file>`."""
    from clfd_bench.envs.writing.spec import load_writing_spec
    from clfd_bench.resources import resource_path

    return resource_path("tasks", load_writing_spec().tolerances_file)


def covering_radius(ref: np.ndarray, pred: np.ndarray, fraction: float) -> float:
    """Smallest radius r such that `pred` passes within r along `fraction` of `ref`'s arc
    length (the inverse of `clfd_bench.metrics.trajectory.coverage(ref, pred, r)`).

    Args:
        ref: [T, 2] the trajectory to cover.
        pred: [T2, 2] the covering trajectory.
        fraction: in (0, 1].

    Returns:
        The radius, in the arrays' unit.
    """
    _, d = nearest_distances(pred, ref)
    seg_d = np.maximum(d[1:], d[:-1])  # a segment is covered when both its ends are
    seg_len = np.linalg.norm(np.diff(ref, axis=0), axis=1)
    order = np.argsort(seg_d, kind="stable")
    cum = np.cumsum(seg_len[order])
    k = int(np.searchsorted(cum, fraction * cum[-1] * (1 - 1e-12)))
    return float(seg_d[order[min(k, len(order) - 1)]])


def demo_dwell(demo: np.ndarray, radius: float, hold_steps: int) -> float:
    """Fraction of the samples of `demo` [T, 2] followed by `hold_steps` copies of its last
    point that lie within `radius` of the last point (how long a default rollout of the demo
    rests at its end)."""
    d = np.linalg.norm(demo - demo[-1], axis=1)
    return float((np.count_nonzero(d <= radius) + hold_steps) / (len(demo) + hold_steps))


def demo_size(demos: np.ndarray) -> float:
    """The size of a task: the median over its demos [N, T, 2] of their bounding-box diagonal
    (data units)."""
    demos = np.asarray(demos, dtype=float)
    return float(np.median(np.linalg.norm(demos.max(axis=1) - demos.min(axis=1), axis=-1)))


def derive_task_tolerances(demos: np.ndarray, sim_scale: float, procedure: dict[str, float],
                           hold_steps: int) -> dict[str, float]:
    """The tolerances of one task (see the module docstring).

    Args:
        demos: [N, T, 2] the task's demos, data units.
        sim_scale: metres on the board per data unit.
        procedure: `tasks/writing.toml` [tolerances] (the `PROCEDURE_KEYS`; floors and
            `dwell_radius` in metres on the board).
        hold_steps: samples the pen holds its last point after a default rollout.

    Returns:
        {hausdorff, coverage_radius, min_coverage, max_dwell, goal_tolerance, dwell_radius}
        (lengths in data units) and the statistics they come from (demo_hausdorff_max,
        demo_covering_radius_max, demo_dwell_max, demo_size) or describe the spread
        (demo_hausdorff_median).
    """
    demos = np.asarray(demos, dtype=float)
    n = len(demos)
    if demos.ndim != 3 or demos.shape[-1] != 2 or n < 2:
        raise ValueError(f"need >= 2 demos [N, T, 2], got {demos.shape}")
    p = procedure
    pairs_h = [hausdorff(demos[i], demos[j]) for i in range(n) for j in range(i + 1, n)]
    q = float(p["coverage_fraction"])
    radii = [covering_radius(demos[j], demos[i], q) for i in range(n) for j in range(n) if i != j]
    dwell_radius = p["dwell_radius"] / sim_scale
    dwell = [demo_dwell(d, dwell_radius, hold_steps) for d in demos]
    h_max, r_max, size = float(max(pairs_h)), float(max(radii)), demo_size(demos)
    cover = max(p["coverage_floor"] / sim_scale, p["coverage_factor"] * r_max)
    return {
        "hausdorff": max(p["hausdorff_floor"] / sim_scale, p["hausdorff_factor"] * h_max),
        "coverage_radius": cover,
        "min_coverage": q,
        "max_dwell": min(p["dwell_cap"], p["dwell_factor"] * max(dwell)),
        "goal_tolerance": max(p["goal_floor"] / sim_scale,
                              min(p["goal_size_fraction"] * size, cover)),
        "dwell_radius": dwell_radius,
        "demo_hausdorff_max": h_max,
        "demo_hausdorff_median": float(np.median(pairs_h)),
        "demo_covering_radius_max": r_max,
        "demo_dwell_max": float(max(dwell)),
        "demo_size": size,
    }


def derive_tolerances(datasets: tuple[str, ...] = DATASETS) -> dict[str, dict[str, dict]]:
    """Every writing task's tolerances: {dataset: {task: derive_task_tolerances(...)}}."""
    from clfd_bench.data import load_dataset
    from clfd_bench.envs.writing.spec import SETTLE_STEPS, load_writing_spec

    spec = load_writing_spec()
    out: dict[str, dict[str, dict]] = {}
    for name in datasets:
        ds = load_dataset(name)
        out[name] = {t.name: derive_task_tolerances(np.asarray(t.demos), float(t.sim_scale),
                                                    spec.tolerance_procedure, SETTLE_STEPS)
                     for t in ds.tasks}
    return out


_HEADER = """\
Writing envs: per-task success tolerances. GENERATED by `python eval/make_task_specs.py`
(clfd_bench.envs.writing.derive) from the demonstrations; do not edit by hand: change the
procedure constants in tasks/writing.toml [tolerances] (or the code) and regenerate.

Lengths are in the task's data units: HelloWorld metres (on the board, and letter units for
clfd/HelloWorld-v3), LASA units (0.003 m on the board each).
- hausdorff = max(hausdorff_floor / sim_scale, hausdorff_factor * demo_hausdorff_max):
  the largest two-sided deviation of the ink from the target demo; demo_hausdorff_max /
  _median = max / median over the task's demo pairs of their Hausdorff distance.
- coverage_radius = max(coverage_floor / sim_scale, coverage_factor *
  demo_covering_radius_max), min_coverage = coverage_fraction: the ink must pass within
  coverage_radius along min_coverage of the target's arc length; demo_covering_radius_max
  = max over ordered demo pairs of the radius within which one demo covers that fraction
  of the other.
- goal_tolerance = max(goal_floor / sim_scale, min(goal_size_fraction * demo_size,
  coverage_radius)): the last ink point must lie within it of the task's end point;
  demo_size = the median over the demos of their bounding-box diagonal.
- max_dwell = min(dwell_cap, dwell_factor * demo_dwell_max): the largest fraction of the
  episode's steps the pen may spend within dwell_radius (= dwell_radius of the procedure /
  sim_scale) of its last point; demo_dwell_max = the largest such fraction over the demos
  (each followed by 1 s of holding).
Procedure constants (tasks/writing.toml [tolerances]):
{procedure}
"""


def _fmt(x: float) -> str:
    """Six significant digits (the table is compared with the derivation at rtol 1e-5)."""
    s = f"{x:.6g}"
    return s if any(c in s for c in ".en") else s + ".0"


def dumps_tolerances(doc: dict[str, dict[str, dict]], procedure: dict[str, float]) -> str:
    """The TOML text of the table (a comment header with the procedure, one table per task:
    [<dataset>.<task>])."""
    header = _HEADER.format(procedure="\n".join(f"  {k} = {procedure[k]}"
                                                for k in PROCEDURE_KEYS))
    lines = ["# " + ln if ln else "#" for ln in header.rstrip("\n").split("\n")]
    for ds, tasks in doc.items():
        for task, vals in tasks.items():
            lines += ["", f'[{ds}."{task}"]']
            lines += [f"{k} = {_fmt(float(v))}" for k, v in vals.items()]
    return "\n".join(lines) + "\n"
