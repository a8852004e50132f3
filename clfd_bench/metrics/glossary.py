"""The glossary: one line for every metric and column clfd-bench shows.

This is the single source of these definitions. The README's "Glossary" section is generated
from it (``python eval/make_readme_glossary.py``; ``--check`` says whether the README is up
to date, and ``tests/test_glossary.py`` fails when it is not), and the results site
(:mod:`clfd_bench.site`) shows each definition as the tooltip of its column header.

Every definition states what the code computes (:mod:`clfd_bench.metrics.cl`,
:mod:`clfd_bench.metrics.trajectory`, :mod:`clfd_bench.metrics.orientation`,
:mod:`clfd_bench.metrics.thresholds`, :mod:`clfd_bench.leaderboard.aggregate`,
:mod:`clfd_bench.execution.execute`). Formulas are between backticks in Markdown;
:func:`plain` drops the backticks for a tooltip.
"""

from __future__ import annotations

from dataclasses import dataclass

from clfd_bench.metrics.cl import CRITERIA

__all__ = ["BEGIN", "END", "GLOSSARY", "SECTIONS", "Term", "markdown", "plain",
           "replace_readme_block", "readme_block", "tooltip"]


@dataclass(frozen=True)
class Term:
    """One glossary line.

    Attributes:
        key: the name the code uses (a key of ``leaderboard.json``'s row metrics, a failure
            kind, an error metric, ...); unique across the glossary.
        name: the name as a table or figure shows it.
        definition: one sentence or two, Markdown (formulas in backticks).
        better: which way a value is better, for a column of numbers that ranks something:
            ``"higher"`` or ``"lower"``; None when neither is (a count of runs, a figure).
            The results site sorts a column best-first on the first click and marks its best
            value with it.
    """

    key: str
    name: str
    definition: str
    better: str | None = None

    def __post_init__(self) -> None:
        if self.better not in (None, "higher", "lower"):
            raise ValueError(f"glossary term {self.key!r}: better must be 'higher', 'lower' "
                             f"or None, got {self.better!r}")


_CRITERIA = f"{', '.join(CRITERIA[:-1])} and {CRITERIA[-1]}"

SECTIONS: tuple[tuple[str, str, tuple[Term, ...]], ...] = (
    (
        "Continual-learning notation",
        "As in the paper (Auddy et al. 2023, after Díaz-Rodríguez et al. 2018). ACC, REM, MS, "
        "TE, FS, SSS, CL_score and CL_stability lie in [0, 1], 1 best.",
        (
            Term("M", "M", "the number of tasks, learned one after another as tasks 0 … M−1."),
            Term("R", "R",
                 "the accuracy matrix: `R[i, j]` (`j ≤ i`) is the fraction of task j's demos "
                 "whose prediction after learning task i, started at the demo's start, has an "
                 "error at most the threshold (a run's page shows one R per thresholded error, "
                 "and one from execution)."),
        ),
    ),
    (
        "Leaderboard columns",
        "`leaderboard.md`, `.csv` and `.json`, and the results site's table.",
        (
            Term("rank", "#",
                 "rank by median CL_score, best first; rows without a CL_score come after "
                 "those with one, ordered by median ACC; rows without a finished run last.",
                 better="lower"),
            Term("paper_rank", "paper #",
                 "the method's rank by CL_score in the paper's CL table for the same dataset, "
                 "NODE variant and methods (equal printed CL_scores share a rank); shown only "
                 "when such a table exists.",
                 better="lower"),
            Term("paper_cl_score", "paper CL_score",
                 "the CL_score the paper's matching table prints for the method "
                 "(`leaderboard.md`; on the site, the grey number under each cell is the "
                 "paper's value for that column)."),
            Term("method", "method",
                 "the continual-learning method, or named entry (e.g. `hn-snode`), of the "
                 "row."),
            Term("runs", "runs",
                 "the row's finished runs (one per seed and task order); \"(+k failed)\" counts "
                 "the runs that failed."),
            Term("cell", "cell",
                 "the median over the row's finished runs; `leaderboard.md` adds `[q1, q3]`, "
                 "the interquartile range, when the runs differ (on the site: hover the cell); "
                 "\"-\": no value; \"—\": not provided by the run (predictions scored "
                 "elsewhere without model size, training time or stored samples), never "
                 "estimated."),
            Term("CL_score", "CL_score",
                 f"the mean of {_CRITERIA} (the paper writes a sum; its tables print the "
                 "mean).",
                 better="higher"),
            Term("CL_stability", "CL_stab",
                 f"CL_stability: 1 − the sample standard deviation (ddof 1) of {_CRITERIA}.",
                 better="higher"),
            Term("ACC", "ACC",
                 "accuracy: the mean of `R[i, j]` over all `i ≥ j` (trajectory R: DTW at most "
                 "the threshold).",
                 better="higher"),
            Term("REM", "REM", "remembering: `1 − |min(BWT, 0)|`.",
                 better="higher"),
            Term("BWT", "BWT",
                 "backward transfer: the mean over `i > j` of `R[i, j] − R[j, j]`, in [−1, 1]; "
                 "negative means forgetting; empty with one task; not part of CL_score.",
                 better="higher"),
            Term("MS", "MS",
                 "model size efficiency: `min(1, (1/M) Σ_i Mem(θ_0) / Mem(θ_i))`, "
                 "`Mem(θ_i)` the number of parameters kept, after learning task i, to "
                 "reproduce every task learned so far.",
                 better="higher"),
            Term("TE", "TE",
                 "time efficiency: `min(1, T_0 / M · Σ_i 1 / T_i)`, `T_i` the wall-clock "
                 "seconds spent learning task i.",
                 better="higher"),
            Term("FS", "FS",
                 "final model size: `1 − Mem(θ_{M−1}) / Mem_max`, `Mem_max` the largest final "
                 "parameter count among the leaderboard's methods (each method's final count is "
                 "the median over its runs).",
                 better="higher"),
            Term("SSS", "SSS",
                 "sample storage size efficiency: `1 − min(1, (1/M) Σ_i stored_i / total)`, "
                 "`stored_i` the demonstration samples kept after learning task i, "
                 "`total` the training samples of all M tasks.",
                 better="higher"),
            Term("exec_ACC", "exec ACC",
                 "ACC of the execution R: `R[i, j]` is the fraction of task j's demos whose "
                 "prediction after task i, executed on the simulated Panda from the demo's "
                 "start, meets the task's success criterion.",
                 better="higher"),
            Term("exec_REM", "exec REM", "REM of the execution R: `1 − |min(exec BWT, 0)|`.",
                 better="higher"),
            Term("exec_BWT", "exec BWT",
                 "BWT of the execution R: the mean over `i > j` of `R[i, j] − R[j, j]`.",
                 better="higher"),
            Term("exec_CL_score", "exec CL_score",
                 "CL_score with exec ACC and exec REM in place of ACC and REM (MS, TE, FS and "
                 "SSS unchanged).",
                 better="higher"),
            Term("train_time_s", "train s",
                 "wall-clock seconds of training, summed over the run's tasks (runs trained "
                 "together in lockstep: each its share, the batch's time over its runs).",
                 better="lower"),
            Term("train_cpu_s", "train CPU s",
                 "CPU seconds of the training process, summed over the run's tasks (when every "
                 "task recorded them; in lockstep, each run's share).",
                 better="lower"),
            Term("final_params", "params",
                 "the parameter count after the last task (RoboTasks: of the position model).",
                 better="lower"),
            Term("exec_failures", "exec failures",
                 "the executions of the method's runs that failed, counted by kind (reflex, "
                 "tracking, unreachable, collision, blowup, diverged, task: see the failure "
                 "kinds); an execution counts its first failure. Below them, the success "
                 "checks behind the task failures, each with how often it failed (an execution "
                 "that fails two counts for both).",
                 better="lower"),
        ),
    ),
    (
        "Trajectory errors",
        "Between a prediction and its demo, in the data's units (LASA's own units; metres for "
        "HelloWorld and RoboTasks positions); in `results.json` under `errors`.",
        (
            Term("dtw", "DTW",
                 "dynamic time warping distance: the sum of the Euclidean distances between "
                 "matched points along the best warping path (steps (1, 0), (0, 1), (1, 1), "
                 "first points to last points); not normalised, so it grows with the "
                 "trajectory's length.",
                 better="lower"),
            Term("frechet", "Fréchet",
                 "discrete Fréchet distance: the smallest, over monotone couplings of the two "
                 "point sequences, of the largest Euclidean distance between coupled points.",
                 better="lower"),
            Term("swept_area", "swept area",
                 "the sum over `t` of the area of the quadrilateral `(pred[t], pred[t+1], "
                 "demo[t+1], demo[t])`, in squared length units.",
                 better="lower"),
            Term("quaternion", "quaternion error (E_q)",
                 "`E_q = 1/(3T) · Σ_t ‖2 Log(q_t ∗ conj(q̂_t))‖₁`: the mean absolute component "
                 "of the rotation vector from the predicted to the demo's orientation, in "
                 "degrees (RoboTasks, RoboTasks9).",
                 better="lower"),
            Term("threshold", "threshold",
                 "a prediction is accurate when its error is at most this: DTW 2191 (LASA "
                 "units), 1821 cm (HelloWorld), 7131 cm (RoboTasks; RoboTasks9 uses the same) "
                 "and E_q 10° from the paper; LASA's Fréchet 5.0 and swept area 70.0 from the "
                 "authors' released code."),
        ),
    ),
    (
        "Execution failure kinds",
        "Why an execution on the simulated Panda failed (the `exec failures` column).",
        (
            Term("reflex", "reflex",
                 "a commanded joint reference outside the joint ranges, or a velocity, "
                 "acceleration or jerk of the command over libfranka's limits: the real Panda "
                 "would stop."),
            Term("unreachable", "unreachable",
                 "a target pose beyond the robot's reach or below the floor."),
            Term("tracking", "tracking",
                 "the hand's pose error to the command over the tracking bound."),
            Term("collision", "collision",
                 "a robot link, hand or finger pushing a non-robot object harder than the "
                 "collision bound."),
            Term("blowup", "blowup",
                 "the physics simulation blew up (MuJoCo's bad qpos/qvel/qacc warnings or a "
                 "non-finite state)."),
            Term("diverged", "diverged", "the prediction holds NaN or inf; it is not executed."),
            Term("task", "task",
                 "the task's success criterion was not met, at the end or as soon as the env "
                 "decided it ([docs/execution.md](docs/execution.md) has every criterion)."),
        ),
    ),
    (
        "Figures",
        "Written by every leaderboard next to its tables.",
        (
            Term("error_vs_task", "error_vs_task.png",
                 "after learning task i (x axis), the DTW of every task seen so far over all "
                 "runs of a method: median line and IQR band, log scale, the threshold "
                 "dashed."),
            Term("error_boxes", "error_boxes.png",
                 "box plots of every DTW after the last task, per method, log scale, the "
                 "threshold dashed."),
            Term("cl_radar", "cl_radar.png",
                 f"the medians of {_CRITERIA}, one polygon per method."),
            Term("success_vs_task", "success_vs_task.png",
                 "after learning task i (x axis), the fraction of successful executions over "
                 "every demo of the tasks seen so far: median line and IQR band over a "
                 "method's runs."),
        ),
    ),
)
"""``(title, one-line introduction, terms)`` per section, in the README's order."""

GLOSSARY: dict[str, Term] = {term.key: term for _, _, terms in SECTIONS for term in terms}
"""Every term by its key."""

if len(GLOSSARY) != sum(len(terms) for _, _, terms in SECTIONS):  # pragma: no cover
    raise RuntimeError("clfd_bench.metrics.glossary: two terms share a key")

BEGIN = "<!-- glossary: generated from clfd_bench/metrics/glossary.py by " \
    "eval/make_readme_glossary.py; do not edit by hand -->"
"""The line before the README's generated glossary."""
END = "<!-- glossary: end -->"
"""The line after it."""


def plain(text: str) -> str:
    """``text`` without Markdown: backticks dropped, ``[label](link)`` reduced to ``label``."""
    import re

    return re.sub(r"\[([^\]]+)\]\([^)]+\)", r"\1", text).replace("`", "")


def tooltip(key: str) -> str:
    """The plain-text definition of ``key`` as a column header's tooltip: "name: definition".

    Raises:
        KeyError: ``key`` has no glossary entry (the message names the file to add it to).
    """
    try:
        term = GLOSSARY[key]
    except KeyError:
        raise KeyError(f"{key!r} has no entry in clfd_bench/metrics/glossary.py") from None
    return f"{plain(term.name)}: {plain(term.definition)}"


def markdown() -> str:
    """The README's glossary (between :data:`BEGIN` and :data:`END`, both excluded)."""
    lines: list[str] = []
    for title, intro, terms in SECTIONS:
        lines += [f"### {title}", "", intro, ""]
        lines += [f"- **{term.name}**: {term.definition}" for term in terms]
        lines.append("")
    return "\n".join(lines)


def readme_block(readme: str) -> str:
    """The generated part of a README's text (between the markers).

    Raises:
        ValueError: the markers are missing or out of order.
    """
    start, end = readme.find(BEGIN), readme.find(END)
    if start < 0 or end < start:
        raise ValueError("README.md has no generated glossary: add the lines\n"
                         f"{BEGIN}\n{END}\nwhere it goes, then run "
                         "python eval/make_readme_glossary.py")
    return readme[start + len(BEGIN):end].strip("\n") + "\n"


def replace_readme_block(readme: str) -> str:
    """``readme`` with its generated glossary replaced by :func:`markdown`."""
    readme_block(readme)  # the markers are there
    start, end = readme.find(BEGIN) + len(BEGIN), readme.find(END)
    return readme[:start] + "\n" + markdown() + readme[end:]
