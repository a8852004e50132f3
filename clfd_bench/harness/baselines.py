"""The hyperparameter files: finding and reading a method's ``baselines/<method>.toml`` (or
a plugin's own file, or ``--config``) and ``baselines/snode.toml``, and checking the structure
of a profile's tables (top-level keys, ``method``, the profile's table names).

The values in those tables are layered and checked by
:func:`clfd_bench.harness.config.resolve_config`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from clfd_bench.harness.run_config import DATASET_TABLES, PROFILES, suggest
from clfd_bench.learning.part_config import ConfigError
from clfd_bench.resources import resource_path

__all__ = [
    "DOC_KEYS",
    "SNODE_FILE",
    "SNODE_TABLE",
    "TableSource",
    "baselines_file",
    "load_profile_table",
    "profile_table",
    "snode_profile_table",
    "table_source",
]

DOC_KEYS = ("notes",)
SNODE_TABLE = "snode"
"""The table of a method's profile that applies to stable-NODE runs (``--node s``) only."""


def baselines_file(method: str) -> Path:
    """``baselines/<method>.toml``."""
    return resource_path("baselines", f"{method}.toml")


SNODE_FILE = "snode.toml"
"""``baselines/snode.toml``: the stable NODE's settings per profile, for every method."""


@dataclass(frozen=True)
class TableSource:
    """Where a method's hyperparameters are read from. ``label`` is how messages name the
    file (``baselines/hn.toml`` for the built-ins, the path for a plugin's)."""

    method: str
    name: str
    path: Path
    label: str


def table_source(method: str, config_file: str | Path | None = None) -> TableSource:
    """The method's hyperparameter file: ``config_file`` if given, else the plugin class's
    own, else ``baselines/<name>.toml``."""
    from clfd_bench.methods import get_method_class, own_config_file

    cls = get_method_class(method)
    if config_file is not None:
        path = Path(config_file).expanduser().resolve()
    else:
        path = own_config_file(cls)
    if path is None:
        return TableSource(method, cls.name, baselines_file(cls.name), f"baselines/{cls.name}.toml")
    return TableSource(method, cls.name, path, str(path))


def _read_baselines(src: TableSource) -> tuple[Path, dict[str, Any]]:
    path = src.path
    if not path.is_file():
        fix = ("; pass --config PATH (a TOML with the tables of baselines/*.toml, see "
               "docs/methods.md) or set the method class's config_file")
        raise ConfigError(f"no hyperparameter file for method {src.method!r}: {path} does not "
                          f"exist{fix}")
    try:
        with path.open("rb") as fh:
            return path, tomllib.load(fh)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(
            f"{path} is not valid TOML: {exc}; fix the file at that line"
        ) from None
    except OSError as exc:
        raise ConfigError(f"cannot read {path}: {exc.strerror or exc}") from None


def snode_profile_table(profile: str) -> tuple[dict[str, Any], TableSource]:
    """The ``[profile]`` table of ``baselines/snode.toml`` (only stable-NODE keys and the
    solver/network keys it changes) and its source, for error messages."""
    src = TableSource("snode", "snode", baselines_file("snode"), f"baselines/{SNODE_FILE}")
    path, doc = _read_baselines(src)
    table = doc.get(profile)
    if not isinstance(table, dict):
        raise ConfigError(f"{path} has no [{profile}] table; it needs one per profile "
                          f"({', '.join(PROFILES)})")
    return table, src


def load_profile_table(method: str, profile: str,
                       config_file: str | Path | None = None) -> dict[str, Any]:
    """The raw ``[profile]`` table of the method's hyperparameter file (validated
    structure): ``baselines/<method>.toml``, or for a plugin ``config_file`` / its own."""
    return profile_table(table_source(method, config_file), profile)


def profile_table(src: TableSource, profile: str) -> dict[str, Any]:
    if profile not in PROFILES:
        raise ConfigError(f"unknown profile {profile!r}{suggest(profile, PROFILES)}; "
                          f"valid: {', '.join(PROFILES)}")
    path, doc = _read_baselines(src)
    top_valid = {"method", "description", *PROFILES}
    for key in doc:
        if key not in top_valid:
            raise ConfigError(
                f"{path}: unknown top-level key {key!r}{suggest(key, sorted(top_valid))}; "
                f"valid: {', '.join(sorted(top_valid))}"
            )
    if doc.get("method") != src.name:
        raise ConfigError(f"{path}: 'method' must be {src.name!r} (the class's name), got "
                          f"{doc.get('method')!r}")
    if profile not in doc:
        raise ConfigError(f"{path} has no [{profile}] profile; it has: "
                          f"{', '.join(p for p in PROFILES if p in doc)}")
    table = doc[profile]
    valid = {"defaults", SNODE_TABLE, *DATASET_TABLES, *DOC_KEYS}
    for key in table:
        if key not in valid:
            raise ConfigError(
                f"{path} [{profile}]: unknown table {key!r}{suggest(key, sorted(valid))}; "
                f"valid: {', '.join(sorted(valid))}"
            )
    return table
