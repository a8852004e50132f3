"""``clfd-bench pretrained``: finished results shipped with clfd-bench, to explore without
training.

    clfd-bench pretrained list
    clfd-bench pretrained get helloworld-fast [--out results/helloworld-fast] [--force]

``get`` verifies the bundle's sha256, extracts it into ``--out`` (default
``results/<name>``) exactly as a leaderboard job writes its folder (``leaderboard.md/.csv/
.json``, figures, ``runs/...`` with checkpoints, predictions and execution results), and
prints what to run next: ``clfd-bench video``, ``evaluate``, ``site`` take it as they take a
folder trained here. It says when the bundle's execution results were made by another
simulator than the installed one (``clfd-bench evaluate`` then re-executes, without
training).
"""

from __future__ import annotations

import argparse
import importlib.util
import shlex
import sys
from pathlib import Path

__all__ = ["next_steps", "register"]


def next_steps(out: Path) -> list[str]:
    """The commands worth running on a fresh results folder ``out``."""
    from clfd_bench.leaderboard.report import read_leaderboard
    from clfd_bench.pretrained import method_runs

    runs = dict(method_runs(out))
    try:  # the leaderboard's order
        order = list(read_leaderboard(out)["meta"]["methods"])
        runs = dict(sorted(runs.items(), key=lambda kv: (kv[0] not in order,
                                                          order.index(kv[0]) if kv[0] in order
                                                          else 0, kv[0])))
    except (ValueError, KeyError):
        pass
    q = shlex.quote
    lines = [f"cat {q(str(out / 'leaderboard.md'))}"]
    if importlib.util.find_spec("clfd_bench.cli.site") is not None:
        lines.append(f"clfd-bench site {q(str(out))} --out {q(str(out / 'site'))}")
    if runs:
        method, run = next(((m, p) for m, p in runs.items() if m == "hn"),
                           next(iter(runs.items())))
        lines += [
            f"clfd-bench video {q(str(run))} --task all --out {q(str(out / 'videos'))}",
            f"clfd-bench video --compare {' '.join(q(str(p)) for p in runs.values())} "
            f"--task 0 --out {q(str(out / 'videos'))}",
            f"clfd-bench evaluate {q(str(run))}",
        ]
    return lines


def _list(args: argparse.Namespace) -> int:
    from clfd_bench.pretrained import describe

    print(describe())
    return 0


def _get(args: argparse.Namespace) -> int:
    from clfd_bench.pretrained import PretrainedError, get, stale_runs

    try:
        out = get(args.name, args.out, force=args.force)
    except (PretrainedError, OSError) as exc:  # OSError: e.g. --out not writable, disk full
        print(f"clfd-bench pretrained get: error: {exc}", file=sys.stderr)
        return 2
    print(f"results: {out}")
    stale = stale_runs(out)
    if stale:
        print(f"note: the execution results of {len(stale)} run(s) were made by another "
              "simulator than the installed one (its files or the mujoco, mink, gymnasium "
              "versions differ); tables, figures and videos work, and `clfd-bench evaluate "
              "RUN_DIR` re-executes a run's predictions without training:")
        for path, reason in stale:
            print(f"  {path}: {reason}")
    print("next:")
    for line in next_steps(out):
        print(f"  {line}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``pretrained`` subcommand (``list``, ``get``)."""
    p = subparsers.add_parser(
        "pretrained",
        help="finished results shipped with clfd-bench (list, get): no training needed",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = p.add_subparsers(dest="pretrained_command", metavar="ACTION", required=True,
                           parser_class=type(p))
    ls = sub.add_parser("list", help="the shipped bundles")
    ls.set_defaults(func=_list)
    g = sub.add_parser("get", help="extract a bundle into a results folder")
    g.add_argument("name", metavar="NAME", help="a bundle's name (see `pretrained list`)")
    g.add_argument("--out", default=None, metavar="DIR",
                   help="the results folder to create (default: results/NAME)")
    g.add_argument("--force", action="store_true",
                   help="replace --out when it exists and is not empty")
    g.set_defaults(func=_get)
