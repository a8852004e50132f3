"""What determines a run: :class:`RunConfig` (saved as ``config`` in every results.json) and
its run-level values (``method``, ``dataset``, ``profile``, ``order``, ``seed``, ``node``,
``tasks``), each with its type and valid range in :data:`RUN_RULES` (``order`` and ``tasks``
bounded by the dataset: :func:`run_rules`, :func:`check_run_values`).

The hyperparameters of its models are :class:`~clfd_bench.learning.part_config.PartConfig`;
resolving a config from ``baselines/<method>.toml`` and ``--set`` overrides is
:func:`clfd_bench.harness.config.resolve_config`. :func:`suggest` is the "did you mean" every
config message uses.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

from clfd_bench.learning.part_config import (
    PART_FIELDS,
    PART_RULES,
    ConfigError,
    PartConfig,
    Rule,
)
from clfd_bench.node_variants import NODE_VARIANTS
from clfd_bench.profiles import PROFILE_NAMES

__all__ = [
    "DATASET_TABLES",
    "PARTS_POSE",
    "POSE_DATASETS",
    "PROFILES",
    "RUN_RULES",
    "RunConfig",
    "check_run_values",
    "run_rules",
    "suggest",
]

PROFILES = PROFILE_NAMES
"""The profiles a baselines file may hold (:mod:`clfd_bench.profiles`)."""
DATASET_TABLES = ("lasa", "helloworld", "robotasks", "robotasks9")
POSE_DATASETS = ("robotasks", "robotasks9")
PARTS_POSE = ("position", "orientation")


@dataclass(frozen=True)
class RunConfig:
    """Everything that determines a run's results (saved as ``config`` in results.json).

    Attributes:
        method: registered CL method name. dataset: dataset name. profile: baselines profile.
        order: task order (0, 1, 2). seed: random seed. node: ``t`` (NODE^T), ``i``
            (NODE^I) or ``s`` (sNODE), :data:`~clfd_bench.node_variants.NODE_VARIANTS`.
        tasks: number of tasks learned (the first ``tasks`` of the order).
        parts: ``(("position", cfg),)`` or, for poses, position and orientation configs.
        overrides: the ``--set`` overrides that were applied (for the record).
    """

    method: str
    dataset: str
    profile: str
    order: int
    seed: int
    node: str
    tasks: int | None
    parts: tuple[tuple[str, PartConfig], ...]
    overrides: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        for key, rule in RUN_RULES.items():  # dataset-dependent bounds: resolve_config
            _, problem = rule.check(key, getattr(self, key))
            if problem:
                raise ConfigError(problem)

    def part(self, name: str) -> PartConfig:
        """The config of part ``name``."""
        for n, cfg in self.parts:
            if n == name:
                return cfg
        raise KeyError(f"no part {name!r}; parts: {[n for n, _ in self.parts]}")

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "method": self.method,
            "dataset": self.dataset,
            "profile": self.profile,
            "order": self.order,
            "seed": self.seed,
            "node": self.node,
            "tasks": self.tasks,
            "parts": {name: cfg.to_dict() for name, cfg in self.parts},
            "overrides": list(self.overrides),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> RunConfig:
        """Inverse of :meth:`to_dict`."""
        parts = tuple(
            (name, _build_part(dict(values), f"saved config part {name!r}"))
            for name, values in d["parts"].items()
        )
        return cls(
            method=d["method"], dataset=d["dataset"], profile=d["profile"], order=d["order"],
            seed=d["seed"], node=d["node"], tasks=d["tasks"], parts=parts,
            overrides=tuple(d.get("overrides", ())),
        )


def suggest(key: str, valid: Sequence[str]) -> str:
    """`` (did you mean 'x'?)`` for the valid name closest to ``key``, or ``""``."""
    close = difflib.get_close_matches(key, list(valid), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _build_part(values: dict[str, Any], where: str) -> PartConfig:
    """A :class:`PartConfig` from plain values (a saved config), every value checked."""
    coerced: dict[str, Any] = {}
    extras = values.pop("extras", None) or {}
    if not isinstance(extras, Mapping):
        raise ConfigError(f"{where}: extras must be a table of a method's own "
                          f"hyperparameters, got {extras!r}")
    coerced["extras"] = {k: tuple(v) if isinstance(v, list) else v for k, v in extras.items()}
    for key, value in values.items():
        if key not in PART_FIELDS:
            raise ConfigError(
                f"{where}: unknown key {key!r}{suggest(key, list(PART_FIELDS))}; "
                f"valid keys: {', '.join(PART_FIELDS)}"
            )
        if value is None:
            continue
        coerced[key], wrong_type = PART_RULES[key].coerce(value)
        if wrong_type:
            raise ConfigError(f"{where}: {key} must be {wrong_type}, got {value!r}")
    missing = [
        f.name for f in fields(PartConfig)
        if f.default is dataclasses.MISSING and f.name not in coerced
    ]
    if missing:
        raise ConfigError(f"{where}: missing required key(s) {missing}")
    try:
        return PartConfig(**coerced)  # checks the ranges
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None


# ------------------------------------------------------------------- run-level values
RUN_RULES: dict[str, Rule] = {
    "method": Rule("str", what="a registered CL method"),
    "dataset": Rule("str", choices=DATASET_TABLES),
    "profile": Rule("str", choices=PROFILES),
    "order": Rule("int", lo=0, what="task order; below the dataset's number of orders"),
    "seed": Rule("int", lo=0, hi=2**32 - 1, what="random seed"),
    "node": Rule("str", choices=tuple(NODE_VARIANTS),
                 what=", ".join(f"{k}: {v}" for k, v in NODE_VARIANTS.items())),
    "tasks": Rule("int", lo=1, optional=True, what="at most the dataset's number of tasks"),
}
"""The type and valid range of every scalar :class:`RunConfig` field (``parts`` are checked
by :data:`PART_RULES`); ``order`` and ``tasks`` are also bounded by the dataset
(:func:`run_rules`), ``method`` by the method registry."""


def run_rules(dataset: str, order: int | None = None) -> dict[str, Rule]:
    """:data:`RUN_RULES` with the bounds of ``dataset`` filled in: ``order`` below its number
    of orders and, given a valid ``order``, ``tasks`` at most its number of tasks."""
    from clfd_bench.data import DATASETS
    from clfd_bench.methods import list_methods

    rules = dict(RUN_RULES)
    rules["method"] = dataclasses.replace(rules["method"], choices=tuple(list_methods()))
    info = DATASETS.get(dataset)
    if info is None:
        return rules
    rules["order"] = dataclasses.replace(
        rules["order"], hi=info.num_orders - 1,
        what=f"{dataset} has {info.num_orders} task order{'s' if info.num_orders > 1 else ''}")
    if isinstance(order, int) and not isinstance(order, bool) and 0 <= order < info.num_orders:
        n = len(info.task_names()[order])
        rules["tasks"] = dataclasses.replace(
            rules["tasks"], hi=n, what=f"{dataset} has {n} tasks")
    return rules


def check_run_values(
    values: Mapping[str, Any], dataset: str, arg_names: Mapping[str, str] | None = None
) -> None:
    """Check run-level values (``order``, ``seed``, ``node``, ``tasks``, ...) of a run on
    ``dataset`` against :func:`run_rules`.

    Args:
        arg_names: the option each value came from, for the message (default ``--<name>``).

    Raises:
        ConfigError: one line naming the option, the value and the valid range.
    """
    names = {key: f"--{key}" for key in RUN_RULES} | dict(arg_names or {})
    # the task count is only looked up for a --tasks to check (robotasks9 reads a file)
    rules = run_rules(dataset, values.get("order") if values.get("tasks") is not None else None)
    for key, value in values.items():
        _, problem = rules[key].check(key, value)
        if problem:
            raise ConfigError(f"{names[key]} {value}: {problem}")
