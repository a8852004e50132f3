"""The borderline gallery (``clfd-bench gallery``): the learned executions nearest each
success criterion's bound, on both sides, drawn so a reader can check every verdict.

:func:`build_gallery` reads the runs of results folders, gathers every execution with its
env's final checks (:func:`clfd_bench.execution.final_checks.gather_executions`: executes what
the runs' caches lack), picks per env and numeric check the ``per_side`` executions nearest the
bound on the passing and on the failing side
(:func:`clfd_bench.execution.borderline.select_borderline`), executes each picked prediction
once more with a trace and draws it:

- writing envs (letters, shapes): in the task's data units, the task's demos (grey), the
  target demo (black), the prediction (orange, dashed) and the ink (blue), the start (circle)
  and the end point (cross); where the bound is a distance on the board it is drawn: the
  end-point check as a circle of its radius around the end point, the Hausdorff check as the
  farthest pair of points with a circle of the allowed distance;
- scenes (RoboTasks, RoboTasks9): the closing frame (the final state, offscreen MuJoCo,
  :func:`clfd_bench.viz.video.closing_frame`) with the demonstration, the prediction and the
  gripper's path drawn in.

Each picture is captioned with the method, task, demo (and after which task), the check's
value against its bound and its verdict, whether it alone decided the execution, and every
check of the execution. Written to ``OUT``: ``<dataset>/<env>/<check>_<side><k>.png``,
``gallery.md`` (every picture, grouped by dataset, env and check) and one contact sheet per
dataset (``sheet_<dataset>.png``: per check, the nearest pass and the nearest failure across
the dataset's envs) for the docs.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.envs.checks import Check
from clfd_bench.execution.borderline import Borderline, Pick, select_borderline

__all__ = ["GalleryReport", "build_gallery", "draw_writing", "execute_writing",
           "pick_caption", "sheet_picks"]

#: Pixels of one scene's closing frame.
_FRAME_W, _FRAME_H = 800, 600
_DPI = 100


@dataclasses.dataclass
class GalleryReport:
    """What :func:`build_gallery` wrote and measured.

    Attributes:
        out: the output folder; markdown: its ``gallery.md``.
        sheets: dataset -> contact sheet path.
        pictures: pictures drawn.
        borderlines: the selection (per env and check).
        executions: distinct executions considered; left_out: of them, those not describing
            a whole episode (ended early on a motion limit, tracking, reach or collision).
        no_checks: env id -> executions whose env reported no checks.
        skipped: run path -> why it was left out.
        mismatches: picks whose re-executed check differed from the cached one.
        gather_s, render_s: wall-clock seconds of gathering (executions) and drawing.
    """

    out: Path
    markdown: Path
    sheets: dict[str, Path]
    pictures: int
    borderlines: list[Borderline]
    executions: int
    left_out: int
    no_checks: dict[str, int]
    skipped: dict[str, str]
    mismatches: list[str]
    gather_s: float
    render_s: float


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_")


def _method(label: dict[str, Any]) -> str:
    from clfd_bench.viz.video import method_label

    method = str(label.get("method") or "")
    return method_label(method) if method else Path(str(label.get("run", "?"))).name


def _verdict(check: Check) -> str:
    return "passes" if check.passed else "fails"


def pick_caption(pick: Pick) -> list[str]:
    """The caption lines of a pick: who (method, task, demo, after which task), the check's
    value against its bound with its verdict and margin, and whether it alone decided the
    execution."""
    lab, c = pick.execution.label, pick.check
    who = (f"{_method(lab)} · task '{lab.get('task')}' · demo {lab.get('demo')} · after task "
           f"{lab.get('after_task')}")
    unit = f" {c.unit}" if c.unit else ""
    what = f"{c.describe()} → {_verdict(c)} (margin {c.margin:+.3g}{unit})"
    if pick.side == "pass":
        why = ("execution succeeded (every check passes)" if pick.decisive else
               f"execution failed on {', '.join(pick.also_failed)}")
    else:
        why = ("only this check fails: it alone fails the execution" if pick.decisive else
               f"also fails: {', '.join(pick.also_failed)}")
    return [who, what, why]


def sheet_picks(borderlines: Sequence[Borderline], dataset_of: dict[str, str]
                ) -> dict[str, list[tuple[str, Pick | None, Pick | None]]]:
    """Per dataset, one row per check name (and unit): the nearest pass and the nearest
    failure over the dataset's envs (failures of only this check preferred, as in the
    selection); None where a side has no execution."""
    groups: dict[str, dict[str, list[Borderline]]] = {}
    for b in borderlines:
        unit = (b.passing or b.failing)[0].check.unit if (b.passing or b.failing) else ""
        row = f"{b.check} [{unit}]" if unit else b.check
        groups.setdefault(dataset_of.get(b.env_id, "?"), {}).setdefault(row, []).append(b)

    def best(picks: list[Pick], side: str) -> Pick | None:
        if not picks:
            return None
        if side == "pass":
            return min(picks, key=lambda p: (p.margin, p.execution.key))
        return min(picks, key=lambda p: (not p.decisive, -p.margin, p.execution.key))

    return {ds: [(row, best([p for b in bs for p in b.passing], "pass"),
                  best([p for b in bs for p in b.failing], "fail"))
                 for row, bs in rows.items()]
            for ds, rows in groups.items()}


def build_gallery(results_dirs: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str],
                  *, per_side: int = 2, sheets: str | os.PathLike[str] | None = None,
                  workers: int = 1) -> GalleryReport:
    """Writes the borderline gallery of the runs in ``results_dirs`` to ``out``.

    Args:
        results_dirs: results folders (or run directories): every run under them
            (:func:`clfd_bench.runs.find_runs`).
        out: output folder (created): the pictures, ``gallery.md`` and the contact sheets.
        per_side: pictures per check and side.
        sheets: write the contact sheets here instead of ``out`` (e.g. ``docs/figures``).
        workers: processes executing what the runs' caches lack.

    Returns:
        A :class:`GalleryReport`.

    Raises:
        ValueError: a folder holds no run (the message names it), or no run could be read.
    """
    from clfd_bench.execution.final_checks import gather_executions
    from clfd_bench.runs import find_runs

    run_dirs = []
    for folder in results_dirs:
        found = find_runs(folder) if Path(folder).is_dir() else []
        if not found:
            raise ValueError(f"{folder} holds no run (no results.json under it); pass a "
                             "results folder of `clfd-bench leaderboard` or a run directory "
                             "of `clfd-bench train`")
        run_dirs += [r.path for r in found]
    t0 = time.perf_counter()
    gathered = gather_executions(run_dirs, workers=workers)
    gather_s = time.perf_counter() - t0
    if not gathered.runs:
        raise ValueError("no run could be read: " + "; ".join(
            f"{k}: {v}" for k, v in gathered.skipped.items()))
    borderlines = select_borderline(gathered.executions, per_side=per_side)
    unique = {ex.key: ex for ex in gathered.executions}  # one per executed prediction
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    dataset_of = {ex.env_id: str(ex.label.get("dataset")) for ex in gathered.executions}
    t1 = time.perf_counter()
    drawer = _Drawer(out)
    paths: dict[tuple[str, str, str, int], Path] = {}
    todo = [(b, side, k, p) for b in borderlines
            for side, picks in (("pass", b.passing), ("fail", b.failing))
            for k, p in enumerate(picks)]
    from clfd_bench.progress import progress

    bar = progress(total=len(todo), desc="gallery", unit="picture")
    try:
        for b, side, k, pick in todo:
            rel = Path(_safe(dataset_of[b.env_id])) / _safe(b.env_id.split("/")[-1]) / \
                f"{_safe(b.check)}_{side}{k + 1}.png"
            drawer.draw(pick, out / rel)
            paths[(b.env_id, b.check, side, k)] = rel
            bar.update(1)
    finally:
        bar.close()
        drawer.close()
    sheet_dir = Path(sheets) if sheets is not None else out
    sheet_paths = _write_sheets(borderlines, dataset_of, paths, out, sheet_dir)
    render_s = time.perf_counter() - t1
    report = GalleryReport(
        out=out, markdown=out / "gallery.md", sheets=sheet_paths, pictures=len(todo),
        borderlines=borderlines, executions=len(unique),
        left_out=sum(not ex.complete for ex in unique.values()),
        no_checks=gathered.no_checks, skipped=gathered.skipped,
        mismatches=drawer.mismatches, gather_s=gather_s, render_s=render_s)
    _write_markdown(report, dataset_of, paths, [str(d) for d in results_dirs], per_side)
    return report


class _Drawer:
    """Executes picked predictions again (with a trace) and draws them; one execution is run
    once even when it is picked for several checks."""

    def __init__(self, out: Path):
        self.out = out
        self.mismatches: list[str] = []
        self._runs: dict[tuple[str, int], dict[int, np.ndarray]] = {}
        self._demos: dict[str, list[np.ndarray]] = {}
        self._done: dict[str, dict[str, Any]] = {}

    def close(self) -> None:
        self._done.clear()

    def _prediction(self, label: dict[str, Any]) -> np.ndarray:
        from clfd_bench.runs import RunDir

        key = (str(label["run"]), int(label["after_task"]))
        if key not in self._runs:
            self._runs = {key: RunDir(key[0]).load_predictions(key[1])}  # one file held
        return self._runs[key][int(label["task_index"])][int(label["demo"])]

    def _demonstration(self, label: dict[str, Any]) -> np.ndarray:
        from clfd_bench.execution.saved_run import load_run

        run = str(label["run"])
        if run not in self._demos:
            self._demos[run] = load_run(run).demos()
        return self._demos[run][int(label["task_index"])][int(label["demo"])]

    def _execute(self, pick: Pick) -> dict[str, Any]:
        """The picked execution run again: its result and what to draw."""
        from clfd_bench.execution.env_pool import get_env
        from clfd_bench.viz.video import VideoStyle, closing_frame

        key = pick.execution.key
        if key in self._done:
            return self._done[key]
        lab = pick.execution.label
        env = get_env(str(lab["env_id"]))
        base = env.unwrapped
        traj = self._prediction(lab)
        demo = int(lab["demo"])
        if getattr(base, "tool", None) == "pen" and hasattr(base, "target"):
            drawn = execute_writing(env, traj, demo)
        else:
            style = VideoStyle(width=_FRAME_W, height=_FRAME_H)
            result, frame = closing_frame(env, traj, demo,
                                          demonstration=self._demonstration(lab), style=style)
            drawn = {"kind": "scene", "frame": frame}
            drawn["result"] = result
            drawn["checks"] = result.checks() or []
        self._done = {key: drawn}  # keep one: picks of one execution are drawn in a row
        return drawn

    def draw(self, pick: Pick, path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.patches import Rectangle

        drawn = self._execute(pick)
        checks: list[Check] = drawn["checks"]
        now = next((c for c in checks if c.name == pick.check.name), None)
        if now is None or now.passed != pick.check.passed or not math.isclose(
                now.margin, pick.check.margin, rel_tol=1e-6, abs_tol=1e-12):
            self.mismatches.append(f"{path.name}: cached {pick.check.describe()}, re-executed "
                                   f"{now.describe() if now else 'no such check'}")
        fig = plt.figure(figsize=(_FRAME_W / _DPI, 7.4), dpi=_DPI)
        ax = fig.add_axes((0.1, 0.25, 0.87, 0.6))
        if drawn["kind"] == "writing":
            draw_writing(ax, drawn, pick.check)
        else:
            ax.imshow(drawn["frame"])
            ax.set_axis_off()
        colour = "#1e9e46" if pick.check.passed else "#d62728"
        lines = pick_caption(pick)
        fig.text(0.02, 0.975, lines[0], fontsize=11, va="top")
        fig.text(0.02, 0.935, lines[1], fontsize=12, va="top", color=colour,
                 fontweight="bold")
        fig.text(0.02, 0.895, lines[2], fontsize=10, va="top")
        listing = "   ".join(f"{'✓' if c.passed else '✗'} {c.describe()}" for c in checks)
        fig.text(0.02, 0.17, "all checks of this execution:\n" + _wrap(listing, 105),
                 fontsize=8, va="top", family="monospace")
        fig.patches.append(Rectangle(  # the verdict's colour as a border
            (0.003, 0.003), 0.994, 0.994, transform=fig.transFigure, fill=False,
            edgecolor=colour, linewidth=4))
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=_DPI)
        plt.close(fig)


def _wrap(text: str, width: int) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(text, width, break_on_hyphens=False))


def _bound_in_data(check: Check, drawn: dict[str, Any]) -> float | None:
    """The check's bound as a distance in the task's data units (None when its unit is not a
    length the board knows)."""
    if check.unit and check.unit == drawn["data_units"]:
        return float(check.bound)
    if check.unit == "m":  # a distance on the board (m): data = board / sim_scale
        return float(check.bound) / drawn["sim_scale"]
    return None


def execute_writing(env: Any, trajectory: np.ndarray, demo: int) -> dict[str, Any]:
    """Executes `trajectory` ([T, 2], the task's data units) on a writing env (letter or shape)
    against demo `demo`, to the horizon, and returns what :func:`draw_writing` draws: kind
    "writing", target [T', 2], demos [N, T', 2], ink [K, 2] (data units), goal [2],
    prediction [T, 2], data_units, flip (HelloWorld: drawn as the letter reads), sim_scale,
    result (:class:`clfd_bench.execution.execute.ExecResult`) and checks (its final
    :class:`Check` list)."""
    from clfd_bench.execution.execute import execute

    base = env.unwrapped
    result = execute(env, trajectory, demo, stop_when_decided=False)
    return {"kind": "writing", "target": np.asarray(base.target(), float),
            "demos": np.asarray(base.demos, float),
            "ink": base.to_data(base.ink_trace()), "goal": np.asarray(base.goal),
            "prediction": np.asarray(trajectory, float),
            "data_units": str(getattr(base, "data_units", "")),
            "flip": getattr(base, "dataset", "") == "helloworld",
            "sim_scale": float(getattr(base, "sim_scale", 1.0)),
            "result": result, "checks": result.checks() or []}


def draw_writing(ax: Any, drawn: dict[str, Any], check: Check) -> None:
    """Draws on matplotlib axes `ax` the ink against the target in data units (the task's demos,
    the target demo, the prediction, the ink, start and end point; `drawn` from
    :func:`execute_writing`), with `check`'s bound where it is a distance (the end point's
    as a circle around the end point, Hausdorff's as the farthest pair of points)."""
    import matplotlib.patches as mpatches

    from clfd_bench.metrics.trajectory import nearest_distances

    for k, d in enumerate(drawn["demos"]):
        ax.plot(d[:, 0], d[:, 1], color="0.82", lw=1.0, zorder=1,
                label="the task's demos" if k == 0 else None)
    target, ink, pred, goal = drawn["target"], drawn["ink"], drawn["prediction"], drawn["goal"]
    ax.plot(target[:, 0], target[:, 1], color="black", lw=1.6, zorder=2, label="target demo")
    ax.plot(pred[:, 0], pred[:, 1], color="#ff8c00", lw=1.2, ls="--", zorder=3,
            label="prediction")
    if len(ink):
        ax.plot(ink[:, 0], ink[:, 1], color="#1f4fd8", lw=2.2, alpha=0.85, zorder=4,
                label="ink")
        ax.plot(*ink[-1], "o", color="#1f4fd8", ms=6, zorder=6, label="last ink point")
    ax.plot(*target[0], "o", mfc="white", mec="black", ms=8, zorder=5, label="start")
    ax.plot(*goal, "x", color="black", ms=9, mew=2, zorder=5, label="end point")
    radius = _bound_in_data(check, drawn)
    colour = "#1e9e46" if check.passed else "#d62728"
    if radius is not None and check.name.startswith("goal"):
        ax.add_patch(mpatches.Circle(goal, radius, fill=False, ec=colour, lw=1.6, ls="-",
                                     zorder=7, label=f"bound: {check.bound:.4g} {check.unit}"))
    elif radius is not None and check.name.startswith("hausdorff") and len(ink) >= 2:
        d_ink, d_target = nearest_distances(ink, target)
        if d_ink.max() >= d_target.max():
            a = ink[int(np.argmax(d_ink))]
            b = target[int(np.argmin(np.linalg.norm(target - a, axis=1)))]
        else:
            b = target[int(np.argmax(d_target))]
            a = ink[int(np.argmin(np.linalg.norm(ink - b, axis=1)))]
        ax.plot([a[0], b[0]], [a[1], b[1]], color=colour, lw=2.0, zorder=7,
                label="farthest pair")
        ax.add_patch(mpatches.Circle(b, radius, fill=False, ec=colour, lw=1.6, zorder=7,
                                     label=f"bound: {check.bound:.4g} {check.unit}"))
    ax.set_aspect("equal", adjustable="datalim")
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7, loc="best", framealpha=0.8)
    unit = f" ({drawn['data_units']})" if drawn["data_units"] else ""
    if drawn["flip"]:  # seen from in front of the board, as the videos show the letters
        ax.invert_xaxis()
        ax.invert_yaxis()
        unit += ", axes reversed: the letter as it reads on the board"
    ax.set_xlabel(f"x{unit}", fontsize=8)
    ax.set_ylabel("y", fontsize=8)


def _write_sheets(borderlines: Sequence[Borderline], dataset_of: dict[str, str],
                  paths: dict[tuple[str, str, str, int], Path], out: Path, sheet_dir: Path
                  ) -> dict[str, Path]:
    """One contact sheet per dataset (rows: checks; columns: nearest pass, nearest failure),
    tiles at half size."""
    from PIL import Image, ImageDraw

    from clfd_bench.io import atomic_write_bytes

    index = {(b.env_id, b.check, side, k): p for b in borderlines
             for side, picks in (("pass", b.passing), ("fail", b.failing))
             for k, p in enumerate(picks)}
    where = {id(p): paths[key] for key, p in index.items()}
    sheet_dir.mkdir(parents=True, exist_ok=True)
    written: dict[str, Path] = {}
    for dataset, rows in sheet_picks(borderlines, dataset_of).items():
        tiles: list[list[Image.Image | None]] = []
        for _, passing, failing in rows:
            tiles.append([None if p is None else _tile(out / where[id(p)])
                          for p in (passing, failing)])
        size = next((t.size for row in tiles for t in row if t is not None), (400, 370))
        w, h = size
        head = 28
        sheet = Image.new("RGB", (2 * w, head + h * len(rows)), "white")
        draw = ImageDraw.Draw(sheet)
        draw.text((10, 6), "nearest pass", fill=(30, 158, 70))
        draw.text((w + 10, 6), "nearest failure", fill=(214, 39, 40))
        for r, row in enumerate(tiles):
            for c, tile in enumerate(row):
                if tile is None:
                    draw.text((c * w + 10, head + r * h + h // 2),
                              f"no execution on this side ({rows[r][0]})", fill=(90, 90, 90))
                else:
                    sheet.paste(tile, (c * w, head + r * h))
        import io

        buf = io.BytesIO()
        sheet = sheet.quantize(colors=128, method=Image.Quantize.MEDIANCUT)
        sheet.save(buf, format="PNG", optimize=True)
        path = sheet_dir / f"gallery_{_safe(dataset)}.png"
        atomic_write_bytes(path, buf.getvalue())
        written[dataset] = path
    return written


def _tile(path: Path):
    from PIL import Image

    with Image.open(path) as im:
        im = im.convert("RGB")
        return im.resize((im.width // 2, im.height // 2), Image.Resampling.LANCZOS)


def _write_markdown(report: GalleryReport, dataset_of: dict[str, str],
                    paths: dict[tuple[str, str, str, int], Path], folders: list[str],
                    per_side: int) -> None:
    from clfd_bench.io import atomic_write_bytes

    lines = ["# Borderline gallery", "",
             f"Generated by `clfd-bench gallery {' '.join(folders)} --out {report.out} "
             f"--per-side {per_side}`.", "",
             "Per env and numeric check, the executions nearest the bound on the passing side "
             "and on the failing side (there, executions that fail only this check first). "
             "Every picture is the execution run again.", "",
             f"- distinct executions: {report.executions} (left out as not describing a "
             f"whole episode: {report.left_out})",
             f"- pictures: {report.pictures}; gathering {report.gather_s:.0f} s, drawing "
             f"{report.render_s:.0f} s"]
    if report.no_checks:
        lines.append("- **no checks reported** (envs that do not fill `info[\"checks\"]`; not "
                     "in the gallery): " + ", ".join(f"{e} ({n} executions)" for e, n in
                                                    sorted(report.no_checks.items())))
    if report.skipped:
        lines.append("- runs left out: " + "; ".join(f"{k}: {v}" for k, v in
                                                     report.skipped.items()))
    if report.mismatches:
        lines.append(f"- re-executions that differ from the cached check ({len(report.mismatches)}"
                     "): " + "; ".join(report.mismatches))
    for dataset, sheet in report.sheets.items():
        rel = os.path.relpath(sheet, report.out)
        lines += ["", f"Contact sheet of {dataset}: [{rel}]({rel})"]
    current = None
    for b in report.borderlines:
        ds = dataset_of.get(b.env_id, "?")
        if ds != current:
            lines += ["", f"## {ds}"]
            current = ds
        lines += ["", f"### {b.env_id} · {b.check}", "",
                  f"{b.candidates[0]} executions pass, {b.candidates[1]} fail.", ""]
        for side, picks in (("pass", b.passing), ("fail", b.failing)):
            if not picks:
                lines.append(f"- {side}: no execution on this side")
            for k, p in enumerate(picks):
                cap = pick_caption(p)
                lines.append(f"- {side} {k + 1}: {cap[0]} — {cap[1]}; {cap[2]} "
                             f"![]({paths[(b.env_id, b.check, side, k)].as_posix()})")
    atomic_write_bytes(report.markdown, ("\n".join(lines) + "\n").encode())
