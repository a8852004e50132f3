"""Resolving a run's configuration (:func:`resolve_config`): the layers of
``baselines/<method>.toml`` and ``--set`` overrides merged into a checked
:class:`~clfd_bench.harness.run_config.RunConfig`, every bad value named with where it came
from. The files are found and read by :mod:`clfd_bench.harness.baselines`; the dataclass and
its run-level rules are :mod:`clfd_bench.harness.run_config`.

A baselines file holds, per profile (``paper``, ``full``, ``fast``, ``smoke``), a
``defaults`` table and one table per dataset; pose datasets (RoboTasks) have ``position`` and
``orientation`` sub-tables for their two models. Runs of the stable NODE (``--node s``) also read
``baselines/snode.toml`` (its ``[profile]`` table, shared by every method) and the method's
optional ``[profile.snode]`` table. Values resolve as

    profile.defaults  <-  profile.<dataset>  <-  profile.<dataset>.<part>
        <-  baselines/snode.toml [profile]  <-  profile.snode  <-  profile.snode.<part>
            <-  profile.snode.<dataset>  <-  profile.snode.<dataset>.<part>
            (the last five: --node s only; <part> is position or orientation on every
            dataset, e.g. profile.snode.position also sets LASA's model, while
            profile.snode.robotasks.position sets RoboTasks' position model alone)
        <-  --set overrides

``robotasks9`` uses the ``robotasks`` tables unless it has its own. Every key must be a field
of :class:`PartConfig` that the method uses; anything else (a typo, ``beta`` for SG) raises
with the valid names. The resolved :class:`~clfd_bench.harness.run_config.RunConfig` is saved
with every run.

Every value is checked once resolved, before any work: its type and range are declared in one
table per dataclass (:data:`~clfd_bench.learning.part_config.PART_RULES` next to
:class:`PartConfig`, :data:`~clfd_bench.harness.run_config.RUN_RULES` next to
:class:`~clfd_bench.harness.run_config.RunConfig`; ``order`` and ``tasks`` bounded by the
dataset), rules between values in
:data:`~clfd_bench.learning.part_config.PART_CONSTRAINTS`. A bad value raises
:class:`ConfigError` with one line naming the key, the value, where it came from
(``--set key=value``, ``baselines/<method>.toml line N [profile.table]``, the default, or the
command-line option), the valid range and the fix.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from clfd_bench.harness.baselines import (
    DOC_KEYS,
    SNODE_FILE,
    SNODE_TABLE,
    TableSource,
    profile_table,
    snode_profile_table,
    table_source,
)
from clfd_bench.harness.run_config import (
    DATASET_TABLES,
    PARTS_POSE,
    POSE_DATASETS,
    PROFILES,
    RunConfig,
    check_run_values,
    suggest,
)
from clfd_bench.learning.part_config import (
    COMMON_KEYS,
    PART_CONSTRAINTS,
    PART_FIELDS,
    PART_RULES,
    SNODE_KEYS,
    ConfigError,
    PartConfig,
    Rule,
)

__all__ = [
    "ConfigError",
    "PART_RULES",
    "PartConfig",
    "parse_override",
    "resolve_config",
]

def parse_override(text: str, own_keys: Sequence[str] = ()) -> tuple[str | None, str, Any]:
    """``"[part.]key=value"`` -> ``(part or None, key, value)``; the value is TOML
    (``lr=3e-3``, ``node_hidden=[64,64]``, ``solver="rk4"``; bare words are strings).
    ``own_keys``: the method's own hyperparameters, valid besides the config keys."""
    if "=" not in text:
        raise ConfigError(f"--set {text}: an override must look like key=value (e.g. lr=1e-3)")
    key, raw = (s.strip() for s in text.split("=", 1))
    part: str | None = None
    if "." in key:
        part, key = key.split(".", 1)
        if part not in PARTS_POSE:
            raise ConfigError(f"--set {text}: part must be one of {', '.join(PARTS_POSE)} "
                              "(e.g. --set orientation.lr=1e-3)")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    if key not in PART_FIELDS and key not in own_keys:
        known = [*PART_FIELDS, *own_keys]
        raise ConfigError(
            f"--set {text}: unknown key {key!r}{suggest(key, known)}; "
            f"valid keys: {', '.join(known)}"
        )
    return part, key, value


@dataclass(frozen=True)
class _Origin:
    """Where a resolved value came from: a ``--set``, a TOML table, or the default."""

    kind: str  # "set" | "toml" | "default"
    text: str  # the --set text, or the table name below the profile ("fast.lasa")
    source: TableSource | None = None  # the file, when not the method's (baselines/snode.toml)


def _toml_repr(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list | tuple):
        return "[" + ",".join(_toml_repr(v) for v in value) + "]"
    return str(value)


def _toml_line(path: Path, table: str, key: str) -> int | None:
    """The line of ``key = ...`` in ``[table]`` of a TOML file (None: not found)."""
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return None
    current = None
    pattern = re.compile(rf"\s*{re.escape(key)}\s*=")
    for number, line in enumerate(lines, 1):
        stripped = line.split("#", 1)[0].strip()
        if stripped.startswith("[") and stripped.endswith("]"):
            current = ".".join(p.strip() for p in stripped.strip("[]").split("."))
        elif current == table and pattern.match(line):
            return number
    return None


def _where(src: TableSource, key: str, origin: _Origin) -> str:
    if origin.kind == "set":
        return f"--set {origin.text}"
    src = origin.source or src
    line = _toml_line(src.path, origin.text, key)
    return f"{src.label}{f' line {line}' if line else ''} [{origin.text}]"


def _located(src: TableSource, profile: str, key: str, origin: _Origin, problem: str,
             part: str | None, profile_value: Any = None,
             rule: Rule | None = None) -> ConfigError:
    """The one-line error for a bad value: where it came from, what is wrong, the fix."""
    prefix = f"{part}." if part else ""
    if origin.kind == "set":
        field_ = PART_FIELDS.get(key)
        default = field_.default if field_ is not None else None
        rule = rule or PART_RULES[key]
        if profile_value is not None:
            hint = f"; the {profile} profile uses {prefix}{key}={_toml_repr(profile_value)}"
        elif default not in (None, dataclasses.MISSING) and rule.valid(default):
            hint = f"; the default is {prefix}{key}={_toml_repr(default)}"
        else:
            hint = "; fix or drop this --set"
        return ConfigError(f"--set {origin.text}: {problem}{hint}")
    if origin.kind == "toml":
        return ConfigError(f"{_where(src, key, origin)}: {problem}; fix it in "
                           f"{(origin.source or src).path}, or override it with "
                           f"--set {prefix}{key}=VALUE")
    return ConfigError(
        f"{src.label} [{origin.text}] does not set {key}, which method "
        f"{src.method!r} needs ({problem}); add {key} = VALUE there, or pass "
        f"--set {prefix}{key}=VALUE"
    )


def _position_tangent_scale(src: TableSource, profile: str, dataset: str, source: str,
                            is_pose: bool, value: float, origin: _Origin) -> ConfigError:
    """The error for a ``tangent_scale`` other than 1 on a position model."""
    shown = _toml_repr(value)
    if not is_pose:
        fix = f"drop it ({dataset} has no orientations)"
    elif origin.kind == "set":
        fix = f"use --set orientation.tangent_scale={shown}"
    else:
        fix = f"set it in [{profile}.{source}.orientation] only"
    return ConfigError(
        f"{_where(src, 'tangent_scale', origin)}: tangent_scale = {shown} scales "
        f"orientation tangent vectors, which the position model does not have; {fix}"
    )


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
    arg_names: Mapping[str, str] | None = None,
    config_file: str | Path | None = None,
) -> RunConfig:
    """Resolve the configuration of one run from the baselines file and overrides, and check
    every value of it (:data:`PART_RULES`,
    :data:`~clfd_bench.harness.run_config.RUN_RULES`).

    Args:
        method: a built-in name, an installed plugin's name or an import spec
            (:mod:`clfd_bench.methods.registry`); stored normalised in the config.
        method_keys: the method-specific keys the method accepts (default: looked up in the
            method registry). Keys outside ``COMMON_KEYS | method_keys`` and the method's
            ``own_hyperparameters`` raise.
        config_file: the hyperparameter file (default: ``baselines/<method>.toml``, or a
            plugin class's ``config_file``).
        arg_names: the command-line option each run-level value came from, named in errors
            (default ``--order``, ``--seed``, ...).

    Raises:
        ConfigError: one line naming the bad key or value, where it came from (``--set ...``
            or ``baselines/<method>.toml line N [table]``), the valid range and the fix.
        UnknownMethodError: ``method`` is not registered.
        MethodClassError: a plugin class does not implement the method interface.
        DatasetError: ``tasks`` is given for ``robotasks9`` and its sequence file is bad.
    """
    from clfd_bench.methods import get_method_class, normalise_method

    method = normalise_method(method)
    method_cls = get_method_class(method)
    if method_keys is None:
        method_keys = method_cls.hyperparameters
    own_rules: Mapping[str, Rule] = method_cls.own_hyperparameters
    allowed = COMMON_KEYS | method_keys
    if dataset not in DATASET_TABLES:
        raise ConfigError(f"unknown dataset {dataset!r}{suggest(dataset, DATASET_TABLES)}; "
                          f"valid: {', '.join(DATASET_TABLES)}")
    if profile not in PROFILES:
        raise ConfigError(f"unknown profile {profile!r}{suggest(profile, PROFILES)}; "
                          f"valid: {', '.join(PROFILES)}")
    check_run_values({"node": node, "order": order, "seed": seed, "tasks": tasks}, dataset,
                     arg_names)
    parsed = [(text, *parse_override(text, tuple(own_rules))) for text in overrides]
    is_pose = dataset in POSE_DATASETS
    for text, o_part, _, _ in parsed:
        if o_part is not None and not is_pose:
            raise ConfigError(f"--set {text}: {dataset} has one model (position); drop the "
                              f"'{o_part}.' prefix")
    src = table_source(method, config_file)
    table = profile_table(src, profile)
    source = dataset if dataset in table or dataset not in POSE_DATASETS else "robotasks"
    if source not in table:
        notes = table.get("notes", "")
        raise ConfigError(
            f"{src.label} [{profile}] has no settings for dataset {dataset!r}"
            f"{'; ' + notes if notes else ''}; datasets with settings: "
            f"{', '.join(d for d in DATASET_TABLES if d in table)}"
        )
    parts = PARTS_POSE if is_pose else ("position",)
    resolved: list[tuple[str, PartConfig]] = []
    for part in parts:
        merged: dict[str, Any] = {}
        origin: dict[str, _Origin] = {}
        layers = [("defaults", table.get("defaults", {})), (source, table[source])]
        if is_pose:
            layers.append((f"{source}.{part}", table[source].get(part, {})))
        sources = {}
        snode_ds_layer: str | None = None  # the layer name of the dataset's sNODE table
        if node == "s":
            shared, shared_src = snode_profile_table(profile)
            layers.append((SNODE_FILE, shared))
            sources[SNODE_FILE] = shared_src
            own_snode = table.get(SNODE_TABLE, {})
            layers.append((SNODE_TABLE, own_snode))
            layers.append((f"{SNODE_TABLE}.{part}", own_snode.get(part, {})))
            # robotasks9 reads the robotasks sNODE table unless it has its own
            snode_ds = (dataset if dataset in own_snode or dataset not in POSE_DATASETS
                        else "robotasks")
            ds_snode = own_snode.get(snode_ds, {})
            snode_ds_layer = f"{SNODE_TABLE}.{snode_ds}"
            layers.append((snode_ds_layer, ds_snode))
            if is_pose:
                layers.append((f"{SNODE_TABLE}.{snode_ds}.{part}", ds_snode.get(part, {})))
        for layer_name, layer in layers:
            layer_src = sources.get(layer_name)
            table_text = profile if layer_src else f"{profile}.{layer_name}"
            where = f"{(layer_src or src).label} [{table_text}]"
            for key, value in layer.items():
                if key in PARTS_POSE and isinstance(value, dict):
                    if layer_name not in (source, SNODE_TABLE, snode_ds_layer):
                        raise ConfigError(
                            f"{where}: the [{key}] sub-table is only read under "
                            f"[{profile}.<dataset>], [{profile}.{SNODE_TABLE}] and "
                            f"[{profile}.{SNODE_TABLE}.<dataset>]; move its keys there")
                    if not is_pose and layer_name != SNODE_TABLE:
                        raise ConfigError(f"{where}: [{key}] tables only exist for pose data")
                    continue  # read as its own layer
                is_table = isinstance(value, dict)
                if is_table and layer_name == SNODE_TABLE and key in DATASET_TABLES:
                    continue  # a dataset's sNODE table: its own layer when that dataset runs
                if is_table:
                    valid = (*PARTS_POSE, *DATASET_TABLES) if layer_name == SNODE_TABLE \
                        else PARTS_POSE
                    raise ConfigError(f"{where}: unknown sub-table {key!r}"
                                      f"{suggest(key, valid)}; valid: {', '.join(valid)}")
                if key in DOC_KEYS:
                    continue
                if key not in PART_FIELDS and key not in own_rules:
                    known = [*PART_FIELDS, *own_rules]
                    raise ConfigError(
                        f"{where}: unknown key {key!r}{suggest(key, known)}; "
                        f"valid keys: {', '.join(known)}"
                    )
                merged[key] = value
                origin[key] = _Origin("toml", table_text, layer_src)
        from_profile = dict(merged)
        for text, o_part, key, value in parsed:
            if o_part is None or o_part == part:
                merged[key] = value
                origin[key] = _Origin("set", text)
        prefix = part if is_pose else None
        values: dict[str, Any] = {}
        extras: dict[str, Any] = {}
        for key, value in merged.items():
            if key in SNODE_KEYS and node != "s":
                raise ConfigError(
                    f"{_where(src, key, origin[key])}: {key!r} sets the stable NODE, which "
                    f"this run (--node {node}) does not train; use --node s, or drop it")
            if key not in allowed and key not in own_rules:
                own = sorted(method_keys | set(own_rules))
                raise ConfigError(
                    f"{_where(src, key, origin[key])}: {key!r} is not a hyperparameter of "
                    f"method {method!r} "
                    f"(its own keys: {', '.join(own) or 'none'})"
                )
            rule = own_rules.get(key) or PART_RULES[key]
            checked, problem = rule.check(key, value)
            if problem:
                good = from_profile.get(key)
                if good is not None and rule.check(key, good)[1]:
                    good = None  # the profile's own value is bad too: no example
                raise _located(src, profile, key, origin[key], problem, prefix, good, rule)
            (extras if key in own_rules else values)[key] = checked
        if part == "position" and values.get("tangent_scale", 1.0) != 1.0:
            raise _position_tangent_scale(src, profile, dataset, source, is_pose,
                                          values["tangent_scale"], origin["tangent_scale"])
        table_name = f"{profile}.{source}.{part}" if is_pose else f"{profile}.{source}"
        for key in sorted(allowed - set(values)):  # keys the method uses, left at default
            default = PART_FIELDS[key].default
            if default is dataclasses.MISSING:
                raise ConfigError(f"{src.label} [{table_name}]: missing required "
                                  f"key {key!r}; add it there, or pass --set {key}=VALUE")
            _, problem = PART_RULES[key].check(key, default)
            if problem:
                raise _located(src, profile, key, _Origin("default", table_name), problem,
                               prefix)
        for key in sorted(set(own_rules) - set(extras)):  # own keys have no default
            if not own_rules[key].optional:
                raise ConfigError(
                    f"{src.label} [{table_name}]: missing {key!r}, a hyperparameter of method "
                    f"{method!r} ({own_rules[key].describe()}); add {key} = VALUE there, or "
                    f"pass --set {key}=VALUE")
            extras[key] = None
        full = {f.name: f.default for f in fields(PartConfig)} | values
        for rule in PART_CONSTRAINTS:
            if not rule.holds(full):
                mine = [k for k in rule.keys if k in origin and origin[k].kind == "set"]
                lead = (", ".join(f"--set {origin[k].text}" for k in mine) if mine else
                        f"{src.label} [{table_name}]")
                others = ", ".join(f"{k} = {_toml_repr(full[k])}" for k in rule.keys
                                   if k not in mine)
                raise ConfigError(f"{lead}: does not go with {others} "
                                  f"(the {profile} profile's values): {rule.text}")
        resolved.append((part, PartConfig(**values, extras=extras).resolved()))
    return RunConfig(
        method=method, dataset=dataset, profile=profile, order=order, seed=seed, node=node,
        tasks=tasks, parts=tuple(resolved), overrides=tuple(overrides),
    )
