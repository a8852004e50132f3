"""``build_site``: a results folder -> a static site (HTML from Jinja2 templates).

What the site holds (``SITE_DIR/``)::

    index.html               leaderboard (sortable), paper comparison, the profiles side by
                             side (when ``clfd-bench paper profiles --out`` wrote
                             profile_comparison.json into the results folder), figures,
                             video wall
    runs/<run>.html          per run: R matrices as heat maps, CL metrics, execution
                             failures of its last model, config, provenance
    runs/<run>_R.png         the heat maps
    figures/*.png            the leaderboard's figures (copied)
    videos/<run>/<key>/task<j>/*.mp4   the wall's tiles, each with its poster *.png (see
                             clfd_bench.site.wall)
    data/leaderboard.*       the leaderboard's tables (copied)
    site.css, sort.js        style and the table sorter (a few lines of plain JavaScript)
    wall.js                  plays a wall tile while the pointer is on it (posters otherwise)

Everything is read through the files' owner modules: the leaderboard
(:mod:`clfd_bench.leaderboard.report`), the runs (:mod:`clfd_bench.execution.saved_run`,
:mod:`clfd_bench.runs`), the paper's numbers (:mod:`clfd_bench.metrics.paper_numbers`, via
the leaderboard), the profile comparison (:mod:`clfd_bench.studies.profile_compare`). Links
are relative, so the folder opens from disk and from any static host.
Every file is written atomically; pages, heat maps and copies are rewritten on every build,
videos are rendered once (an interrupted build resumes where it stopped).
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import math
import re
import shutil
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from clfd_bench.io import atomic_write_bytes, atomic_write_text
from clfd_bench.leaderboard.report import COLUMNS
from clfd_bench.leaderboard.report import format_cell as _fmt
from clfd_bench.metrics.glossary import GLOSSARY, tooltip
from clfd_bench.site.wall import (
    WALL_STYLE,
    TileJob,
    TileResult,
    existing_video,
    poster_for,
    render_tiles,
    tile_key,
)
from clfd_bench.studies.profile_compare import caption as comparison_caption
from clfd_bench.studies.profile_compare import read_comparison
from clfd_bench.studies.profile_compare import table as comparison_table

__all__ = ["WALL_STYLE", "SiteResult", "best_marks", "build_site"]

#: The titles of the leaderboard's column groups (``Column.group``, of
#: :data:`clfd_bench.leaderboard.report.COLUMNS`, the table's columns).
_GROUPS = {"trajectory": "Trajectory (DTW under the paper's threshold)",
           "execution": "Execution on the simulated Panda", "cost": "Cost"}
_STATIC = ("site.css", "sort.js", "wall.js")
#: The table's other headers, by glossary key (their tooltips: clfd_bench.metrics.glossary).
_HEADER_KEYS = ("rank", "paper_rank", "method", "runs", "exec_failures")
#: The CL metrics of a run's page, in its order.
_RUN_METRICS = ("ACC", "REM", "BWT", "MS", "TE", "SSS")


@dataclasses.dataclass
class SiteResult:
    """What :func:`build_site` did.

    Attributes:
        index: the site's ``index.html``.
        pages: every HTML page written.
        videos_rendered, videos_reused: wall tiles rendered now / found from a previous build.
        video_errors: ``(run, task, error)`` of tiles without a video.
        seconds: wall-clock time of the build; video_seconds: of its video rendering.
    """

    index: Path
    pages: list[Path]
    videos_rendered: int = 0
    videos_reused: int = 0
    video_errors: list[tuple[str, str, str]] = dataclasses.field(default_factory=list)
    seconds: float = 0.0
    video_seconds: float = 0.0


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.+=-]+", "__", name).strip("_") or "run"


def _copy(src: Path, dst: Path) -> Path:
    atomic_write_bytes(dst, src.read_bytes())
    return dst


def _flatten(value: Any, prefix: str = "") -> list[tuple[str, str]]:
    """Nested mappings as ``(dotted.key, text)`` rows; lists of scalars as one row."""
    if isinstance(value, Mapping):
        rows: list[tuple[str, str]] = []
        for key, sub in value.items():
            rows += _flatten(sub, f"{prefix}.{key}" if prefix else str(key))
        return rows
    if isinstance(value, (list, tuple)) and value and all(isinstance(v, Mapping) for v in value):
        if all(v == value[0] for v in value):  # e.g. the same CPU for every task
            return _flatten(value[0], f"{prefix}[all {len(value)}]")
        rows = []
        for k, sub in enumerate(value):
            rows += _flatten(sub, f"{prefix}[{k}]")
        return rows
    if isinstance(value, str):
        return [(prefix, value)]
    return [(prefix, json.dumps(value))]


# ----------------------------------------------------------------------------- the table
def _shown(value: float | None, key: str) -> float | None:
    """``value`` as its cell shows it (rounded to the cell's precision,
    :func:`~clfd_bench.leaderboard.report.format_cell`), None for no value."""
    if value is None or math.isnan(value):
        return None
    return float(_fmt(value, key).replace(",", ""))


def best_marks(values: Sequence[float | None], better: str | None) -> list[str | None]:
    """Which cells of a column to mark: ``"best"`` (the column's best value, alone), ``"tie"``
    (tied for the best: equal to it at the shown precision) or None, per value.

    ``values`` are as shown (:func:`_shown`; None: an empty cell); ``better`` is the column's
    direction from the glossary (``"higher"``, ``"lower"``, or None: nothing is marked).
    Nothing is marked either when fewer than two cells have a value or when every value is
    the best (a column where all tie singles nobody out)."""
    given = [v for v in values if v is not None]
    if better is None or len(given) < 2:
        return [None] * len(values)
    best = max(given) if better == "higher" else min(given)
    n_best = sum(v == best for v in given)
    if n_best == len(given):
        return [None] * len(values)
    mark = "best" if n_best == 1 else "tie"
    return [mark if v is not None and v == best else None for v in values]


def _better(key: str) -> str | None:
    term = GLOSSARY.get(key)
    return term.better if term is not None else None


def _header_tip(key: str) -> str:
    """A header's tooltip: the glossary's definition and which way is better."""
    better = _better(key)
    return tooltip(key) + (f" ({better} is better)" if better else "")


def _mark_column(cells: list[dict[str, Any]], shown: list[float | None], better: str | None,
                 names: list[str]) -> None:
    """Sets ``mark`` and ``mark_tip`` of one column's cells (:func:`best_marks`)."""
    marks = best_marks(shown, better)
    tied = [name for name, mark in zip(names, marks, strict=True) if mark == "tie"]
    for cell, mark, name in zip(cells, marks, names, strict=True):
        cell["mark"] = mark
        if mark == "best":
            cell["mark_tip"] = f"the column's best ({better} is better)"
        elif mark == "tie":
            others = ", ".join(n for n in tied if n != name)
            cell["mark_tip"] = (f"tied for the column's best with {others}: equal at the "
                                f"shown precision ({better} is better)")


def _table(doc: dict[str, Any], paper: dict[str, dict[str, float]],
           pages: dict[str, list[tuple[str, str]]]) -> dict[str, Any]:
    """The leaderboard table's header groups and rows (cells with text and sort value)."""
    from clfd_bench.execution.execute import FAILURE_KINDS
    from clfd_bench.metrics.paper_numbers import CL_COLUMNS  # shown under ours

    rows = []
    kinds = [k for k in FAILURE_KINDS
             if any((r.get("exec_failures") or {}).get(k) for r in doc["rows"])]
    for row in doc["rows"]:
        method = str(row["method"])
        ours = paper.get(method.lower(), {})
        cells = []
        for key, _, group in COLUMNS:
            metric = (row.get("metrics") or {}).get(key) or {}
            median, q1, q3 = metric.get("median"), metric.get("q1"), metric.get("q3")
            text = ("—" if median is None and key in (row.get("not_provided") or [])
                    else _fmt(median, key))
            n = len(metric.get("values") or [])
            tip = (f"median {_fmt(median, key)}, IQR [{_fmt(q1, key)}, {_fmt(q3, key)}] over "
                   f"{n} run{'s' if n != 1 else ''}") if median is not None else ""
            cells.append({
                "text": text, "sort": "" if median is None else f"{median:.9g}", "tip": tip,
                "shown": _shown(median, key),
                "group": group,
                "paper": (f"{ours[key]:.2f}" if key in CL_COLUMNS and key in ours else None),
            })
        failures = row.get("exec_failures")
        rows.append({
            "rank": row["rank"], "method": method, "name": method.upper(),
            "runs_ok": row.get("runs_ok", 0), "runs_failed": row.get("runs_failed", 0),
            "paper_rank": row.get("paper_rank"), "cells": cells,
            "failures": None if failures is None else [(k, failures.get(k, 0)) for k in kinds],
            "failures_total": None if failures is None else sum(failures.values()),
            "failed_checks": ", ".join(f"{name} {n}" for name, n in
                                       (row.get("exec_failed_checks") or {}).items()),
            "errors": row.get("errors") or [], "pages": pages.get(method, []),
            "fails_cell": {"mark": None},
        })
    names = [r["name"] for r in rows]
    for c, (key, _, _) in enumerate(COLUMNS):
        column = [r["cells"][c] for r in rows]
        _mark_column(column, [cell["shown"] for cell in column], _better(key), names)
    _mark_column([r["fails_cell"] for r in rows],
                 [None if r["failures_total"] is None else float(r["failures_total"])
                  for r in rows], _better("exec_failures"), names)
    groups = []
    for _, _, group in COLUMNS:
        if groups and groups[-1]["key"] == group:
            groups[-1]["span"] += 1
        else:
            groups.append({"key": group, "title": _GROUPS[group], "span": 1})
    return {"groups": groups,
            # under the "Execution on the simulated Panda" group its columns drop "exec "
            "columns": [{"key": k, "head": h.removeprefix("exec ") if g == "execution" else h,
                         "group": g, "title": _header_tip(k), "better": _better(k) or ""}
                        for k, h, g in COLUMNS],
            "tips": {k: _header_tip(k) for k in _HEADER_KEYS},
            "better": {k: _better(k) or "" for k in _HEADER_KEYS},
            "rows": rows, "kinds": kinds}


# ----------------------------------------------------------------------------- runs
@dataclasses.dataclass
class _Run:
    """A run of the leaderboard as the site shows it."""

    label: str
    name: str
    slug: str
    status: str
    seed: int | None
    order: int | None
    saved: Any = None  # SavedRun, or None when the run has no readable results
    error: str | None = None
    tiles: list[dict[str, Any]] = dataclasses.field(default_factory=list)

    @property
    def page(self) -> str:
        return f"runs/{self.slug}.html"


def _load_runs(results_dir: Path, doc: dict[str, Any]) -> list[_Run]:
    from clfd_bench.execution.saved_run import load_run
    from clfd_bench.leaderboard.report import leaderboard_runs
    from clfd_bench.runs import RunFileError

    runs = []
    for run in leaderboard_runs(results_dir, doc):
        entry = _Run(run.label, run.name, _slug(run.name), run.status, run.seed, run.order)
        try:
            entry.saved = load_run(run.path)
        except (FileNotFoundError, RunFileError, ValueError) as exc:
            entry.error = str(exc)
        runs.append(entry)
    return runs


def _wall_runs(runs: list[_Run], order: list[str]) -> list[_Run]:
    """Per row (in the table's order), the run whose last learned model the wall shows: its
    first finished run (grid order: task order, then seed) that learned something."""
    chosen = []
    for label in order:
        for run in runs:
            if (run.label == label and run.saved is not None and run.saved.num_learned > 0
                    and run.status in ("done", "included")):
                chosen.append(run)
                break
    return chosen


def _tile_jobs(site: Path, run: _Run, demo: int, style: Mapping[str, Any]) -> list[TileJob]:
    from clfd_bench.runs import RunDir

    saved = run.saved
    last = saved.num_learned - 1
    fingerprint = (saved.provenance().get("execution") or {}).get("fingerprint")
    key = tile_key(RunDir(saved.path).predictions_sha256(last), fingerprint, demo,
                   style["width"], style["height"], style["fps"])
    base = site / "videos" / run.slug
    if base.is_dir():  # tiles of older predictions, simulators or styles
        for old in base.iterdir():
            if old.is_dir() and old.name != key:
                shutil.rmtree(old)
    return [TileJob(str(saved.path), j, demo, str(base / key / f"task{j}"), style["width"],
                    style["height"], style["fps"]) for j in range(saved.num_learned)]


def _tile(run: _Run, j: int, demo: int, result: TileResult | None, site: Path,
          videos: bool) -> dict[str, Any]:
    """What the wall shows for task j of a run: its video and its execution outcome."""
    saved = run.saved
    execution = saved.execution(j)
    tile: dict[str, Any] = {"task": j, "name": saved.task_names[j], "video": None,
                            "poster": None, "outcome": None, "kind": None, "reason": None,
                            "rate": None, "note": None}
    if execution is not None and demo < len(execution.success):
        ok = execution.success[demo]
        tile.update(outcome="success" if ok else "failure", kind=execution.kinds[demo],
                    reason=execution.reasons[demo],
                    rate=f"{sum(execution.success)}/{len(execution.success)} demos succeed")
    elif execution is None:
        tile["note"] = "not executed in simulation"
    if result is not None and result.video is not None:
        tile["video"] = result.video.relative_to(site).as_posix()
        tile["poster"] = poster_for(result.video).relative_to(site).as_posix()
    elif result is not None:
        tile["note"] = f"no video: {result.error}"
    elif not videos:
        tile["note"] = tile["note"] or "videos not rendered (--no-videos)"
    return tile


def _run_metric_tip(key: str) -> str:
    """A run page's CL metric row: its glossary definition, and its execution counterpart's."""
    from clfd_bench.metrics.glossary import GLOSSARY

    tip = tooltip(key)
    return tip + (f" Execution column: {tooltip('exec_' + key)}" if f"exec_{key}" in GLOSSARY
                  else "")


def _run_page(run: _Run, site: Path) -> dict[str, Any]:
    """The context of a run's page."""
    from clfd_bench.site.heatmaps import plot_r_matrices

    ctx: dict[str, Any] = {"run": run, "error": run.error}
    saved = run.saved
    if saved is None:
        return ctx
    results = saved.results
    matrices = saved.accuracy_matrices()
    if matrices and saved.num_learned:
        png = site / "runs" / f"{run.slug}_R.png"
        plot_r_matrices(matrices, saved.task_names, png,
                        thresholds=results.get("thresholds") or {},
                        title=f"{run.label.upper()} {run.name}")
        ctx["heatmap"] = png.name
    ctx["matrix_names"] = list(matrices)
    cl = results.get("cl_metrics") or {}
    sim_cl = results.get("sim_cl_metrics") or {}
    ctx["metrics"] = [(k, _fmt(cl.get(k), k), _fmt(sim_cl.get(k), k) if k in sim_cl else "",
                       _run_metric_tip(k)) for k in _RUN_METRICS]
    ctx["r_tip"] = tooltip("R")
    failures = []
    for j in range(saved.num_learned):
        execution = saved.execution(j)
        if execution is None:
            continue
        for d, ok in enumerate(execution.success):
            if not ok:
                failures.append({"task": saved.task_names[j], "demo": d,
                                 "kind": execution.kinds[d], "reason": execution.reasons[d]})
    ctx["failures"] = failures
    ctx["executed"] = saved.executed
    ctx["config"] = _flatten(results.get("config") or {})
    ctx["provenance"] = {section: _flatten(values)
                         for section, values in saved.provenance().items()}
    ctx["has_commit"] = any("commit" in key for rows in ctx["provenance"].values()
                            for key, _ in rows)
    ctx["summary"] = [
        ("method", saved.method or run.label),
        ("dataset", saved.dataset), ("task order", str(saved.order)),
        ("tasks", ", ".join(saved.task_names)),
        ("learned", f"{saved.num_learned} of {len(saved.task_names)}"),
        ("status", run.status),
        ("train time", f"{sum(results.get('train_time_s') or []):.0f} s"),
    ]
    return ctx


def _wall_rows(wall: list[_Run], order: list[str], runs: list[_Run], tasks: list[str],
               errors: dict[str, list[str]]) -> list[dict[str, Any]]:
    """The wall's rows in the table's order; a row without a finished run says why."""
    by_label = {r.label: r for r in wall}
    rows = []
    for label in order:
        run = by_label.get(label)
        if run is not None:
            tiles = {t["name"]: t for t in run.tiles}
            rows.append({"label": label, "name": run.name, "page": run.page,
                         "cells": [tiles.get(name) for name in tasks], "missing": None})
            continue
        mine = [r for r in runs if r.label == label]
        why = "; ".join(errors.get(label) or [
            f"{r.name}: {r.status}" + (f" ({r.error})" if r.error else "") for r in mine
        ]) or "no run"
        rows.append({"label": label, "name": None, "page": mine[0].page if mine else None,
                     "cells": [], "missing": f"no finished run to show ({why})"})
    return rows


# ----------------------------------------------------------------------------- build
def _environment():
    import jinja2

    return jinja2.Environment(
        loader=jinja2.PackageLoader("clfd_bench.site", "templates"),
        autoescape=jinja2.select_autoescape(["html", "j2"], default_for_string=True,
                                            default=True),
        undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)


def _static(name: str) -> bytes:
    from importlib.resources import files

    return files("clfd_bench.site").joinpath("static", name).read_bytes()


def _remove_temp_files(out: Path) -> None:
    """Temporary files a killed build left (``.<name>.<random>.tmp*``; only while holding the
    site's lock)."""
    for tmp in out.rglob(".*.tmp*"):
        if tmp.is_file():
            tmp.unlink(missing_ok=True)


def build_site(results_dir: str | Path, out: str | Path, *, videos: bool = True,
               demo: int = 0, style: Mapping[str, Any] | None = None,
               workers: int = 1, log: Any = None) -> SiteResult:
    """Writes the static site of the results folder ``results_dir`` into ``out``.

    Args:
        results_dir: a leaderboard's output folder (``leaderboard.json``, ``runs/``).
        out: the site's folder (created; files of an earlier build are replaced, its videos
            reused).
        videos: render the video wall's tiles (off: the wall shows outcomes without videos).
        demo: the demo whose start every tile's execution starts from.
        style: ``{"width", "height", "fps"}`` of the tiles (default :data:`WALL_STYLE`).
        workers: processes rendering tiles.
        log: a callable taking one line of progress (default: none).

    Raises:
        InputError: ``results_dir`` is not a results folder (the message says what to run),
            or ``out`` is unusable.
        RunLockedError: another build writes into ``out``.
    """
    from clfd_bench.runs import exclusive

    results_dir, out = Path(results_dir), Path(out)
    from clfd_bench.harness.validate import InputError, check_out_dir
    from clfd_bench.leaderboard.report import read_leaderboard

    doc = read_leaderboard(results_dir)  # before anything is created
    check_out_dir(out)
    if out.resolve() == results_dir.resolve():
        raise InputError(f"--out {out} is the results folder itself; give the site a folder "
                         "of its own (e.g. RESULTS_DIR/site)")
    with exclusive(out, "clfd-bench site"):
        _remove_temp_files(out)
        return _build(results_dir, out, doc, videos=videos, demo=demo, style=style,
                      workers=workers, log=log)


def _build(results_dir: Path, out: Path, doc: dict[str, Any], *, videos: bool, demo: int,
           style: Mapping[str, Any] | None, workers: int, log: Any) -> SiteResult:
    """:func:`build_site` once the inputs are checked and the site's folder is held."""
    from clfd_bench.leaderboard.report import leaderboard_figures, paper_values
    from clfd_bench.node_variants import node_label
    from clfd_bench.progress import progress
    from clfd_bench.version import __version__

    start = time.perf_counter()
    say = log or (lambda line: None)
    style = {**WALL_STYLE, **(style or {})}
    meta = doc["meta"]
    runs = _load_runs(results_dir, doc)
    order = [str(r["method"]) for r in doc["rows"]]
    pages: dict[str, list[tuple[str, str]]] = {}
    for run in runs:
        pages.setdefault(run.label, []).append((run.name, run.page))

    # The video wall: the last learned model of each row's run, every task.
    wall = _wall_runs(runs, order)
    for run in wall:
        first = run.saved.execution(0)
        if first is not None and not 0 <= demo < len(first.success):
            from clfd_bench.harness.validate import InputError

            raise InputError(f"--demo {demo}: {run.name} has demos 0..{len(first.success) - 1}")

    # Figures and tables, copied so the site stands alone.
    figures = [_copy(p, out / "figures" / p.name) for p in leaderboard_figures(results_dir, doc)]
    downloads = []
    for name in ("leaderboard.md", "leaderboard.csv", "leaderboard.json"):
        if (results_dir / name).is_file():
            downloads.append(_copy(results_dir / name, out / "data" / name))
    for name in _STATIC:
        atomic_write_bytes(out / name, _static(name))

    jobs = [job for run in wall for job in _tile_jobs(out, run, demo, style)] if videos else []
    tile_results: dict[tuple[str, int], TileResult] = {}
    result = SiteResult(out / "index.html", [])
    if jobs:
        t_videos = time.perf_counter()
        missing = sum(existing_video(j.out_dir, j.task) is None for j in jobs)
        bar = progress(total=missing, desc="site videos", unit="video")

        def on_done(r: TileResult) -> None:
            bar.update(1)
            state = "ok" if r.video is not None else f"FAILED: {r.error}"
            run = "/".join(Path(r.job.run_dir).parts[-3:])
            say(f"[site] video {run} task {r.job.task}: {state} ({r.seconds:.1f} s)")

        try:
            done = render_tiles(jobs, workers=workers, on_done=on_done)
        finally:
            bar.close()
        for r in done:
            tile_results[(r.job.run_dir, r.job.task)] = r
            if r.reused:
                result.videos_reused += 1
            elif r.video is not None:
                result.videos_rendered += 1
        result.video_seconds = time.perf_counter() - t_videos
    tasks: list[str] = []
    for run in wall:
        run.tiles = []
        for j in range(run.saved.num_learned):
            rendered = tile_results.get((str(run.saved.path), j))
            tile = _tile(run, j, demo, rendered, out, videos)
            if rendered is not None and rendered.video is None:
                result.video_errors.append((run.name, tile["name"], tile["note"]))
            run.tiles.append(tile)
        for name in run.saved.task_names[: run.saved.num_learned]:
            if name not in tasks:
                tasks.append(name)

    env = _environment()
    common = {"version": __version__, "dataset": meta["dataset"],
              "built": datetime.datetime.now(datetime.timezone.utc).strftime(
                  "%Y-%m-%d %H:%M UTC")}
    for run in runs:
        ctx = _run_page(run, out)
        path = out / run.page
        atomic_write_text(path, env.get_template("run.html").render(
            **common, root="../", title=f"{run.label.upper()} · {run.name}", **ctx))
        result.pages.append(path)

    paper = paper_values(doc)
    grid = (f"methods {', '.join(meta['methods'])}; seeds {meta['seeds']}; orders "
            f"{meta['orders']}; {node_label(meta.get('node', 't'))}"
            + (f"; first {meta['tasks']} tasks" if meta.get("tasks") else "")
            + ("; with simulated execution" if meta.get("sim") else "; no simulation"))
    paper_doc = doc.get("paper") or {}
    notes = [paper_doc.get("note") or ""]
    if (paper_doc.get("executed") or {}).get("note"):
        notes.append(paper_doc["executed"]["note"])
    comparison = read_comparison(results_dir)
    profiles = None
    if comparison is not None:
        head, rows = comparison_table(comparison)
        profiles = {"caption": comparison_caption(comparison), "head": head, "rows": rows}
    index = env.get_template("index.html").render(
        **common, root="", title=f"clfd-bench leaderboard: {meta['dataset']} "
        f"({meta['profile']} profile)", profile=meta["profile"], grid=grid,
        table=_table(doc, paper, pages), paper_table=paper_doc.get("table"),
        paper_note=" ".join(n for n in notes if n),
        profiles=profiles, figures=[f.relative_to(out).as_posix() for f in figures],
        downloads=[d.relative_to(out).as_posix() for d in downloads],
        wall=_wall_rows(wall, order, runs, tasks,
                        {str(r["method"]): list(r.get("errors") or []) for r in doc["rows"]}),
        wall_tasks=tasks, wall_style=style, demo=demo, videos=videos,
        runs=[{"label": r.label, "name": r.name, "page": r.page, "status": r.status,
               "error": r.error} for r in runs])
    atomic_write_text(result.index, index)
    result.pages.insert(0, result.index)
    result.seconds = time.perf_counter() - start
    say(f"[site] {len(result.pages)} pages, {len(figures)} figures, "
        f"{result.videos_rendered} videos rendered ({result.video_seconds:.0f} s), "
        f"{result.videos_reused} reused, {len(result.video_errors)} without video: "
        f"{result.index}")
    return result
