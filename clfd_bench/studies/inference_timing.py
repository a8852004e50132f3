"""Inference timing of the hypernetwork methods (HN, CHN): the paper's appendix table.

The study (:func:`run_study`, ``clfd-bench study timing``) times every dataset part (LASA,
HelloWorld, RoboTasks positions, RoboTasks orientations) for each hypernetwork method on each
device, caches each measured cell in ``out/cells/`` with the machine it ran on, and writes the
comparison with the paper's table. What is timed and how:
:mod:`clfd_bench.studies.inference_timing_measure`; the tables and the figure:
:mod:`clfd_bench.studies.inference_timing_report`.
"""

from __future__ import annotations

import os
import platform
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

from clfd_bench.data.types import Task
from clfd_bench.harness.learner import Learner
from clfd_bench.io import atomic_write_json
from clfd_bench.runs import RunDir
from clfd_bench.studies.inference_timing_measure import (
    DATASETS,
    METHODS,
    apply_eval_overrides,
    build_learner,
    check_timing_dataset,
    check_timing_method,
    load_run,
    measure_part,
    timed_parts,
)
from clfd_bench.studies.inference_timing_report import summary, write_outputs

__all__ = [
    "StudyResult",
    "cell_path",
    "default_devices",
    "machine_info",
    "run_study",
]


def cell_path(out: str | os.PathLike[str], device: str, dataset: str, part: str,
              method: str) -> Path:
    """Where a measured cell is cached: ``out/cells/{device}_{dataset}_{part}_{method}.json``."""
    return Path(out) / "cells" / f"{device}_{dataset}_{part}_{method.lower()}.json"


# -- machine ------------------------------------------------------------------------------
def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def machine_info() -> dict[str, Any]:
    """CPU model, core counts, torch version and threads, GPU name, load average now."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else None
    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except OSError:  # pragma: no cover
        load = None
    return {
        "cpu": _cpu_model(),
        "logical_cpus": os.cpu_count(),
        "available_cores": cores,
        "torch": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "gpu": gpu,
        "load_average_1_5_15min": load,
    }


# -- the study ----------------------------------------------------------------------------
@dataclass
class StudyResult:
    """What :func:`run_study` measured and wrote."""

    cells: list[dict[str, Any]]
    rows: dict[str, list[dict[str, Any]]]
    files: list[Path]
    machine: dict[str, Any]
    measured: int
    cached: int

    def summary(self) -> str:
        return " ".join(summary(rows, d, self.machine) for d, rows in self.rows.items())


def default_devices() -> tuple[str, ...]:
    """``cpu``, plus ``cuda`` when a GPU is available."""
    return ("cpu", "cuda") if torch.cuda.is_available() else ("cpu",)


def _parts_of(dataset: str) -> tuple[str, ...]:
    return ("position", "orientation") if dataset == "robotasks" else ("position",)


def run_study(
    out: str | os.PathLike[str],
    *,
    methods: Sequence[str] = METHODS,
    datasets: Sequence[str] = DATASETS,
    runs: Sequence[str | os.PathLike[str]] = (),
    profile: str = "paper",
    overrides: Sequence[str] = (),
    repeats: int = 100,
    warmup: int = 5,
    threads: int = 1,
    devices: Sequence[str] | None = None,
    seed: int = 0,
    task: int = 0,
    force: bool = False,
    log: Callable[[str], None] | None = print,
) -> StudyResult:
    """Measure every cell (cached in ``out/cells/``; a cell measured with the same settings is
    reused unless ``force``) and write the tables and figures into ``out``.

    Args:
        methods, datasets: what to build at ``profile``'s sizes (ignored when ``runs`` given).
        runs: trained HN/CHN run directories to time instead of built models.
        overrides: ``[part.]key=value`` config overrides for built models (e.g.
            ``eval_solver=rk4``); for runs only the solver keys :data:`EVAL_KEYS`.
        threads: torch CPU threads while timing (restored afterwards).
        devices: ``cpu`` and/or ``cuda`` (default: :func:`default_devices`).
        task: the task whose embedding generates the NODE (and whose demo 0 starts it).
    """
    from clfd_bench.progress import progress

    for m in methods:
        check_timing_method(m)
    for d in datasets:
        check_timing_dataset(d)
    devices = tuple(devices or default_devices())
    for d in devices:
        if d not in ("cpu", "cuda"):
            raise ValueError(f"unknown device {d!r}; valid: cpu, cuda")
        if d == "cuda" and not torch.cuda.is_available():
            raise ValueError("device cuda requested but torch.cuda.is_available() is False")
    out = Path(out)
    previous_threads = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        machine = machine_info()
        base = {"repeats": repeats, "warmup": warmup, "threads": threads, "task": task,
                "torch": torch.__version__}
        if runs:
            jobs = [("run", str(Path(r)), "") for r in runs]
        else:
            jobs = [("built", m, d) for m in methods for d in datasets]
        cells: list[dict[str, Any]] = []
        measured = cached = 0
        bar = progress(total=len(jobs) * len(devices), desc="timing")
        for kind, a, b in jobs:
            if kind == "run":
                learner, tasks = load_run(a, threads)
                apply_eval_overrides(learner, overrides)
                method, dataset, source = learner.config.method, learner.config.dataset, a
                settings = {**base, "source": source, "overrides": list(overrides),
                            "checkpoint_sha256": RunDir(a).checkpoint_sha256()}
                loaded: tuple[Learner, list[Task]] | None = (learner, tasks)
            else:
                method, dataset, source = a, b, "built"
                settings = {**base, "source": source, "profile": profile,
                            "overrides": list(overrides), "seed": seed}
                loaded = None
            for device in devices:
                keys = [(p, cell_path(out, device, dataset, p, method)) for p in _parts_of(dataset)]
                todo = []
                for part, path in keys:
                    cell = _read_cell(path, settings) if not force else None
                    if cell is None:
                        todo.append(part)
                    else:
                        cells.append(cell)
                        cached += 1
                if todo:
                    if loaded is None:
                        loaded = build_learner(method, dataset, profile, overrides=overrides,
                                               seed=seed)
                    learner, tasks = loaded
                    for tp in timed_parts(learner, tasks, source=source, index=task):
                        if tp.kind not in todo:
                            continue
                        bar.set_postfix_str(f"{device} {tp.label} {method.upper()}")
                        cell = measure_part(tp, repeats=repeats, warmup=warmup, device=device)
                        cell["settings"] = settings
                        cell["load_average_after"] = machine_info()["load_average_1_5_15min"]
                        atomic_write_json(cell_path(out, device, dataset, tp.kind, method), cell)
                        cells.append(cell)
                        measured += 1
                        if log:
                            log(f"[timing] {device} {tp.label:16s} {method.upper():3s}: "
                                f"generate {cell['generate_ms']:.3f} ms, step "
                                f"{cell['step_ms']:.3f} ms, integrate "
                                f"{cell['integrate_ms']:.1f} ms ({cell['nfe']} evaluations)")
                bar.update(1)
        bar.close()
        study_settings = {"profile": profile if not runs else "from runs",
                          "repeats": repeats, "warmup": warmup, "threads": threads,
                          "task": task, "seed": seed, "overrides": list(overrides),
                          "source": "runs: " + ", ".join(map(str, runs)) if runs
                          else "built (untrained weights)"}
        rows, files = write_outputs(out, cells, machine, study_settings)
    finally:
        torch.set_num_threads(previous_threads)
    return StudyResult(cells, rows, files, machine, measured, cached)


def _read_cell(path: Path, settings: Mapping[str, Any]) -> dict[str, Any] | None:
    import json

    if not path.is_file():
        return None
    try:
        cell = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return cell if cell.get("settings") == dict(settings) else None
