"""One dataset's leaderboards at two or more profiles, side by side: is ``fast`` faithful?

Issue 38 asks whether the execution ranking is a property of the methods or of the reduced
``fast`` models: per method, trajectory ACC/REM and execution ACC/REM at each profile (e.g.
``fast`` and ``full``, the paper's model sizes), the runs behind them and their training CPU
time, and whether ``fast``'s exec ACC is within :data:`EXEC_TOLERANCE` of the reference
profile's. The inputs are leaderboard folders (``leaderboard.json``, read by
:func:`clfd_bench.leaderboard.report.read_leaderboard`); nothing is trained or executed here.

    clfd-bench paper profiles fast=results/helloworld full=results/full/helloworld --out DIR
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from clfd_bench.harness.validate import InputError
from clfd_bench.io import atomic_write_json, atomic_write_text
from clfd_bench.leaderboard.report import read_leaderboard

__all__ = ["EXEC_TOLERANCE", "KEYS", "ProfileComparison", "caption", "compare_profiles",
           "markdown", "read_comparison", "table", "write_comparison"]

#: |exec ACC(fast) - exec ACC(reference)| a faithful profile stays within (issue 38).
EXEC_TOLERANCE = 0.05
#: leaderboard metrics compared, with their column headers.
KEYS: tuple[tuple[str, str], ...] = (
    ("ACC", "ACC"), ("REM", "REM"), ("exec_ACC", "exec ACC"), ("exec_REM", "exec REM"),
    ("train_cpu_s", "train CPU s"),
)


@dataclasses.dataclass(frozen=True)
class ProfileComparison:
    """Leaderboards of one dataset at several profiles.

    Attributes:
        dataset: the dataset every leaderboard is about.
        profiles: profile labels in the order given (the last is the reference).
        methods: every method of any leaderboard, in first-seen order.
        values: ``{profile: {method: {key: [per-run values]}}}`` for :data:`KEYS`.
        runs: ``{profile: {method: finished runs}}``.
        seeds: ``{profile: [seeds]}`` of each leaderboard's grid.
        sources: ``{profile: folder}``.
    """

    dataset: str
    profiles: tuple[str, ...]
    methods: tuple[str, ...]
    values: dict[str, dict[str, dict[str, list[float]]]]
    runs: dict[str, dict[str, int]]
    seeds: dict[str, list[int]]
    sources: dict[str, str]

    def median(self, profile: str, method: str, key: str) -> float:
        """Median over the runs (nan when there is none)."""
        vals = self.values.get(profile, {}).get(method, {}).get(key) or []
        return float(statistics.median(vals)) if vals else math.nan

    def exec_gap(self, method: str, profile: str, reference: str | None = None) -> float:
        """Median exec ACC at ``profile`` minus that at ``reference`` (default: the last
        profile); nan when either is missing."""
        reference = reference or self.profiles[-1]
        return self.median(profile, method, "exec_ACC") - self.median(reference, method,
                                                                      "exec_ACC")

    def to_json(self) -> dict[str, Any]:
        gaps = {p: {m: _finite(self.exec_gap(m, p)) for m in self.methods}
                for p in self.profiles[:-1]}
        return {"dataset": self.dataset, "profiles": list(self.profiles),
                "methods": list(self.methods), "values": self.values, "runs": self.runs,
                "seeds": self.seeds, "sources": self.sources, "exec_gap": gaps,
                "exec_tolerance": EXEC_TOLERANCE}


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def compare_profiles(folders: Mapping[str, str | Path]) -> ProfileComparison:
    """Reads the leaderboard of each ``{profile label: folder}`` (at least two, one dataset).

    Raises:
        InputError: fewer than two folders, a folder that is not a leaderboard, or
            leaderboards of different datasets.
    """
    if len(folders) < 2:
        raise InputError("give at least two leaderboard folders, e.g. fast=results/helloworld "
                         "full=results/full/helloworld")
    values: dict[str, dict[str, dict[str, list[float]]]] = {}
    runs: dict[str, dict[str, int]] = {}
    seeds: dict[str, list[int]] = {}
    datasets: dict[str, str] = {}
    methods: list[str] = []
    for label, folder in folders.items():
        doc = read_leaderboard(folder)
        meta = doc["meta"]
        datasets[label] = str(meta.get("dataset"))
        seeds[label] = [int(s) for s in meta.get("seeds") or []]
        values[label], runs[label] = {}, {}
        for row in doc["rows"]:
            method = str(row["method"])
            if method not in methods:
                methods.append(method)
            runs[label][method] = int(row.get("runs_ok", 0))
            metrics = row.get("metrics") or {}
            values[label][method] = {
                key: [float(v) for v in (metrics.get(key) or {}).get("values") or []]
                for key, _ in KEYS}
    if len(set(datasets.values())) != 1:
        shown = ", ".join(f"{k}: {v}" for k, v in datasets.items())
        raise InputError(f"the leaderboards are of different datasets ({shown}); compare one "
                         "dataset's leaderboards")
    return ProfileComparison(
        dataset=next(iter(datasets.values())), profiles=tuple(folders), methods=tuple(methods),
        values=values, runs=runs, seeds=seeds,
        sources={k: str(Path(v)) for k, v in folders.items()})


def _cell(cmp: ProfileComparison, profile: str, method: str, key: str) -> str:
    vals = cmp.values.get(profile, {}).get(method, {}).get(key) or []
    if not vals:
        return "—"
    fmt = "{:.0f}" if key == "train_cpu_s" else "{:.2f}"
    med = fmt.format(statistics.median(vals))
    if len(vals) > 1:
        med += f" [{fmt.format(min(vals))}–{fmt.format(max(vals))}]"
    return med


def table(cmp: ProfileComparison) -> tuple[list[str], list[list[str]]]:
    """The comparison's header and rows of cells: a row per method, each key of :data:`KEYS`
    at every profile, the runs, then each non-reference profile's exec ACC gap to the
    reference (marked ✗ beyond :data:`EXEC_TOLERANCE`)."""
    ref = cmp.profiles[-1]
    head = ["method"] + [f"{h} {p}" for _, h in KEYS for p in cmp.profiles] \
        + [f"runs {p}" for p in cmp.profiles] \
        + [f"exec ACC {p} − {ref}" for p in cmp.profiles[:-1]]
    rows = []
    for method in cmp.methods:
        cells = [method.upper()]
        cells += [_cell(cmp, p, method, key) for key, _ in KEYS for p in cmp.profiles]
        cells += [str(cmp.runs.get(p, {}).get(method, 0)) for p in cmp.profiles]
        for p in cmp.profiles[:-1]:
            gap = cmp.exec_gap(method, p)
            cells.append("—" if not math.isfinite(gap) else
                         f"{gap:+.2f}" + (" ✗" if abs(gap) > EXEC_TOLERANCE else ""))
        rows.append(cells)
    return head, rows


def caption(cmp: ProfileComparison) -> str:
    """What the cells are, the seeds and sources, and the tolerance rule."""
    return ("Cells: median [min–max] over finished runs (seeds "
            + "; ".join(f"{p}: {cmp.seeds[p]}" for p in cmp.profiles)
            + f"). Sources: {', '.join(f'{p} {s}' for p, s in cmp.sources.items())}. A gap "
            f"over {EXEC_TOLERANCE} is marked ✗ (issue 38: fast must stay within it of "
            f"{cmp.profiles[-1]}, or say why). train CPU s: CPU seconds of one run's training.")


def markdown(cmp: ProfileComparison) -> str:
    """The comparison as a markdown table (:func:`table`) under a title and :func:`caption`."""
    head, rows = table(cmp)
    lines = [f"# {cmp.dataset}: profiles {', '.join(cmp.profiles)}", "", caption(cmp), "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(cells) + " |" for cells in rows]
    return "\n".join(lines) + "\n"


def write_comparison(cmp: ProfileComparison, out: str | Path,
                     stem: str = "profile_comparison") -> Sequence[Path]:
    """Writes ``<stem>.md`` and ``<stem>.json`` into ``out`` (atomically); returns the paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    md, js = out / f"{stem}.md", out / f"{stem}.json"
    atomic_write_text(md, markdown(cmp))
    atomic_write_json(js, cmp.to_json())
    return md, js


def read_comparison(folder: str | Path, stem: str = "profile_comparison"
                    ) -> ProfileComparison | None:
    """The comparison :func:`write_comparison` wrote into ``folder``; None when there is none.

    Raises:
        InputError: the file is there but not a comparison this version can read.
    """
    import json

    path = Path(folder) / f"{stem}.json"
    if not path.is_file():
        return None
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
        return ProfileComparison(
            dataset=str(d["dataset"]), profiles=tuple(d["profiles"]),
            methods=tuple(d["methods"]), values=d["values"], runs=d["runs"],
            seeds=d["seeds"], sources=d["sources"])
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{path} is not a profile comparison ({exc!r}); write it again with "
                         "`clfd-bench paper profiles ... --out FOLDER`") from None
