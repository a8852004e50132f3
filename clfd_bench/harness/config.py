"""Run configuration: frozen dataclasses loaded from ``baselines/<method>.toml``.

A baselines file holds, per profile (``paper``, ``fast``, ``smoke``), a ``defaults`` table
and one table per dataset; pose datasets (RoboTasks) have ``position`` and ``orientation``
sub-tables for their two models. Values resolve as

    profile.defaults  <-  profile.<dataset>  <-  profile.<dataset>.<part>  <-  --set overrides

``robotasks9`` uses the ``robotasks`` tables unless it has its own. Every key must be a field
of :class:`PartConfig` that the method uses; anything else (a typo, ``beta`` for SG) raises
with the valid names. The resolved :class:`RunConfig` is saved with every run.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from clfd_bench.learning.part_config import COMMON_KEYS, PART_FIELDS, ConfigError, PartConfig
from clfd_bench.resources import resource_path

__all__ = [
    "ConfigError",
    "PROFILES",
    "PartConfig",
    "RunConfig",
    "load_profile_table",
    "parse_override",
    "resolve_config",
]

PROFILES = ("paper", "fast", "smoke")
DATASET_TABLES = ("lasa", "helloworld", "robotasks", "robotasks9")
POSE_DATASETS = ("robotasks", "robotasks9")
PARTS_POSE = ("position", "orientation")
_DOC_KEYS = ("notes",)


@dataclass(frozen=True)
class RunConfig:
    """Everything that determines a run's results (saved as ``config`` in results.json).

    Attributes:
        method: registered CL method name. dataset: dataset name. profile: baselines profile.
        order: task order (0, 1, 2). seed: random seed. node: ``t`` (NODE^T) or ``i``.
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
        if self.node not in ("t", "i"):
            raise ConfigError(f"node must be 't' (NODE^T) or 'i' (NODE^I), got {self.node!r}")
        if self.tasks is not None and self.tasks < 1:
            raise ConfigError(f"tasks must be >= 1, got {self.tasks}")

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


def _suggest(key: str, valid: Sequence[str]) -> str:
    close = difflib.get_close_matches(key, list(valid), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _coerce(name: str, value: Any, where: str) -> Any:
    f = PART_FIELDS[name]
    default = f.default
    ftype = str(f.type)
    if "tuple" in ftype:
        if not isinstance(value, list | tuple) or not all(
            isinstance(v, int) and not isinstance(v, bool) for v in value
        ):
            raise ConfigError(f"{where}: {name} must be a list of integers, got {value!r}")
        return tuple(value)
    if ftype.startswith("bool"):
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: {name} must be true or false, got {value!r}")
        return value
    if ftype.startswith("int"):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: {name} must be an integer, got {value!r}")
        return value
    if ftype.startswith("float"):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{where}: {name} must be a number, got {value!r}")
        return float(value)
    if ftype.startswith("str"):
        if not isinstance(value, str):
            raise ConfigError(f"{where}: {name} must be a string, got {value!r}")
        return value
    raise AssertionError(f"unhandled field type {ftype} (default {default!r})")  # pragma: no cover


def _build_part(values: dict[str, Any], where: str) -> PartConfig:
    for key in values:
        if key not in PART_FIELDS:
            raise ConfigError(
                f"{where}: unknown key {key!r}{_suggest(key, list(PART_FIELDS))}; "
                f"valid keys: {', '.join(PART_FIELDS)}"
            )
    coerced = {k: _coerce(k, v, where) for k, v in values.items() if v is not None}
    missing = [
        f.name for f in fields(PartConfig)
        if f.default is dataclasses.MISSING and f.name not in coerced
    ]
    if missing:
        raise ConfigError(f"{where}: missing required key(s) {missing}")
    return PartConfig(**coerced)


def baselines_file(method: str) -> Path:
    """``baselines/<method>.toml``."""
    return resource_path("baselines", f"{method}.toml")


def load_profile_table(method: str, profile: str) -> dict[str, Any]:
    """The raw ``[profile]`` table of ``baselines/<method>.toml`` (validated structure)."""
    path = baselines_file(method)
    if not path.is_file():
        raise ConfigError(f"no baselines file for method {method!r}: {path} does not exist")
    with path.open("rb") as fh:
        doc = tomllib.load(fh)
    top_valid = {"method", "description", *PROFILES}
    for key in doc:
        if key not in top_valid:
            raise ConfigError(
                f"{path}: unknown top-level key {key!r}{_suggest(key, sorted(top_valid))}; "
                f"valid: {', '.join(sorted(top_valid))}"
            )
    if doc.get("method") != method:
        raise ConfigError(f"{path}: 'method' must be {method!r}, got {doc.get('method')!r}")
    if profile not in PROFILES:
        raise ConfigError(f"unknown profile {profile!r}{_suggest(profile, PROFILES)}; "
                          f"valid: {', '.join(PROFILES)}")
    if profile not in doc:
        raise ConfigError(f"{path} has no [{profile}] profile; it has: "
                          f"{', '.join(p for p in PROFILES if p in doc)}")
    table = doc[profile]
    valid = {"defaults", *DATASET_TABLES, *_DOC_KEYS}
    for key in table:
        if key not in valid:
            raise ConfigError(
                f"{path} [{profile}]: unknown table {key!r}{_suggest(key, sorted(valid))}; "
                f"valid: {', '.join(sorted(valid))}"
            )
    return table


def parse_override(text: str) -> tuple[str | None, str, Any]:
    """``"[part.]key=value"`` -> ``(part or None, key, value)``; the value is TOML
    (``lr=3e-3``, ``node_hidden=[64,64]``, ``solver="rk4"``; bare words are strings)."""
    if "=" not in text:
        raise ConfigError(f"override {text!r} must look like key=value (e.g. lr=1e-3)")
    key, raw = (s.strip() for s in text.split("=", 1))
    part: str | None = None
    if "." in key:
        part, key = key.split(".", 1)
        if part not in PARTS_POSE:
            raise ConfigError(f"override {text!r}: part must be one of {', '.join(PARTS_POSE)}")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    if key not in PART_FIELDS:
        raise ConfigError(
            f"override {text!r}: unknown key {key!r}{_suggest(key, list(PART_FIELDS))}; "
            f"valid keys: {', '.join(PART_FIELDS)}"
        )
    return part, key, value


def resolve_config(
    method: str,
    dataset: str,
    profile: str,
    *,
    seed: int = 0,
    order: int = 0,
    node: str = "t",
    tasks: int | None = None,
    overrides: Sequence[str] = (),
    method_keys: frozenset[str] | None = None,
) -> RunConfig:
    """Resolve the configuration of one run from the baselines file and overrides.

    Args:
        method_keys: the method-specific keys the method accepts (default: looked up in the
            method registry). Keys outside ``COMMON_KEYS | method_keys`` raise.

    Raises:
        ConfigError: for unknown keys, wrong types, a missing dataset table or bad values.
    """
    if method_keys is None:
        from clfd_bench.methods import get_method_class

        method_keys = get_method_class(method).hyperparameters
    allowed = COMMON_KEYS | method_keys
    if dataset not in DATASET_TABLES:
        raise ConfigError(f"unknown dataset {dataset!r}{_suggest(dataset, DATASET_TABLES)}; "
                          f"valid: {', '.join(DATASET_TABLES)}")
    table = load_profile_table(method, profile)
    source = dataset if dataset in table or dataset not in POSE_DATASETS else "robotasks"
    if source not in table:
        notes = table.get("notes", "")
        raise ConfigError(
            f"baselines/{method}.toml [{profile}] has no settings for dataset {dataset!r}"
            f"{'; ' + notes if notes else ''}; datasets with settings: "
            f"{', '.join(d for d in DATASET_TABLES if d in table)}"
        )
    is_pose = dataset in POSE_DATASETS
    parts = PARTS_POSE if is_pose else ("position",)
    parsed = [parse_override(o) for o in overrides]
    resolved: list[tuple[str, PartConfig]] = []
    for part in parts:
        where = f"baselines/{method}.toml [{profile}.{source}{'.' + part if is_pose else ''}]"
        merged: dict[str, Any] = {}
        layers = [table.get("defaults", {}), table[source]]
        if is_pose:
            layers.append(table[source].get(part, {}))
        for layer in layers:
            for key, value in layer.items():
                if key in PARTS_POSE and isinstance(value, dict):
                    if not is_pose:
                        raise ConfigError(f"{where}: [{key}] tables only exist for pose data")
                    continue
                if key in _DOC_KEYS:
                    continue
                merged[key] = value
        if is_pose:
            for key in table[source]:
                if isinstance(table[source][key], dict) and key not in PARTS_POSE:
                    raise ConfigError(f"{where}: unknown sub-table {key!r}; valid: "
                                      f"{', '.join(PARTS_POSE)}")
        for o_part, key, value in parsed:
            if o_part is None or o_part == part:
                merged[key] = value
        for key in merged:
            if key in PART_FIELDS and key not in allowed:
                raise ConfigError(
                    f"{where}: {key!r} is not a hyperparameter of method {method!r} "
                    f"(its own keys: {', '.join(sorted(method_keys)) or 'none'})"
                )
        resolved.append((part, _build_part(merged, where).resolved()))
    return RunConfig(
        method=method, dataset=dataset, profile=profile, order=order, seed=seed, node=node,
        tasks=tasks, parts=tuple(resolved), overrides=tuple(overrides),
    )
