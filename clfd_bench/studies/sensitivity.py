"""Sensitivity to the regularisation hyperparameters (paper, hyperparameter-sensitivity study).

The paper draws 5 configurations per method, independently and uniformly, from
SI ``c, xi in [0.1, 0.5]``, MAS ``c (lambda) in [0.1, 0.5]``, HN and CHN ``beta in [1e-3, 1e-2]``,
trains each on LASA with NODE^T, and reports per method the median and IQR (over its
configurations) of CL_score and CL_stability computed *without SSS* (none of these methods
stores data). Here:

* :func:`draw_configs` draws the configurations from a generator seeded by ``(seed, method)``
  (so adding a method or more configurations keeps the earlier draws), rounds each value to 4
  significant digits, and that rounded value is what is trained and recorded (in the run's
  name, ``..._beta=0.004235``, and in ``configs.json``);
* each configuration is a :class:`~clfd_bench.leaderboard.grid.RunSpec` with ``overrides``,
  run through :func:`~clfd_bench.leaderboard.runner.run_specs` (finished runs are skipped);
* :func:`config_scores` recomputes the criteria per run with FS across the compared methods
  (each method's median final size, as :func:`~clfd_bench.leaderboard.aggregate.aggregate`
  does) and CL_score / CL_stability over the criteria without SSS;
* :func:`summarize` gives median and IQR (q3 - q1) per method, next to the paper's
  (:func:`clfd_bench.metrics.paper_numbers.sensitivity`).
"""

from __future__ import annotations

import csv
import io
import math
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from clfd_bench.io import atomic_write_json, atomic_write_text, json_safe
from clfd_bench.leaderboard.aggregate import RunRecord, quartiles
from clfd_bench.leaderboard.grid import DEFAULT_OPTIONS, GridOptions, RunSpec
from clfd_bench.leaderboard.plots import _plt, _save
from clfd_bench.leaderboard.runner import run_specs
from clfd_bench.metrics.cl import CRITERIA, cl_score, cl_stability, final_model_size
from clfd_bench.node_variants import node_label

__all__ = [
    "ConfigDraw",
    "ConfigScore",
    "SensitivityResult",
    "config_scores",
    "default_ranges",
    "draw_configs",
    "format_value",
    "parse_range",
    "run_sensitivity_study",
    "sensitivity_figure",
    "sensitivity_specs",
    "summarize",
    "write_sensitivity_tables",
]

DROPPED: tuple[str, ...] = ("SSS",)
"""Criteria the paper leaves out of this study's CL_score / CL_stability."""

Ranges = dict[str, dict[str, tuple[float, float]]]
"""``{method: {config key: (low, high)}}`` (lower-case method names)."""


def default_ranges() -> Ranges:
    """The paper's ranges (``baselines/paper_results.toml``), keyed by lower-case method."""
    from clfd_bench.metrics.paper_numbers import sensitivity_ranges

    return {m.lower(): dict(r) for m, r in sensitivity_ranges().items()}


def parse_range(text: str) -> tuple[str | None, str, float, float]:
    """``"[method.]key=low,high"`` -> ``(method or None, key, low, high)``.

    Without a method the range applies to every studied method that samples ``key``.
    """
    if "=" not in text:
        raise ValueError(f"range {text!r} must look like key=low,high (e.g. beta=1e-3,1e-2)")
    key, bounds = (s.strip() for s in text.split("=", 1))
    method: str | None = None
    if "." in key:
        method, key = (s.strip() for s in key.split(".", 1))
        method = method.lower()
    try:
        low, high = (float(x) for x in bounds.split(","))
    except ValueError:
        raise ValueError(f"range {text!r}: expected two numbers low,high after '='") from None
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise ValueError(f"range {text!r}: need finite low < high, got {low}, {high}")
    return method, key, low, high


def apply_ranges(base: Ranges, methods: list[str], texts: list[str]) -> Ranges:
    """The ranges of ``methods``: ``base`` with the ``--range`` texts applied.

    Raises:
        ValueError: a method without any range, or a range that matches no studied method.
    """
    ranges = {m: dict(base.get(m, {})) for m in methods}
    for text in texts:
        method, key, low, high = parse_range(text)
        if method is not None:
            if method not in ranges:
                raise ValueError(f"range {text!r}: method {method!r} is not studied "
                                 f"(studied: {', '.join(methods)})")  # fmt: skip
            ranges[method][key] = (low, high)
            continue
        hits = [m for m in methods if key in ranges[m]]
        if not hits:
            keys = sorted({k for r in ranges.values() for k in r})
            raise ValueError(
                f"range {text!r}: no studied method samples {key!r} (sampled keys: "
                f"{', '.join(keys) or 'none'}); write method.{key}=low,high to add it to one"
            )
        for m in hits:
            ranges[m][key] = (low, high)
    missing = [m for m in methods if not ranges[m]]
    if missing:
        raise ValueError(
            f"no hyperparameter range for {', '.join(missing)}: the paper's study covers "
            f"{', '.join(base)}; give one with --range {missing[0]}.KEY=low,high"
        )
    return ranges


def format_value(value: float) -> str:
    """A drawn value as it is trained and recorded: 4 significant digits."""
    return f"{value:.4g}"


@dataclass(frozen=True)
class ConfigDraw:
    """One drawn configuration: ``values`` as ``(key, text)`` pairs (the ``--set`` values)."""

    method: str
    index: int
    values: tuple[tuple[str, str], ...]

    def value(self, key: str) -> float:
        """The drawn value of ``key`` as a number."""
        return float(dict(self.values)[key])


def draw_configs(methods: list[str], configs: int, seed: int, ranges: Ranges) -> list[ConfigDraw]:
    """Draw ``configs`` configurations per method, every key uniform in its range.

    The generator of a method is seeded with ``(seed, crc32(method))``: the draws of one
    method do not depend on which other methods are studied, and drawing more configurations
    keeps the first ones. Values are rounded by :func:`format_value`.
    """
    if configs < 1:
        raise ValueError(f"--configs must be >= 1, got {configs}")
    draws: list[ConfigDraw] = []
    for method in methods:
        if method not in ranges or not ranges[method]:
            raise ValueError(f"no hyperparameter range for method {method!r}")
        rng = np.random.default_rng([seed, zlib.crc32(method.encode())])
        for index in range(configs):
            values = tuple(
                (key, format_value(float(rng.uniform(low, high))))
                for key, (low, high) in ranges[method].items()
            )
            draws.append(ConfigDraw(method, index, values))
    return draws


def sensitivity_specs(
    draws: list[ConfigDraw],
    dataset: str,
    profile: str,
    seed: int,
    options: GridOptions = DEFAULT_OPTIONS,
) -> list[RunSpec]:
    """One :class:`RunSpec` per drawn configuration (its values as ``overrides``), with the
    node, tasks and simulation of ``options``."""
    return [
        RunSpec(dataset, d.method, profile, seed, 0, options.node, options.tasks, options.sim,
                overrides=d.values)
        for d in draws
    ]


def plan_sensitivity(
    dataset: str,
    methods: list[str],
    configs: int,
    seed: int,
    profile: str,
    ranges: Ranges | None = None,
    options: GridOptions = DEFAULT_OPTIONS,
) -> tuple[Ranges, list[ConfigDraw], list[RunSpec]]:
    """The study's ranges, draws and runs, each run's configuration checked before any
    training (``ValueError`` / ``ConfigError`` for a bad range or a key a method lacks).

    Args:
        ranges: ``{method: {key: (low, high)}}``; default the paper's (:func:`default_ranges`).
    """
    ranges = apply_ranges(default_ranges(), methods, []) if ranges is None else ranges
    draws = draw_configs(methods, configs, seed, ranges)
    specs = sensitivity_specs(draws, dataset, profile, seed, options)
    for spec in specs:
        spec.config()
    return ranges, draws, specs


# ------------------------------------------------------------------------------ scores
@dataclass
class ConfigScore:
    """The criteria of one configuration's run and its CL_score / CL_stability without SSS.

    ``criteria`` holds ACC, REM, MS, TE, FS (NaN where missing); the scores are NaN unless
    every one of them is there. ``exec_acc``: ACC of simulated execution (NaN without).
    """

    method: str
    name: str
    status: str
    values: dict[str, float]
    criteria: dict[str, float] = field(default_factory=dict)
    cl_score: float = math.nan
    cl_stability: float = math.nan
    exec_acc: float = math.nan


def config_scores(
    records: list[RunRecord], methods: list[str], drop: tuple[str, ...] = DROPPED
) -> list[ConfigScore]:
    """Per run: the CL criteria without ``drop``, FS across ``methods``, and the two scores.

    FS uses each method's median final model size over its finished runs, against the
    largest of them (as the leaderboard does); it is left out (scores NaN) unless every
    method has a finished run.

    Args:
        records: runs of the study (``spec.overrides`` hold the drawn values).
        methods: the compared methods.
        drop: criteria not counted (the paper's study drops SSS).
    """
    kept = tuple(c for c in CRITERIA if c not in drop)
    sizes: dict[str, float] = {}
    for method in methods:
        vals = [float(r.results["num_params"][-1]) for r in records
                if r.spec.method == method and r.status == "done" and r.results
                and r.results.get("num_params")]  # fmt: skip
        if vals:
            sizes[method] = float(np.median(vals))
    out: list[ConfigScore] = []
    for record in records:
        values = {k: float(v) for k, v in record.spec.overrides}
        score = ConfigScore(record.spec.method, record.spec.name, record.status, values)
        out.append(score)
        if record.status != "done" or not record.results:
            continue
        cl = dict(record.results.get("cl_metrics", {}))
        if sizes and len(sizes) == len(methods):
            cl["FS"] = final_model_size(sizes, record.spec.method)
        score.criteria = {
            k: float(cl[k]) if cl.get(k) is not None else math.nan for k in kept
        }
        exec_acc = (record.results.get("sim_cl_metrics") or {}).get("ACC")
        score.exec_acc = math.nan if exec_acc is None else float(exec_acc)
        if all(math.isfinite(v) for v in score.criteria.values()):
            score.cl_score = cl_score(score.criteria)
            score.cl_stability = cl_stability(score.criteria)
    return out


def summarize(scores: list[ConfigScore], methods: list[str]) -> dict[str, dict[str, Any]]:
    """Per method: ``n``, and for CL_score / CL_stability ``_q1``, ``_median``, ``_q3``,
    ``_iqr`` (q3 - q1) over its configurations, next to the paper's ``paper_*_median`` /
    ``paper_*_iqr`` and the differences ``diff_*_median`` (ours - paper; NaN without a paper
    number)."""
    from clfd_bench.metrics.paper_numbers import sensitivity

    paper = sensitivity()
    out: dict[str, dict[str, Any]] = {}
    for method in methods:
        mine = [s for s in scores if s.method == method]
        entry: dict[str, Any] = {
            "n": sum(1 for s in mine if math.isfinite(s.cl_score)),
            "runs": len(mine),
        }
        ref = paper.get(method.upper(), {})
        for key, attr in (("CL_score", "cl_score"), ("CL_stability", "cl_stability")):
            q1, med, q3 = quartiles([getattr(s, attr) for s in mine])
            entry.update({f"{key}_q1": q1, f"{key}_median": med, f"{key}_q3": q3,
                          f"{key}_iqr": q3 - q1})  # fmt: skip
            p_med = ref.get(f"{key}_median", math.nan)
            entry[f"paper_{key}_median"] = p_med
            entry[f"paper_{key}_iqr"] = ref.get(f"{key}_iqr", math.nan)
            entry[f"diff_{key}_median"] = med - p_med
        out[method] = entry
    return out


# ------------------------------------------------------------------------------ output
def _f(value: float, digits: int = 4) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def _markdown(summary: dict, scores: list[ConfigScore], meta: dict[str, Any]) -> str:
    ranges = "; ".join(
        f"{m.upper()}: " + ", ".join(f"{k} in [{lo:g}, {hi:g}]" for k, (lo, hi) in r.items())
        for m, r in meta["ranges"].items()
    )
    lines = [
        "# Sensitivity to the regularisation hyperparameters",
        "",
        f"Dataset {meta['dataset']}, {node_label(meta['node'])}, profile {meta['profile']}, "
        f"seed {meta['seed']}, {meta['configs']} configurations per method drawn uniformly "
        f"({ranges})" + (f"; first {meta['tasks']} tasks" if meta.get("tasks") else "") + ".",
        "CL_score / CL_stability over ACC, REM, MS, TE, FS (no SSS, as in the paper; FS across "
        "the methods studied here). Median and IQR (q3 - q1) over each method's "
        "configurations; paper: its table tab:lasa_hyperparam_study (full LASA, 26 tasks, "
        "paper profile); diff = ours - paper.",
        "",
        "| method | configs | CL_score median | IQR | paper | paper IQR | diff | "
        "CL_stab median | IQR | paper | paper IQR | diff |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for method, e in summary.items():
        cells = [method.upper(), f"{e['n']}/{e['runs']}"]
        for key in ("CL_score", "CL_stability"):
            cells += [_f(e[f"{key}_median"]), _f(e[f"{key}_iqr"]), _f(e[f"paper_{key}_median"]),
                      _f(e[f"paper_{key}_iqr"]), _f(e[f"diff_{key}_median"])]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    kept = [c for c in CRITERIA if c not in DROPPED]
    lines += ["", "## Configurations", "",
              "| method | values | " + " | ".join(kept)
              + " | CL_score | CL_stab | exec ACC | run |",
              "|---|---|" + "---|" * (len(kept) + 4)]  # fmt: skip
    for s in scores:
        vals = ", ".join(f"{k}={format_value(v)}" for k, v in s.values.items())
        crit = [_f(s.criteria.get(k, math.nan), 2) for k in kept]
        status = "" if s.status == "done" else f" ({s.status})"
        lines.append(f"| {s.method.upper()} | {vals} | " + " | ".join(crit)
                     + f" | {_f(s.cl_score)} | {_f(s.cl_stability)} | {_f(s.exec_acc, 2)} | "
                     f"`{s.name}`{status} |")
    if meta.get("figure"):
        lines += ["", f"![sensitivity]({Path(meta['figure']).name})"]
    return "\n".join(lines) + "\n"


def write_sensitivity_tables(
    summary: dict, scores: list[ConfigScore], out: Path, meta: dict[str, Any]
) -> list[Path]:
    """Write ``sensitivity.md``, ``.csv`` (one row per method) and ``.json``; return paths."""
    out.mkdir(parents=True, exist_ok=True)
    md, cs, js = out / "sensitivity.md", out / "sensitivity.csv", out / "sensitivity.json"
    atomic_write_text(md, _markdown(summary, scores, meta))
    buffer = io.StringIO()
    writer = csv.writer(buffer)
    keys = sorted({k for e in summary.values() for k in e if k not in ("n", "runs")})
    writer.writerow(["method", "n", "runs", *keys])
    for method, e in summary.items():
        writer.writerow([method, e["n"], e["runs"],
                         *("" if not math.isfinite(e[k]) else e[k] for k in keys)])  # fmt: skip
    atomic_write_text(cs, buffer.getvalue())
    payload = {
        "schema_version": 1,
        "meta": json_safe(meta),
        "summary": json_safe(summary),
        "configs": [
            json_safe({"method": s.method, "run": s.name, "status": s.status, "values": s.values,
                   "criteria": s.criteria, "CL_score": s.cl_score,
                   "CL_stability": s.cl_stability, "exec_ACC": s.exec_acc})
            for s in scores
        ],  # fmt: skip
    }
    atomic_write_json(js, payload)
    return [md, cs, js]


def sensitivity_figure(scores: list[ConfigScore], summary: dict, ranges: Ranges, title: str):
    """One panel per method: each configuration's CL_score (circles) and CL_stability
    (squares) over the value of its (first) hyperparameter; the paper's medians as dashed
    lines; other sampled keys (SI's xi) written next to the points."""
    plt = _plt()
    methods = list(summary)
    fig, axes = plt.subplots(1, len(methods), figsize=(3.4 * len(methods) + 0.4, 3.6),
                             squeeze=False, sharey=True, layout="constrained")  # fmt: skip
    for ax, method in zip(axes[0], methods, strict=True):
        keys = list(ranges[method])
        key = keys[0]
        mine = [s for s in scores if s.method == method and math.isfinite(s.cl_score)]
        xs = [s.values.get(key, math.nan) for s in mine]
        ax.scatter(xs, [s.cl_score for s in mine], marker="o", color="C0", label="CL_score")
        ax.scatter(xs, [s.cl_stability for s in mine], marker="s", color="C1",
                   label="CL_stability")  # fmt: skip
        # Other sampled keys (SI's xi): their values next to the CL_score points, staggered
        # vertically (in order of x) so that neighbouring labels do not overlap.
        ranked = sorted(range(len(mine)), key=lambda i: xs[i])
        for place, i in enumerate(ranked):
            extra = ", ".join(format_value(mine[i].values[k]) for k in keys[1:]
                              if k in mine[i].values)
            if extra:
                ax.annotate(extra, (xs[i], mine[i].cl_score), fontsize=6,
                            xytext=(4, (4, -10, 14)[place % 3]), textcoords="offset points")
        e = summary[method]
        for k, color in (("CL_score", "C0"), ("CL_stability", "C1")):
            if math.isfinite(e[f"paper_{k}_median"]):
                ax.axhline(e[f"paper_{k}_median"], color=color, ls="--", lw=1,
                           label=f"paper median {k}")  # fmt: skip
        low, high = ranges[method][key]
        ax.set_xlim(low - 0.05 * (high - low), high + 0.05 * (high - low))
        ax.set_xlabel(key + (f" (numbers: {', '.join(keys[1:])})" if keys[1:] else ""))
        ax.set_title(method.upper())
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("score without SSS (1 best)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=4, fontsize=8)
    fig.suptitle(title)
    return fig


# ------------------------------------------------------------------------------ study
@dataclass
class SensitivityResult:
    """What :func:`run_sensitivity_study` did and wrote."""

    draws: list[ConfigDraw]
    specs: list[RunSpec]
    trained: list[RunSpec]
    skipped: list[RunSpec]
    failed: list[Any]
    scores: list[ConfigScore]
    summary: dict[str, dict[str, Any]]
    files: list[Path]
    seconds: float

    def text(self) -> str:
        """One paragraph: what ran and how the methods compare with the paper."""
        per = "; ".join(
            f"{m.upper()} CL_score {_f(e['CL_score_median'], 3)} (IQR "
            f"{_f(e['CL_score_iqr'], 3)}, paper {_f(e['paper_CL_score_median'], 3)}), "
            f"CL_stability {_f(e['CL_stability_median'], 3)} (IQR "
            f"{_f(e['CL_stability_iqr'], 3)}, paper {_f(e['paper_CL_stability_median'], 3)})"
            for m, e in self.summary.items()
        )
        order = sorted(
            (m for m, e in self.summary.items() if math.isfinite(e["CL_score_median"])),
            key=lambda m: -self.summary[m]["CL_score_median"],
        )
        return (
            f"Sensitivity study: {len(self.specs)} runs ({len(self.trained)} trained now, "
            f"{len(self.skipped)} already done, {len(self.failed)} failed) in "
            f"{self.seconds:.0f} s. Median over configurations without SSS: {per}. Ranking by "
            f"median CL_score: {' > '.join(m.upper() for m in order) or 'none'} (paper: HN > "
            "CHN > MAS > SI)."
        )


def run_sensitivity_study(
    dataset: str,
    methods: list[str],
    configs: int,
    seed: int,
    profile: str,
    out: Path,
    ranges: Ranges | None = None,
    options: GridOptions = DEFAULT_OPTIONS,
) -> SensitivityResult:
    """Draw the configurations, run (or resume) their runs, then write tables and figure.

    Writes into ``out``: ``configs.json`` (the draw: seed, ranges, values, run names),
    ``runs/...``, ``sensitivity.md``, ``.csv``, ``.json`` and ``sensitivity.png``.

    Args:
        ranges: ``{method: {key: (low, high)}}``; default the paper's
            (:func:`default_ranges`).
        seed: seeds both the draw and every training run.
        options: the runs' node, tasks and simulation, and where they run
            (:class:`~clfd_bench.leaderboard.grid.GridOptions`).
    """
    ranges, draws, specs = plan_sensitivity(dataset, methods, configs, seed, profile, ranges,
                                            options)
    start = time.perf_counter()
    out = Path(out)
    atomic_write_json(out / "configs.json", {
        "seed": seed, "dataset": dataset, "profile": profile, "node": options.node,
        "tasks": options.tasks,
        "ranges": {m: {k: list(v) for k, v in r.items()} for m, r in ranges.items()},
        "draws": [{"method": d.method, "index": d.index, "values": dict(d.values),
                   "run": s.name} for d, s in zip(draws, specs, strict=True)],
    })  # fmt: skip
    grid = run_specs(specs, out, options, desc="sensitivity study")
    scores = config_scores(grid.records, methods)
    summary = summarize(scores, methods)
    title = (f"{dataset}: sensitivity to the regularisation hyperparameter ({profile}"
             + (f", {options.tasks} tasks" if options.tasks else "") + ")")  # fmt: skip
    fig = sensitivity_figure(scores, summary, ranges, title)
    figure = _save(fig, out / "sensitivity.png")
    _plt().close(fig)
    meta = {
        "dataset": dataset, "methods": methods, "configs": configs, "seed": seed,
        "profile": profile, "node": options.node, "tasks": options.tasks, "sim": options.sim,
        "executor": options.executor,
        "ranges": {m: {k: list(v) for k, v in r.items()} for m, r in ranges.items()},
        "dropped_criteria": list(DROPPED), "figure": str(figure),
    }  # fmt: skip
    files = write_sensitivity_tables(summary, scores, out, meta) + [figure]
    return SensitivityResult(draws, specs, grid.trained, grid.skipped, grid.failed, scores,
                             summary, files, time.perf_counter() - start)  # fmt: skip
