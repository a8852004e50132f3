"""Model sizes of a profile against the paper's: FS (final model size) per method and table.

FS compares the final model sizes of the methods of one table (``1 - size / largest``), so it
is decided by the profile's architecture alone, before anything is trained. This module builds
every method's model for a dataset and profile, adds all the dataset's tasks (embeddings,
SG's per-task NODEs, penalty state), counts what each keeps (``Method.num_params``, as runs
record it) and puts the FS it gives next to the paper's, per paper table (RoboTasks: the
position and the orientation model separately, as the paper's tables).

    clfd-bench paper sizes --profile fast               # every dataset
    clfd-bench paper sizes --datasets helloworld --profile paper
"""

from __future__ import annotations

from dataclasses import dataclass

from clfd_bench.metrics import paper_numbers
from clfd_bench.metrics.cl import final_model_size
from clfd_bench.studies.paper_grid import paper_methods

__all__ = ["SizeRow", "size_table"]


@dataclass(frozen=True)
class SizeRow:
    """One method of one paper table.

    Attributes:
        dataset, table: the paper table (``table``: ``t`` for LASA/HelloWorld NODE^T,
            ``position``/``orientation`` for RoboTasks).
        method: lower-case method name.
        params: the method's final model size (numbers kept after the last task).
        fs: FS this size gives among the table's methods.
        paper_fs: the paper's FS for the method in that table (None if it has none).
    """

    dataset: str
    table: str
    method: str
    params: int
    fs: float
    paper_fs: float | None

    @property
    def diff(self) -> float | None:
        """``fs - paper_fs`` (None without a paper value)."""
        return None if self.paper_fs is None else self.fs - self.paper_fs


def _final_sizes(dataset: str, profile: str, methods: tuple[str, ...], node: str
                 ) -> dict[str, dict[str, int]]:
    """``{part: {method: params after the last task}}`` (parts: ``position`` for 2-D data,
    ``position``/``orientation`` for poses)."""
    import torch

    from clfd_bench.data import load_dataset
    from clfd_bench.harness.config import resolve_config
    from clfd_bench.harness.learner import Learner

    ds = load_dataset(dataset)
    sizes: dict[str, dict[str, int]] = {}
    for method in methods:
        config = resolve_config(method, dataset, profile, node=node)
        torch.manual_seed(0)
        learner = Learner.from_config(config, ds[0].dim)
        for part_name, part in learner.parts.items():
            for _ in ds.task_names:
                part.method.add_task()
            sizes.setdefault(part_name, {})[method] = int(part.method.num_params())
    return sizes


def size_table(dataset: str, profile: str, methods: tuple[str, ...] | None = None,
               node: str = "t") -> list[SizeRow]:
    """Final model size and FS of every method of the paper's table(s) for ``dataset``.

    Args:
        dataset: ``lasa``, ``helloworld`` or ``robotasks``.
        profile: ``paper``, ``fast`` or ``smoke``.
        methods: default the paper's methods for the dataset (RoboTasks: no SI/MAS).
        node: ``t`` or ``i`` (LASA/HelloWorld; the sizes differ by one input only).

    Returns:
        One row per (table, method), in the order of ``methods``.
    """
    methods = tuple(methods) if methods else paper_methods(dataset)
    rows: list[SizeRow] = []
    for part, sizes in _final_sizes(dataset, profile, methods, node).items():
        table = part if dataset.startswith("robotasks") else node
        paper = (paper_numbers.cl_table(dataset, table)
                 if (dataset, table) in paper_numbers.cl_tables() else {})
        for method in methods:
            ref = paper.get(method.upper(), {}).get("FS")
            rows.append(SizeRow(dataset, table, method, sizes[method],
                                final_model_size(sizes, method), ref))
    return rows
