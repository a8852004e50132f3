"""The writing envs' scene constants and specs: `tasks/writing.toml` (`load_writing_spec`) and
the per-task success tolerances `tasks/writing_tolerances.toml` (`load_tolerances`, derived by
`clfd_bench.envs.writing.derive`)."""

from __future__ import annotations

import dataclasses
import functools
import sys
from typing import Any

import numpy as np

from clfd_bench.envs.base import CONTROL_HZ
from clfd_bench.resources import resource_path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

WRITING_SPEC_FILE = "writing.toml"
#: Physics step of the writing envs: 4 substeps per 60 Hz control period (4.2 ms). The pen's
#: contact tracks as at 2.8 ms (6 substeps; ink within 0.03 mm, same pen-down steps, same
#: tracking error, on demos and 1.5x faster replays) and the envs run ~20 % faster.
PHYSICS_DT = 1.0 / 60.0 / 4
#: HelloWorld text: a step with lift below this is "pen commanded down".
PEN_DOWN_LIFT = 0.05
#: Steps the pen holds its last point after the trajectory, part of the default horizon.
SETTLE_STEPS = 60
#: Cameras (`framing_camera`): elevation in degrees, low enough that the hand (16 cm above the
#: pen tip) shows mostly above the shape on the image rather than over it.
CAMERA_ELEVATION = -30.0
#: Shape envs check new ink against the target's tolerance tube in batches of this many inked
#: steps (`ShapeEnv.decided_failure`): a failure is known at most this many steps late, for
#: about the cost of one query per batch.
DECIDE_BATCH = 8
#: Relative margin of the early Hausdorff decision: a point counts as outside only beyond
#: tolerance × (1 + this), so a float difference from the final check can never flip a success.
DECIDE_MARGIN = 1e-9
#: Keys of `tasks/writing.toml` [tolerances] (the derivation procedure's constants).
TOLERANCE_KEYS = ("hausdorff_factor", "hausdorff_floor", "coverage_fraction", "coverage_factor",
                  "coverage_floor", "dwell_factor", "dwell_cap", "dwell_radius",
                  "goal_size_fraction", "goal_floor")


@dataclasses.dataclass(frozen=True)
class WritingSpec:
    """The contents of `tasks/writing.toml` (see the comments there)."""

    xml: str
    surface_height: float
    x_range: tuple[float, float]
    y_range: tuple[float, float]
    hand_quat: tuple[float, float, float, float]
    press_depth: float
    ink_height: float
    lift_height: float
    min_ink_fraction: float
    dtw_threshold: str
    lasa_center: tuple[float, float]
    text_default: str
    text_scale: float
    text_reference: tuple[float, float]
    text_first_slot: tuple[float, float]
    text_advance: tuple[float, float]
    text_lift_steps: int
    text_travel_steps: int
    text_stray_ink: float
    tolerances_file: str
    tolerance_procedure: dict[str, float]

    @property
    def low(self) -> np.ndarray:
        return np.array([self.x_range[0], self.y_range[0]])

    @property
    def high(self) -> np.ndarray:
        return np.array([self.x_range[1], self.y_range[1]])


@functools.lru_cache(maxsize=1)
def load_writing_spec() -> WritingSpec:
    """Reads `tasks/writing.toml`."""
    path = resource_path("tasks", WRITING_SPEC_FILE)
    with open(path, "rb") as fh:
        doc = tomllib.load(fh)
    try:
        s, p, ok, la, tx, tol = (doc["surface"], doc["pen"], doc["success"], doc["lasa"],
                                 doc["text"], doc["tolerances"])
        spec = WritingSpec(
            xml=s["xml"], surface_height=float(s["height"]), x_range=tuple(s["x_range"]),
            y_range=tuple(s["y_range"]), hand_quat=tuple(p["hand_quat"]),
            press_depth=float(p["press_depth"]), ink_height=float(p["ink_height"]),
            lift_height=float(p["lift_height"]), min_ink_fraction=float(ok["min_ink_fraction"]),
            dtw_threshold=ok["dtw_threshold"],
            lasa_center=tuple(la["center"]), text_default=tx["default"],
            text_scale=float(tx["scale"]), text_reference=tuple(tx["reference"]),
            text_first_slot=tuple(tx["first_slot"]), text_advance=tuple(tx["advance"]),
            text_lift_steps=int(tx["lift_steps"]), text_travel_steps=int(tx["travel_steps"]),
            text_stray_ink=float(tx["stray_ink"]), tolerances_file=tol["file"],
            tolerance_procedure={k: float(tol[k]) for k in TOLERANCE_KEYS})
    except KeyError as exc:
        raise ValueError(f"{path}: missing key {exc}; see the keys documented in the file") from exc
    if spec.dtw_threshold != "paper":
        raise ValueError(f"{path}: success.dtw_threshold must be 'paper', got "
                         f"{spec.dtw_threshold!r}")
    return spec


@dataclasses.dataclass(frozen=True)
class ShapeTolerances:
    """One task's success tolerances (`tasks/writing_tolerances.toml`, data units of the task;
    derived by `clfd_bench.envs.writing.derive`).

    Attributes:
        hausdorff: largest two-sided deviation of the ink from the target (symmetric Hausdorff).
        coverage_radius: the ink must pass within this of the target ...
        min_coverage: ... along at least this fraction of the target's arc length.
        max_dwell: largest fraction of the episode's steps the pen may spend within
            `dwell_radius` of its last position.
        goal_tolerance: the last ink point must lie within this of the task's end point.
        dwell_radius: radius of the dwell check (a pen within it of its last position rests).
    """

    hausdorff: float
    coverage_radius: float
    min_coverage: float
    max_dwell: float
    goal_tolerance: float
    dwell_radius: float


@functools.lru_cache(maxsize=4)
def _tolerance_table(path: str) -> dict[str, Any]:
    with open(path, "rb") as fh:
        return tomllib.load(fh)


def load_tolerances(dataset: str, task: str) -> ShapeTolerances:
    """The tolerances of `task` of `dataset` ("helloworld" or "lasa") from the generated table.

    Raises:
        ValueError: the table lacks the task (regenerate it with `python eval/make_task_specs.py`).
    """
    path = resource_path("tasks", load_writing_spec().tolerances_file)
    try:
        row = _tolerance_table(str(path))[dataset][task]
        return ShapeTolerances(**{f.name: float(row[f.name])
                                  for f in dataclasses.fields(ShapeTolerances)})
    except (FileNotFoundError, KeyError) as exc:
        raise ValueError(f"{path}: no tolerances for {dataset}/{task} ({exc!r}); regenerate the "
                         "table with `python eval/make_task_specs.py`") from exc


def writing_settle_s() -> float:
    """Seconds of settling the writing envs' default horizon includes."""
    return SETTLE_STEPS / CONTROL_HZ
