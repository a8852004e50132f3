"""The paper's own numbers, for printing next to ours.

The values live in ``baselines/paper_results.toml``, extracted from the paper's LaTeX source
(each table names its label there) and printed exactly as the paper rounds them. Methods are
upper-case (``SG``, ``FT``, ``REP``, ``SI``, ``MAS``, ``HN``, ``CHN``), as in the paper.
"""

from __future__ import annotations

import functools
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from clfd_bench.metrics.cl import CRITERIA
from clfd_bench.resources import resource_path

__all__ = [
    "CL_COLUMNS",
    "DATASET_LABELS",
    "INFERENCE_COLUMNS",
    "SENSITIVITY_COLUMNS",
    "cl_table",
    "cl_table_label",
    "cl_tables",
    "inference",
    "load",
    "sensitivity",
    "sensitivity_ranges",
    "train_times",
]

DATASET_LABELS = {"lasa": "LASA", "helloworld": "HelloWorld", "robotasks": "RoboTasks"}
"""How the paper names the datasets it has tables for."""
CL_COLUMNS = (*CRITERIA, "CL_score", "CL_stability")
"""The columns of the paper's CL tables: the criteria (:data:`clfd_bench.metrics.cl.CRITERIA`)
and the two scores over them."""
INFERENCE_COLUMNS = (
    "generate_ms", "generate_hz", "step_ms", "step_hz", "integrate_ms", "integrate_hz",
)  # fmt: skip
SENSITIVITY_COLUMNS = (
    "CL_score_median", "CL_score_iqr", "CL_stability_median", "CL_stability_iqr",
)  # fmt: skip


@functools.cache
def load() -> dict[str, Any]:
    """The whole data file as a dict (cached)."""
    path = resource_path("baselines", "paper_results.toml")
    with open(path, "rb") as f:
        return tomllib.load(f)


def _rows(table: dict[str, Any], columns: tuple[str, ...], where: str) -> dict[str, dict]:
    if tuple(table["columns"]) != columns:
        raise ValueError(f"{where}: columns {table['columns']} are not {list(columns)}")
    out = {}
    for key, values in table.items():
        if key in ("label", "columns", "ranges"):
            continue
        if len(values) != len(columns):
            raise ValueError(f"{where}.{key}: {len(values)} values for {len(columns)} columns")
        out[key] = {c: float(v) for c, v in zip(columns, values, strict=True)}
    return out


def cl_tables() -> list[tuple[str, str]]:
    """The ``(dataset, variant)`` pairs the paper has a CL-metrics table for."""
    return [(d, v) for d, variants in load()["cl"].items() for v in variants]


def cl_table(dataset: str, variant: str) -> dict[str, dict[str, float]]:
    """A CL-metrics table: ``{method: {column: value}}`` (columns :data:`CL_COLUMNS`).

    Args:
        dataset: ``lasa``, ``helloworld`` or ``robotasks``.
        variant: ``t`` / ``i`` (NODE^T / NODE^I; LASA and HelloWorld) or ``position`` /
            ``orientation`` (RoboTasks, NODE^T).
    """
    tables = load()["cl"]
    if (dataset, variant) not in cl_tables():
        valid = ", ".join(f"{d}/{v}" for d, v in cl_tables())
        raise KeyError(f"the paper has no CL table {dataset}/{variant}; it has: {valid}")
    return _rows(tables[dataset][variant], CL_COLUMNS, f"cl.{dataset}.{variant}")


def cl_table_label(dataset: str, variant: str) -> str:
    """The LaTeX label of a CL-metrics table (e.g. ``tab:hw_cl_explicit_time``)."""
    cl_table(dataset, variant)  # an unknown table fails here, listing the valid ones
    return str(load()["cl"][dataset][variant]["label"])


def train_times(table: str) -> dict[str, list]:
    """A wall-clock training-time table (seconds, GPU machine): ``{"tasks": [...], method: [...]}``.

    Args:
        table: ``lasa``, ``helloworld``, ``robotasks_position`` or ``robotasks_orientation``.
    """
    tables = load()["train_time"]
    if table not in tables:
        raise KeyError(f"no training-time table {table!r}; valid: {', '.join(tables)}")
    return {k: list(v) for k, v in tables[table].items() if k != "label"}


def inference(device: str) -> dict[tuple[str, str], dict[str, float]]:
    """The inference-speed table: ``{(dataset_label, method): {column: value}}``.

    Args:
        device: ``cpu`` or ``gpu``. Dataset labels: ``LASA``, ``HelloWorld``,
            ``RoboTasks (pos)``, ``RoboTasks (ori)``; columns :data:`INFERENCE_COLUMNS`.
    """
    tables = load()["inference"]
    if device not in tables:
        raise KeyError(f"no inference table for {device!r}; valid: {', '.join(tables)}")
    table = tables[device]
    if tuple(table["columns"]) != INFERENCE_COLUMNS:
        raise ValueError(f"inference.{device}: unexpected columns {table['columns']}")
    return {
        (row[0], row[1]): {c: float(v) for c, v in zip(INFERENCE_COLUMNS, row[2:], strict=True)}
        for row in table["rows"]
    }


def sensitivity() -> dict[str, dict[str, float]]:
    """The LASA hyperparameter-sensitivity table: ``{method: {column: value}}``."""
    return _rows(load()["sensitivity"]["lasa"], SENSITIVITY_COLUMNS, "sensitivity.lasa")


def sensitivity_ranges() -> dict[str, dict[str, tuple[float, float]]]:
    """The paper's sampling ranges: ``{method: {config key: (low, high)}}``."""
    ranges = load()["sensitivity"]["lasa"]["ranges"]
    return {m: {k: (float(lo), float(hi)) for k, (lo, hi) in r.items()} for m, r in ranges.items()}
