"""Where this installation finds its data and robot model without exports: the settings file.

Two environment variables point clfd-bench at local copies: ``CLFD_DATA_DIR`` (the datasets,
:mod:`clfd_bench.data.sources`) and ``MENAGERIE_ROOT`` (MuJoCo Menagerie, read by the
``mujoco_menagerie`` package). Exported variables are not remembered by a new shell, so
``bash run.sh setup`` records the values it found (the exported ones, or the offline copies
in ``../shared`` beside the checkout) in the settings file of the virtual environment,
``<venv>/clfd-bench.toml``::

    CLFD_DATA_DIR = "/work/shared/datasets"
    MENAGERIE_ROOT = "/work/shared/menagerie"

``import clfd_bench`` calls :func:`apply_settings`: every variable of the file that is not
set in the environment is set from it, so the datasets and the robot model are found in any
shell that uses this venv. An exported variable always wins. Outside a virtual environment
the file is ``$XDG_CONFIG_HOME/clfd-bench/clfd-bench.toml`` (default ``~/.config``);
``CLFD_SETTINGS_FILE`` names another one.
Write it with ``clfd-bench settings KEY=VALUE ...`` (``KEY=`` removes a key; no argument
prints it); ``clfd-bench data`` prints the values in use and where each comes from.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from pathlib import Path

import tomllib

__all__ = [
    "SETTINGS", "apply_settings", "read_settings", "setting_sources", "settings_path",
    "toml_string", "write_settings",
]

SETTINGS: tuple[str, ...] = ("CLFD_DATA_DIR", "MENAGERIE_ROOT")
"""The variables the settings file may hold."""

FILE_NAME = "clfd-bench.toml"

#: What :func:`apply_settings` took from the file (variable -> value), for :func:`setting_sources`.
_applied: dict[str, str] = {}


def settings_path() -> Path:
    """The settings file of this interpreter: ``$CLFD_SETTINGS_FILE`` when set, else
    ``<venv>/clfd-bench.toml`` inside a virtual environment, else
    ``$XDG_CONFIG_HOME/clfd-bench/clfd-bench.toml``. It may not exist."""
    if env := os.environ.get("CLFD_SETTINGS_FILE"):
        return Path(env).expanduser()
    if sys.prefix != sys.base_prefix:
        return Path(sys.prefix) / FILE_NAME
    base = os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config"
    return Path(base) / "clfd-bench" / FILE_NAME


def read_settings(path: Path | None = None) -> dict[str, str]:
    """The variables in the settings file (``{}`` when there is none).

    Raises:
        ValueError: the file is not TOML of ``NAME = "value"`` lines with names from
            :data:`SETTINGS` (the message names the file and how to fix it).
    """
    path = settings_path() if path is None else path
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return {}
    except OSError as exc:
        raise ValueError(f"settings file {path} cannot be read ({exc.strerror or exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"settings file {path} is not valid TOML ({exc}); fix or delete it, "
                         "then run `bash run.sh setup` again") from None
    bad = [k for k, v in data.items() if k not in SETTINGS or not isinstance(v, str)]
    if bad:
        raise ValueError(f"settings file {path}: unknown or non-string key(s) "
                         f"{', '.join(map(repr, bad))}; valid: {', '.join(SETTINGS)} "
                         "(string values)")
    return dict(data)


def write_settings(values: Mapping[str, str], path: Path | None = None) -> Path:
    """Merge ``values`` into the settings file (an empty value removes the key); returns its
    path. Values are written as given (pass absolute paths).

    Raises:
        ValueError: a key not in :data:`SETTINGS`.
    """
    path = settings_path() if path is None else path
    bad = [k for k in values if k not in SETTINGS]
    if bad:
        raise ValueError(f"unknown setting(s) {', '.join(map(repr, bad))}; valid: "
                         f"{', '.join(SETTINGS)}")
    merged = read_settings(path)
    for key, value in values.items():
        if value:
            merged[key] = value
        else:
            merged.pop(key, None)
    lines = ["# clfd-bench settings (clfd_bench/settings.py): used where the variable is not "
             "exported"]
    lines += [f"{key} = {toml_string(merged[key])}" for key in SETTINGS if key in merged]
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    os.replace(tmp, path)
    return path


def toml_string(value: str) -> str:
    """``value`` as a TOML basic string."""
    return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'


def apply_settings() -> None:
    """Set every variable of the settings file that the environment does not set.

    A settings file that cannot be read is reported once on stderr and otherwise ignored:
    importing clfd_bench must not fail because of it (the commands that need the variable
    then say which one is missing).
    """
    try:
        values = read_settings()
    except ValueError as exc:
        print(f"clfd-bench: warning: {exc}", file=sys.stderr)
        return
    for key, value in values.items():
        if not os.environ.get(key):
            os.environ[key] = value
            _applied[key] = value


def setting_sources() -> dict[str, tuple[str | None, str]]:
    """Per variable of :data:`SETTINGS`: ``(value or None, where it comes from)`` -- the
    environment, the settings file (named), or nowhere."""
    out: dict[str, tuple[str | None, str]] = {}
    for key in SETTINGS:
        value = os.environ.get(key) or None
        if value is None:
            out[key] = (None, "not set")
        elif _applied.get(key) == value:
            out[key] = (value, f"from {settings_path()}")
        else:
            out[key] = (value, "from the environment")
    return out
