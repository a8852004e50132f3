"""``clfd-bench settings``: show or write the installation's settings file
(:mod:`clfd_bench.settings`: ``CLFD_DATA_DIR`` and ``MENAGERIE_ROOT`` without exports)."""

from __future__ import annotations

import argparse
import sys

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.settings import (
        read_settings,
        setting_sources,
        settings_path,
        toml_string,
        write_settings,
    )

    path = settings_path()
    if not args.values:
        print(f"# {path}" + ("" if path.exists() else " (none yet)"))
        for key, value in read_settings(path).items():
            print(f"{key} = {toml_string(value)}")
        for key, (value, where) in setting_sources().items():
            print(f"# in use: {key} = {value} ({where})" if value else f"# in use: {key} not set")
        return 0
    values = {}
    for arg in args.values:
        key, sep, value = arg.partition("=")
        if not sep:
            print(f"clfd-bench settings: error: expected KEY=VALUE, got {arg!r} (see "
                  "clfd-bench settings --help)", file=sys.stderr)
            return 2
        values[key] = value
    try:
        written = write_settings(values)
    except (ValueError, OSError) as exc:
        print(f"clfd-bench settings: error: {exc}", file=sys.stderr)
        return 2
    print(f"settings written to {written}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``settings`` subcommand."""
    p = subparsers.add_parser(
        "settings",
        help="show or write where the datasets and the robot model are (no exports needed)",
        description="Show or write this installation's settings file (inside the virtual "
        "environment: <venv>/clfd-bench.toml). Its CLFD_DATA_DIR and MENAGERIE_ROOT are used "
        "wherever the variable is not exported. `bash run.sh setup` writes it.",
    )
    p.add_argument("values", nargs="*", metavar="KEY=VALUE",
                   help="CLFD_DATA_DIR=PATH or MENAGERIE_ROOT=PATH (an empty value removes "
                   "the key); none: print the file and the values in use")
    p.set_defaults(func=_run)
