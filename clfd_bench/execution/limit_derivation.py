"""What the measurement behind `clfd_bench.sim.limits` derives (steps 3 and 4 of the procedure
in `clfd_bench.execution.limit_calibration`, which measures): the record of one measured rollout
(`RolloutMeasurement`), a measurement's records (`Calibration`, saved and read back as JSON by
`to_json` / `from_json`), the bounds they derive (`Calibration.derive()`: `Derived`, each worst
value an `Extreme`, the cutoffs by `choose_cutoff`), and those next to the constants of
`sim.limits` (`compare`, `differences`, relative tolerance `RTOL`).

Peaks are [3, 9] arrays as `MotionMonitor.peaks`: rows velocity, acceleration, jerk; columns
translation, rotation, joints 1..7. Ratios are peaks divided by the published limits.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from clfd_bench.io import json_safe
from clfd_bench.sim import limits as L
from clfd_bench.sim.limits import MotionLimits, MotionMonitor
from clfd_bench.sim.robot import ARM_JOINTS

__all__ = ["RTOL", "Calibration", "Comparison", "Derived", "Extreme", "RolloutMeasurement",
           "choose_cutoff", "compare", "differences"]

#: Relative tolerance of `compare` (measured vs the constants of `sim.limits`).
RTOL = 0.02
_ROWS = ("velocity", "acceleration", "jerk")


# --------------------------------------------------------------------------- one rollout
@dataclasses.dataclass
class RolloutMeasurement:
    """What one rollout measured (all over the trajectory and the settling).

    Attributes:
        env_id, demo, family: which replay.
        success, failure_reason: the env's decision (no limit can fail; a blow-up or the task
            can).
        steps: env steps run; trajectory_steps: of them the trajectory's.
        tracking_position, tracking_rotation: largest hand pose error after a step (m, rad);
        tracking_position_step, tracking_rotation_step: at which step (>= trajectory_steps:
            while settling).
        collision_force: largest normal force (N) of a (robot body, other geom) pair, 0 when the
            robot touched nothing; collision_detail ("link6 hit shelf_board") and
            collision_step.
        raw_peaks: [3, 9] peaks of the raw command (rows velocity, acceleration, jerk; columns
            translation, rotation, joints 1..7).
        rotation_peaks: [R, 3] rotation velocity, acceleration, jerk filtered at each cutoff of
            the rotation grid; joint_peaks: [J, 3, 7] likewise per joint for the joint grid.
        peak_reach: m, largest distance of a commanded position from the shoulder.
        lowest_height, floor_height: m, lowest commanded z and the scene's floor.
        wall_s: seconds of wall time.
    """

    env_id: str
    demo: int
    family: str
    success: bool
    failure_reason: str | None
    steps: int
    trajectory_steps: int
    tracking_position: float
    tracking_position_step: int
    tracking_rotation: float
    tracking_rotation_step: int
    collision_force: float
    collision_detail: str
    collision_step: int | None
    raw_peaks: np.ndarray
    rotation_peaks: np.ndarray
    joint_peaks: np.ndarray
    peak_reach: float
    lowest_height: float
    floor_height: float
    wall_s: float

    def to_json(self) -> dict[str, Any]:
        return json_safe(dataclasses.asdict(self))

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RolloutMeasurement:
        d = dict(d)
        for k in ("raw_peaks", "rotation_peaks", "joint_peaks"):
            d[k] = np.asarray(d[k], dtype=float)
        for k in ("lowest_height", "floor_height"):
            d[k] = -math.inf if d[k] is None else float(d[k])
        return cls(**d)


# --------------------------------------------------------------------------- the procedure
def choose_cutoff(grid: Sequence[float], worst_ratio: Sequence[float],
                  margin: float = L.FILTER_MARGIN) -> float | None:
    """The highest cutoff of `grid` whose worst peak ratio (peak / limit, `worst_ratio[i]` for
    `grid[i]`) stays under 1 / `margin`; None when none does."""
    ok = [float(f) for f, r in zip(grid, worst_ratio, strict=True) if r < 1.0 / margin]
    return max(ok) if ok else None


def _bounds(limits: MotionLimits) -> np.ndarray:
    """[3, 9] the limits as `MotionMonitor.bounds`."""
    return MotionMonitor(limits, 1.0, np.zeros(3)).bounds


@dataclasses.dataclass(frozen=True)
class Extreme:
    """The worst value of a quantity over the replays, and where.

    Attributes:
        value: in the quantity's unit; ratio: value / its limit (NaN when it has none).
        env_id, demo, family, step: the replay and the step (None: not recorded).
        quantity: e.g. "rotation acceleration", "joint2 acceleration", "link6 hit shelf".
    """

    value: float
    env_id: str = ""
    demo: int = -1
    family: str = ""
    quantity: str = ""
    ratio: float = math.nan
    step: int | None = None

    @property
    def where(self) -> str:
        """e.g. "Pouring-v3 demo 7 faster" ("-" when no replay)."""
        if not self.env_id:
            return "-"
        return f"{self.env_id.removeprefix('clfd/')} demo {self.demo} {self.family}"


@dataclasses.dataclass
class Derived:
    """The bounds as the procedure derives them from a `Calibration`.

    Attributes:
        n_rollouts, n_successes, failures: the rollouts, how many succeeded, the failures'
            "env demo family: reason".
        tracking_position_measured, tracking_rotation_measured: worst errors (m, rad).
        tracking_position, tracking_rotation: max(floor, TRACKING_FACTOR × worst).
        tracking_by_family: {family: (worst position Extreme, worst rotation Extreme)}
            (their `quantity` says whether the worst step was in the trajectory or settling).
        collision_force_measured: largest robot-scene pair force (N).
        translation_raw: [3] worst raw translation velocity, acceleration, jerk (ratio to the
            limits); translation_raw_passes: all under 1 / margin (so it stays unfiltered).
        rotation_raw, joint_raw: [3] worst raw rotation / joint (any joint) peaks per row.
        rotation_grid, joint_grid: the cutoffs tried; rotation_worst, joint_worst: the worst
            filtered peak (largest ratio over velocity, acceleration, jerk, and the joints) per
            cutoff; rotation_filter_hz, joint_filter_hz: `choose_cutoff` (None: none passes).
        peak_reach: largest distance of a command from the shoulder (m);
        floor_clearance: smallest height of a command above the scene's floor (m).
    """

    n_rollouts: int
    n_successes: int
    failures: list[str]
    tracking_position_measured: Extreme
    tracking_rotation_measured: Extreme
    tracking_position: float
    tracking_rotation: float
    tracking_by_family: dict[str, tuple[Extreme, Extreme]]
    collision_force_measured: Extreme
    translation_raw: list[Extreme]
    translation_raw_passes: bool
    rotation_raw: list[Extreme]
    joint_raw: list[Extreme]
    rotation_grid: tuple[float, ...]
    joint_grid: tuple[float, ...]
    rotation_worst: list[Extreme]
    joint_worst: list[Extreme]
    rotation_filter_hz: float | None
    joint_filter_hz: float | None
    peak_reach: Extreme
    floor_clearance: Extreme


@dataclasses.dataclass
class Calibration:
    """The measurements of many rollouts (`measure`), and what they derive.

    Attributes:
        records: one `RolloutMeasurement` per rollout.
        rotation_grid, joint_grid: the cutoffs of the records' `rotation_peaks` / `joint_peaks`.
        reference: the limits the peaks are judged against (the published ones; not saved
            by `to_json`).
        margin: the filter margin (`sim.limits.FILTER_MARGIN`).
        wall_s: seconds the measurement took.
    """

    records: list[RolloutMeasurement]
    rotation_grid: tuple[float, ...] = L.ROTATION_FILTER_GRID
    joint_grid: tuple[float, ...] = L.JOINT_FILTER_GRID
    reference: MotionLimits = dataclasses.field(default_factory=MotionLimits)
    margin: float = L.FILTER_MARGIN
    wall_s: float = 0.0

    def _extreme(self, values: np.ndarray, quantities: Sequence[str] | None = None,
                 ratios: np.ndarray | None = None, steps: Sequence[int | None] | None = None,
                 by_ratio: bool = False) -> Extreme:
        """The record with the largest value (or ratio) of `values` [N] (one per record)."""
        if not self.records:
            return Extreme(math.nan)
        key = ratios if by_ratio else values
        i = int(np.argmax(key))
        r = self.records[i]
        return Extreme(float(values[i]), r.env_id, r.demo, r.family,
                       quantities[i] if quantities is not None else "",
                       float(ratios[i]) if ratios is not None else math.nan,
                       steps[i] if steps is not None else None)

    def _tracking(self, records: list[RolloutMeasurement]) -> tuple[Extreme, Extreme]:
        sub = Calibration(records, self.rotation_grid, self.joint_grid, self.reference,
                          self.margin)
        pos = np.array([r.tracking_position for r in records])
        rot = np.array([r.tracking_rotation for r in records])

        def when(r: RolloutMeasurement, step: int) -> str:
            return "settling" if step >= r.trajectory_steps else "trajectory"

        return (sub._extreme(pos, [f"position error ({when(r, r.tracking_position_step)})"
                                   for r in records], pos / L.TRACKING_POSITION,
                             [r.tracking_position_step for r in records]),
                sub._extreme(rot, [f"rotation error ({when(r, r.tracking_rotation_step)})"
                                   for r in records], rot / L.TRACKING_ROTATION,
                             [r.tracking_rotation_step for r in records]))

    def _peak_extreme(self, ratios: np.ndarray, values: np.ndarray, names: list[str]
                      ) -> Extreme:
        """ratios, values: [N, K] per record and quantity; the worst ratio's record."""
        flat = ratios.reshape(len(ratios), -1)
        k = np.argmax(flat, axis=1)
        idx = np.arange(len(flat))
        return self._extreme(values.reshape(len(values), -1)[idx, k],
                             [names[j] for j in k], flat[idx, k], by_ratio=True)

    def derive(self) -> Derived:
        """The bounds the procedure derives from the records (`Derived`)."""
        if not self.records:
            raise ValueError("no rollouts measured")
        recs = self.records
        b = _bounds(self.reference)  # [3, 9]
        raw = np.stack([r.raw_peaks for r in recs])  # [N, 3, 9]
        rot = np.stack([r.rotation_peaks for r in recs])  # [N, R, 3]
        joints = np.stack([r.joint_peaks for r in recs])  # [N, J, 3, 7]
        raw_ratio = raw / b
        joint_names = [f"{j} {w}" for w in _ROWS for j in ARM_JOINTS]  # [3 * 7], row major

        translation = [self._extreme(raw[:, i, 0], [f"cartesian {w}"] * len(recs),
                                     raw_ratio[:, i, 0]) for i, w in enumerate(_ROWS)]
        rotation_raw = [self._extreme(raw[:, i, 1], [f"rotation {w}"] * len(recs),
                                      raw_ratio[:, i, 1]) for i, w in enumerate(_ROWS)]
        joint_raw = [self._peak_extreme(raw_ratio[:, i, 2:], raw[:, i, 2:],
                                        [f"{j} {w}" for j in ARM_JOINTS])
                     for i, w in enumerate(_ROWS)]
        rot_ratio = rot / b[None, None, :, 1]  # [N, R, 3]
        rot_worst = [self._peak_extreme(rot_ratio[:, g], rot[:, g],
                                        [f"rotation {w}" for w in _ROWS])
                     for g in range(len(self.rotation_grid))]
        joint_ratio = joints / b[None, None, :, 2:]  # [N, J, 3, 7]
        joint_worst = [self._peak_extreme(joint_ratio[:, g], joints[:, g], joint_names)
                       for g in range(len(self.joint_grid))]

        pos, rot_err = self._tracking(recs)
        by_family = {f: self._tracking([r for r in recs if r.family == f])
                     for f in dict.fromkeys(r.family for r in recs)}
        force = np.array([r.collision_force for r in recs])
        collision = (self._extreme(force, [r.collision_detail for r in recs],
                                   force / L.COLLISION_FORCE, [r.collision_step for r in recs])
                     if force.max() > 0 else Extreme(0.0, quantity="no robot-scene contact",
                                                     ratio=0.0))
        reach = np.array([r.peak_reach for r in recs])
        clearance = np.array([r.lowest_height - r.floor_height for r in recs])
        return Derived(
            n_rollouts=len(recs), n_successes=sum(r.success for r in recs),
            failures=[f"{r.env_id} demo {r.demo} {r.family}: {r.failure_reason or 'task failed'}"
                      for r in recs if not r.success],
            tracking_position_measured=pos, tracking_rotation_measured=rot_err,
            tracking_position=max(L.TRACKING_FLOOR_POSITION, L.TRACKING_FACTOR * pos.value),
            tracking_rotation=max(L.TRACKING_FLOOR_ROTATION, L.TRACKING_FACTOR * rot_err.value),
            tracking_by_family=by_family, collision_force_measured=collision,
            translation_raw=translation,
            translation_raw_passes=all(e.ratio < 1.0 / self.margin for e in translation),
            rotation_raw=rotation_raw, joint_raw=joint_raw,
            rotation_grid=tuple(self.rotation_grid), joint_grid=tuple(self.joint_grid),
            rotation_worst=rot_worst, joint_worst=joint_worst,
            rotation_filter_hz=choose_cutoff(self.rotation_grid, [e.ratio for e in rot_worst],
                                             self.margin),
            joint_filter_hz=choose_cutoff(self.joint_grid, [e.ratio for e in joint_worst],
                                          self.margin),
            peak_reach=self._extreme(reach, ["reach"] * len(recs), reach / L.MAX_REACH),
            floor_clearance=dataclasses.replace(
                self._extreme(-clearance, ["height above the floor"] * len(recs)),
                value=float(np.min(clearance))))

    def to_json(self) -> dict[str, Any]:
        """Everything (records, grids, margin) as JSON data; `from_json` reads it back."""
        return json_safe({"rotation_grid": self.rotation_grid, "joint_grid": self.joint_grid,
                          "margin": self.margin, "wall_s": self.wall_s,
                          "records": [r.to_json() for r in self.records]})

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Calibration:
        """Reads `to_json()` (the reference limits: the published ones)."""
        return cls([RolloutMeasurement.from_json(r) for r in d["records"]],
                   tuple(d["rotation_grid"]), tuple(d["joint_grid"]),
                   margin=float(d["margin"]), wall_s=float(d.get("wall_s", 0.0)))


# --------------------------------------------------------------------------- comparison
@dataclasses.dataclass(frozen=True)
class Comparison:
    """One derived value next to its constant in `sim.limits`.

    Attributes:
        name: the constant ("TRACKING_MEASURED_POSITION", ...).
        measured, constant: the derived and the stated value.
        ok: they agree (relative tolerance; cutoffs exactly).
        where: the replay of the worst value; note: what the value is.
    """

    name: str
    measured: Any
    constant: Any
    ok: bool
    where: str = ""
    note: str = ""


def _close(a: float, b: float, rtol: float) -> bool:
    return math.isclose(a, b, rel_tol=rtol, abs_tol=1e-9)


def compare(calibration: Calibration | Derived, rtol: float = RTOL) -> list[Comparison]:
    """Every derived value next to its constant in `clfd_bench.sim.limits`."""
    d = calibration.derive() if isinstance(calibration, Calibration) else calibration
    tp, tr, col = (d.tracking_position_measured, d.tracking_rotation_measured,
                   d.collision_force_measured)
    rot_at = dict(zip(d.rotation_grid, d.rotation_worst, strict=True))
    joint_at = dict(zip(d.joint_grid, d.joint_worst, strict=True))
    rot_e = rot_at.get(d.rotation_filter_hz)
    joint_e = joint_at.get(d.joint_filter_hz)
    worst_t = max(d.translation_raw, key=lambda e: e.ratio)
    return [
        Comparison("rollouts successful", d.n_successes, d.n_rollouts,
                   d.n_successes == d.n_rollouts, note="; ".join(d.failures[:5])),
        Comparison("TRACKING_MEASURED_POSITION", tp.value, L.TRACKING_MEASURED_POSITION,
                   _close(tp.value, L.TRACKING_MEASURED_POSITION, rtol), tp.where,
                   "m, worst hand position error"),
        Comparison("TRACKING_MEASURED_ROTATION", tr.value, L.TRACKING_MEASURED_ROTATION,
                   _close(tr.value, L.TRACKING_MEASURED_ROTATION, rtol), tr.where,
                   "rad, worst hand rotation error"),
        Comparison("TRACKING_POSITION", d.tracking_position, L.TRACKING_POSITION,
                   _close(d.tracking_position, L.TRACKING_POSITION, rtol),
                   note=f"max({L.TRACKING_FLOOR_POSITION}, {L.TRACKING_FACTOR} × worst)"),
        Comparison("TRACKING_ROTATION", d.tracking_rotation, L.TRACKING_ROTATION,
                   _close(d.tracking_rotation, L.TRACKING_ROTATION, rtol),
                   note=f"max({L.TRACKING_FLOOR_ROTATION}, {L.TRACKING_FACTOR} × worst)"),
        Comparison("COLLISION_MEASURED_FORCE", col.value, L.COLLISION_MEASURED_FORCE,
                   _close(col.value, L.COLLISION_MEASURED_FORCE, rtol),
                   col.where if col.value > 0 else "",
                   f"N, {col.quantity}" if col.value > 0 else "N, robot touched nothing"),
        Comparison("TRANSLATION_FILTER_HZ", None if d.translation_raw_passes else "raw fails",
                   L.TRANSLATION_FILTER_HZ,
                   d.translation_raw_passes == (L.TRANSLATION_FILTER_HZ is None),
                   worst_t.where, f"raw {worst_t.quantity} {worst_t.ratio:.2f} × limit"),
        Comparison("ROTATION_FILTER_HZ", d.rotation_filter_hz, L.ROTATION_FILTER_HZ,
                   d.rotation_filter_hz == L.ROTATION_FILTER_HZ,
                   rot_e.where if rot_e else "",
                   f"{rot_e.quantity} {rot_e.ratio:.2f} × limit" if rot_e else "none passes"),
        Comparison("JOINT_FILTER_HZ", d.joint_filter_hz, L.JOINT_FILTER_HZ,
                   d.joint_filter_hz == L.JOINT_FILTER_HZ,
                   joint_e.where if joint_e else "",
                   f"{joint_e.quantity} {joint_e.ratio:.2f} × limit" if joint_e
                   else "none passes"),
    ]


def differences(calibration: Calibration | Derived, rtol: float = RTOL) -> list[Comparison]:
    """The `compare` rows whose derived value disagrees with the constant (empty: the
    measurement reproduces `sim.limits`)."""
    return [c for c in compare(calibration, rtol) if not c.ok]
