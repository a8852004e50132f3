"""The one-shape writing envs: a HelloWorld letter (`HelloWorldLetterEnv`) or a LASA shape
(`LasaShapeEnv`), on `ShapeEnv`."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from gymnasium import spaces

from clfd_bench.data import load_task
from clfd_bench.envs.checks import Check, checks_json, failed_checks
from clfd_bench.envs.writing.board import WritingBase
from clfd_bench.envs.writing.judge import judge_shape
from clfd_bench.envs.writing.spec import (
    DECIDE_BATCH,
    DECIDE_MARGIN,
    _tolerance_table,
    load_tolerances,
    load_writing_spec,
)
from clfd_bench.resources import resource_path


class ShapeEnv(WritingBase):
    """One 2-D shape (a HelloWorld letter or a LASA shape): action = pen point on the board."""

    def __init__(self, name: str, render_mode: str | None = None, **kwargs: Any):
        self.task_name = name
        task = load_task(self.dataset, name)
        demos, self.sim_scale = np.asarray(task.demos, dtype=float), float(task.sim_scale)
        self.goal = np.asarray(task.goal, dtype=float)
        if demos.ndim != 3 or demos.shape[-1] != 2:
            raise ValueError(f"{self.dataset}/{name}: expected 2-D demos [N, T, 2], got "
                             f"{demos.shape}")
        self.demos = demos
        self.offset = self._offset(demos)
        self.tolerances = load_tolerances(self.dataset, name)
        self._trees: dict[int, Any] = {}  # demo -> k-d tree of its target (data units)
        self._pending: list[tuple[int, np.ndarray]] = []  # (step, surface xy) ink not checked
        self._off_board = 0
        self._early: dict[str, Any] | None = None
        super().__init__(render_mode, **kwargs)
        from clfd_bench.metrics.thresholds import threshold

        self.dtw_threshold = threshold(self.dataset, "dtw", self.data_units)

    data_units = "m"

    def _offset(self, demos: np.ndarray) -> np.ndarray:
        return np.zeros(2)

    @property
    def num_demos(self) -> int:
        return int(self.demos.shape[0])

    def to_surface(self, points: np.ndarray) -> np.ndarray:
        """Data units [..., 2] -> surface point [..., 2] (m, base frame)."""
        return np.asarray(points, dtype=float) * self.sim_scale + self.offset

    def to_data(self, xy: np.ndarray) -> np.ndarray:
        """Surface point [..., 2] (m) -> data units [..., 2]."""
        return (np.asarray(xy, dtype=float) - self.offset) / self.sim_scale

    def _start_point(self, demo: int) -> np.ndarray:
        return self.to_surface(self.demos[demo, 0])

    def _trajectory_steps(self, demo: int) -> int:
        return int(self.demos.shape[1])

    def _action_space(self) -> spaces.Box:
        return spaces.Box(self.wspec.low, self.wspec.high, dtype=np.float64)

    def _action_to_target(self, action: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, float | None]:
        xy = np.minimum(np.maximum(action, self._low), self._high)
        return self.hand_target(xy), self._hand_quat, None

    def trajectory_to_actions(self, trajectory: np.ndarray) -> np.ndarray:
        """Trajectory [T, 2] in data units -> actions [T, 2] (surface points, m)."""
        traj = np.asarray(trajectory, dtype=float)
        if traj.ndim != 2 or traj.shape[1] != 2:
            raise ValueError(f"{type(self).__name__} expects a 2-D trajectory [T, 2] in "
                             f"{self.dataset} units, got shape {traj.shape}")
        return self.to_surface(traj)

    def target(self) -> np.ndarray:
        """The current episode's target: demo `self.demo` [T, 2], data units."""
        return self.demos[self.demo]

    def demo_trajectory(self, demo: int) -> np.ndarray:
        return self.demos[demo]

    def _framed_points(self) -> np.ndarray:
        return self.to_surface(self.demos.reshape(-1, 2))

    # -- failures decided before the end (`decided_failure`)
    def _reset_task(self, demo: int) -> None:
        super()._reset_task(demo)
        self._pending, self._off_board, self._early = [], 0, None

    def _after_step(self) -> None:
        super()._after_step()
        if self._early is not None:
            return
        step = len(self._ink_flags) - 1
        if self._ink_flags[-1]:
            # checked in batches, when someone asks (`decided_failure`, the final decision)
            self._pending.append((step, self._ink_xy[-1]))
            return
        # At the horizon the ink fraction is inked / horizon <= (horizon - off) / horizon.
        self._off_board += 1
        h, least = self.horizon, self.wspec.min_ink_fraction
        if (h - self._off_board) / h < least:
            self._check_pending()  # a batch that completed earlier decides first
            if self._early is not None:
                return
            self._early = {
                "check": "ink_fraction", "step": step, "value": (h - self._off_board) / h,
                "bound": least,
                "reason": f"the pen was off the board for {self._off_board} of the episode's "
                          f"{h} steps by step {step}: the ink fraction stays below {least:g}"}

    def _check_pending(self) -> None:
        """Checks the pending ink points of every complete batch of `DECIDE_BATCH` inked steps
        against the target: the criterion's Hausdorff distance is at least the distance of any
        ink point to the target, so one point beyond the tolerance decides the failure. The
        batches are checked together (one k-d tree query) but decide as if each had been
        checked at the step that completed it: the first point beyond the tolerance, in step
        order, is the decision; a later point or batch never overrides it."""
        from scipy.spatial import cKDTree

        done = len(self._pending) - len(self._pending) % DECIDE_BATCH
        if self._early is not None or not done:
            return
        batch, self._pending = self._pending[:done], self._pending[done:]
        steps = [k for k, _ in batch]
        points = self.to_data(np.array([xy for _, xy in batch]))
        tree = self._trees.get(self.demo)
        if tree is None:
            tree = self._trees[self.demo] = cKDTree(self.target())
        dist = np.asarray(tree.query(points, k=1)[0], dtype=float)
        bound = self.tolerances.hausdorff
        out = np.flatnonzero(dist > bound * (1.0 + DECIDE_MARGIN))
        if out.size:
            k = int(out[0])
            self._early = {
                "check": "hausdorff", "step": steps[k], "value": float(dist[k]),
                "bound": bound,
                "reason": f"ink at step {steps[k]} lies {dist[k]:.4g} {self.data_units} from the "
                          f"target, beyond the shape's Hausdorff tolerance {bound:.4g}"}

    def decided_failure(self) -> dict[str, Any] | None:
        """The ink already breaks a check no later ink can mend, or None: a point farther than
        `tolerances.hausdorff` from the target (the symmetric Hausdorff distance can only grow
        as ink is added; checked in batches of `DECIDE_BATCH` inked steps), or so many steps
        with the pen off the board that the ink fraction at the horizon stays below
        `min_ink_fraction`. See `PandaEnv.decided_failure`."""
        self._check_pending()
        return None if self._early is None else dict(self._early)

    def _task_state(self) -> dict[str, Any]:
        state = super()._task_state()
        state.update(pending=list(self._pending), off_board=self._off_board,
                     early=None if self._early is None else dict(self._early))
        return state

    def _restore_task_state(self, state: dict[str, Any]) -> None:
        super()._restore_task_state(state)
        self._pending, self._off_board = list(state["pending"]), int(state["off_board"])
        self._early = state["early"]

    def _decide(self) -> dict[str, Any]:
        self._check_pending()  # as if each batch had been checked when it completed
        frac = self._ink_fraction()
        out = judge_shape(self.to_data(self.ink_trace()), self.to_data(self.pen_path()),
                          self.target(), self.goal, self.tolerances, self.dtw_threshold,
                          self.sim_scale)
        least = self.wspec.min_ink_fraction
        checks = [Check("ink_fraction", frac, least, ">=", "",
                        "fraction of the episode's steps with the pen on the board"),
                  *out.pop("checks")]
        if self._early is not None:  # decided before the end (only a partial episode lacks it)
            e = self._early
            scale = self.sim_scale if e["check"] == "hausdorff" else 1.0
            decided = Check(e["check"], e["value"] * scale, e["bound"] * scale,
                            "<=" if e["check"] == "hausdorff" else ">=",
                            "m" if e["check"] == "hausdorff" else "",
                            f"decided at step {e['step']}: {e['reason']}")
            at = [c.name for c in checks].index(decided.name)
            if checks[at].passed:  # the partial episode's own measure does not show it yet
                checks[at] = decided
            out["decided_failure"] = dict(e)
        out.update(ink_fraction=frac, checks=checks_json(checks),
                   failed=failed_checks(checks), is_success=not failed_checks(checks),
                   dtw_threshold=self.dtw_threshold,
                   tolerances=dataclasses.asdict(self.tolerances))
        return out


class HelloWorldLetterEnv(ShapeEnv):
    """## Description

    The Panda, holding a spring-loaded pen, writes one letter of the HelloWorld dataset (h, e, l,
    o, w, r or d) on a writing board. The letter's data are (x, y) points of the hand in the Panda
    base frame in metres, recorded while a person guided the robot over a horizontal surface, so
    the letter is written where the demonstrations were (x ≈ 0.33–0.45 m, y ≈ −0.10–0.09 m).
    The hand keeps a fixed orientation (pointing down, as in `home`) and a fixed height that
    presses the pen tip 4 mm into its spring; mink IK tracks the hand target at 60 Hz.

    ## Action Space

    `Box(2,)`, float64: the pen point (x, y) on the board in metres, Panda base frame, bounded
    by the board (x ∈ [0.15, 0.75], y ∈ [−0.35, 0.35]; `tasks/writing.toml`); actions outside are
    clipped. For HelloWorld, data units are these coordinates (`trajectory_to_actions` is the
    identity); one action per data sample (60 Hz).

    ## Observation Space

    `Dict`: `ee_pos` [3] and `ee_quat` [4] (w, x, y, z) of the `hand` body, `qpos` [7] and
    `qvel` [7] of the arm joints, `pen_tip` [3] (the tip point on the sprung nib, m),
    `pen_down` [1] (1.0 when the tip is on the board this step).

    ## Rewards

    Sparse: 1.0 on the step where success is decided true (the episode's last step), else 0.

    ## Episode End

    Truncated after the demo length (1000 steps) + 60 settle steps, or the `horizon` reset option.
    Terminated by a physics blow-up or a motion-limit failure (`info["failure_reason"]`, see
    `clfd_bench.envs.base`). Success is decided at the end (or by `evaluate()`) on the ink: the
    pen tip points of the steps the pen touched the board, compared with the target demo
    `reset(options={"demo": j})`, in metres. All of these must hold (`judge_shape`):

    - the pen was on the board for ≥ 90 % of the steps;
    - summed DTW ≤ the paper's HelloWorld threshold (1821 cm = 18.21 m);
    - shape: the symmetric Hausdorff distance between ink and target ≤ the letter's
      `hausdorff` tolerance ({hw_hausdorff} cm), and the ink passes within `coverage_radius`
      ({hw_coverage} cm) of the target along ≥ 90 % of its arc length;
    - end: the last ink point lies within `goal_tolerance` ({hw_goal} cm) of the letter's end
      point (the common end point of its demos: the letter was finished);
    - timing: the pen spent ≤ `max_dwell` ({hw_dwell}) of the steps within 1 cm of its last
      position (it wrote the letter rather than rushing to its end and waiting).

    The per-letter tolerances are derived from how much the letter's 8 demos differ from one
    another (`clfd_bench.envs.writing.derive`; procedure and constants in `tasks/writing.toml`
    [tolerances], values in `tasks/writing_tolerances.toml`): `hausdorff` = max(1.5 cm, the
    largest Hausdorff distance between two of its demos), `coverage_radius` = max(1 cm, the
    largest radius within which one demo covers 90 % of another's arc length), `max_dwell` =
    min(0.8, 1.5 × the largest dwell of a demo), `goal_tolerance` = max(1 cm, min(a tenth of
    the letter's size, `coverage_radius`)), the size being the median bounding-box diagonal
    of its demos. The ink may thus differ from the target as much as another demonstration of
    the letter does, and no more, and may stop short of (or run past) the letter's end by a
    tenth of the letter, as long as that is within the demos' spread. Replayed with every
    perturbation family of `clfd_bench.execution.perturb`, each demo and its 2× slower, 1.5×
    faster, noisy (3 mm) and start-offset (1 cm) variants succeed, and time-reversed,
    other-letter, half, straight-line, rush-and-wait, mirrored, drifting and teleporting ones
    fail. `info` reports `ink_fraction`, `dtw`, `hausdorff`, `coverage`, `goal_distance` (m),
    `dwell`, `failed` (the names of the failed checks), `dtw_threshold`, `tolerances`, and
    `checks`: every check as `clfd_bench.envs.checks.Check.to_json` (ink_fraction, dtw,
    hausdorff, coverage, goal, dwell: measured value, bound, comparison, lengths in m).

    Two checks can only get worse as the episode goes on, and `decided_failure()` reports them
    as soon as they break (the episode itself still runs to its horizon): an ink point farther
    than the `hausdorff` tolerance from the target, or so many steps off the board that the ink
    fraction stays below 90 %. `clfd_bench.execution.execute` stops a rollout there (same
    success; `docs/execution.md`, section 3).

    ## Arguments

    `letter` (h, e, l, o, w, r, d), `render_mode` (None | "rgb_array"), `physics_dt` (1/240 s),
    `ik_iterations` (1), `width`, `height`, `limits` ("panda").

    ## Rendering

    `render()` frames the letter: the camera looks at the centre of its demos' bounding box
    from the +y side, 30° down (the letter reads left to right, the hand shows above it), from
    the distance at which the box's bounding circle fits the frame's height.

    ## Version History

    - v3: the end point's bound is derived per letter (a tenth of the letter's size, within its
      coverage radius, at least 1 cm: 1.07-2.08 cm) instead of 1 cm for every letter; the
      dwell check's radius stays 1 cm as its own constant; `info["checks"]` reports every
      check's value and bound.
    - v2: the shape tolerances allow what separates the letter's demos at most (the largest
      pairwise Hausdorff distance and covering radius), not the median pair: learners that
      reproduce a letter as well as its own demonstrators failed 1 in 4 demos.
    - v1: success judged on the shape and timing of the ink, not only the summed DTW: adds the
      Hausdorff, arc-length coverage, and dwell checks with per-letter tolerances derived from
      the demos (a straight stroke passed 'l' on 3/8 demos, rushing to the end and waiting
      passed 'l' on 3/8 and 'h' on 1/8); the camera frames the letter; motion-limit failures.
    - v0: initial version.
    """

    dataset = "helloworld"
    data_units = "m"

    def __init__(self, letter: str = "h", render_mode: str | None = None, **kwargs: Any):
        self.letter = letter
        super().__init__(letter, render_mode, **kwargs)


class LasaShapeEnv(ShapeEnv):
    """## Description

    The Panda, holding a spring-loaded pen, draws one of the paper's 26 LASA handwriting shapes
    on the writing board of the HelloWorld tasks. Shape points p (LASA units) are laid on the
    board at `sim_scale · p + offset` (`sim_scale` from the data layer, 0.003 m per unit; the
    offset centres the bounding box of the shape's demos at (0.45, 0.0) m, `tasks/writing.toml`),
    so the goal (LASA's origin) lies at `offset`.

    ## Action Space

    `Box(2,)`, float64: the pen point (x, y) on the board in metres, Panda base frame (x ∈
    [0.15, 0.75], y ∈ [−0.35, 0.35]); clipped to the board. `trajectory_to_actions` maps LASA
    units to it. One action per data sample, executed at 60 Hz.

    ## Observation Space

    As `clfd/HelloWorld-<letter>-v3`: `ee_pos`, `ee_quat`, `qpos`, `qvel`, `pen_tip`, `pen_down`.

    ## Rewards

    Sparse: 1.0 on the step where success is decided true (the episode's last step), else 0.

    ## Episode End

    Truncated after the demo length (1000 steps) + 60 settle steps (or the `horizon` reset
    option); terminated by a physics blow-up or a motion-limit failure. Success is decided on
    the ink against the target demo, both in LASA units, as for `clfd/HelloWorld-<letter>-v3`
    (`judge_shape`): the pen on the board for ≥ 90 % of the steps; summed DTW ≤ the paper's
    LASA threshold (2191); symmetric Hausdorff distance ≤ the shape's `hausdorff` tolerance
    ({lasa_hausdorff} units); the ink within `coverage_radius` ({lasa_coverage} units)
    of the target along ≥ 90 % of its arc length; the last ink point within `goal_tolerance`
    ({lasa_goal} units) of the goal (LASA's origin); and the pen within 3.3 units (1 cm on the
    board) of its last position for ≤ `max_dwell` ({lasa_dwell}) of the steps. The tolerances
    are derived from the shape's 7 demos by the procedure of `clfd/HelloWorld-<letter>-v3`
    (`tasks/writing.toml` [tolerances]; the floors are 1.5 cm and 1 cm on the board, i.e. 5.0
    and 3.3 units; values in `tasks/writing_tolerances.toml`). `info` reports
    `ink_fraction`, `dtw`, `hausdorff`, `coverage`, `goal_distance`, `dwell` (LASA units),
    `failed`, `dtw_threshold`, `tolerances` (LASA units) and `checks` (as for the letters, in
    metres on the board: LASA units × 0.003). Failures decided before the end are reported by
    `decided_failure()` as for the letters.

    Limits: for `Line` a straight line from start to goal is the shape itself, so a straight
    stroke drawn at the demo's pace succeeds, as does the "mirrored" path (it stays on the same
    line); only its timing can differ.

    ## Arguments

    `shape` (a LASA name, e.g. "Angle", "JShape_2", "heee"), `render_mode`, `physics_dt`,
    `ik_iterations`, `width`, `height`, `limits` ("panda").

    ## Rendering

    `render()` frames the shape: the camera looks at the centre of its demos' bounding box from
    the −y side, 30° down (LASA's x axis points right, its y axis away / up), from the distance
    at which the box's bounding circle fits the frame's height.

    ## Version History

    - v3: the end point's bound is derived per shape as for the letters (1.18-1.96 cm on the
      board instead of 1 cm); `info["checks"]` reports every check (metres on the board).
    - v2: the shape tolerances allow what separates the shape's demos at most (the largest
      pairwise Hausdorff distance and covering radius), not the median pair.
    - v1: success judged on the shape and timing of the ink (Hausdorff, arc-length coverage and
      dwell checks, per-shape tolerances derived from the demos) besides the paper's DTW; the
      camera frames the shape; motion-limit failures.
    - v0: initial version.
    """

    dataset = "lasa"
    data_units = "lasa"

    def __init__(self, shape: str = "Angle", render_mode: str | None = None, **kwargs: Any):
        self.shape = shape
        super().__init__(shape, render_mode, **kwargs)

    #: Looking along +y (from the -y side): LASA's x axis points right and its y axis up.
    camera_azimuth = 90.0

    def _offset(self, demos: np.ndarray) -> np.ndarray:
        spec = load_writing_spec()
        lo, hi = demos.min(axis=(0, 1)), demos.max(axis=(0, 1))
        return np.array(spec.lasa_center) - self.sim_scale * (lo + hi) / 2.0


def _tolerance_ranges() -> dict[str, str]:
    """The docstrings' tolerance ranges, from the generated table (they stay in step with it)."""
    path = resource_path("tasks", load_writing_spec().tolerances_file)
    table = _tolerance_table(str(path))
    out = {}
    for key, ds, unit_scale, digits in (("hw", "helloworld", 100.0, 2), ("lasa", "lasa", 1.0, 1)):
        for name, field, scale in (("hausdorff", "hausdorff", unit_scale),
                                   ("coverage", "coverage_radius", unit_scale),
                                   ("goal", "goal_tolerance", unit_scale),
                                   ("dwell", "max_dwell", 1.0)):
            vals = [float(row[field]) * scale for row in table[ds].values()]
            out[f"{key}_{name}"] = f"{min(vals):.{digits}f}–{max(vals):.{digits}f}"
    return out


def _fill_docstrings() -> None:
    try:
        ranges = _tolerance_ranges()
    except (OSError, KeyError, ValueError) as exc:  # a broken table must not break the import
        ranges = {k: f"(unavailable: {exc!r})" for k in (
            "hw_hausdorff", "hw_coverage", "hw_goal", "hw_dwell", "lasa_hausdorff",
            "lasa_coverage", "lasa_goal", "lasa_dwell")}
    for cls in (HelloWorldLetterEnv, LasaShapeEnv):
        doc = cls.__doc__ or ""
        for key, text in ranges.items():
            doc = doc.replace("{" + key + "}", text)
        cls.__doc__ = doc


_fill_docstrings()
