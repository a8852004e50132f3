"""``clfd-bench leaderboard``: run a grid of CL methods and write the leaderboard."""

from __future__ import annotations

import argparse
import os
import sys

from clfd_bench.cli.common import (
    add_grid_arguments,
    finish,
    grid_options,
    ints,
    names,
    unknown_dataset,
)
from clfd_bench.leaderboard.entries import entry_help
from clfd_bench.profiles import profile_help

__all__ = ["register"]

ALL_METHODS = "sg,ft,rep,si,mas,hn,chn"


def _config(text: str) -> tuple[str, str]:
    method, sep, path = text.partition("=")
    if not sep or not method.strip() or not path.strip():
        msg = f"expected METHOD=PATH (e.g. l2=my_l2.toml), got {text!r}"
        raise argparse.ArgumentTypeError(msg)
    method = method.strip()
    return (method if ":" in method else method.lower()), path.strip()


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from clfd_bench.leaderboard.runner import check_methods, run_leaderboard
    from clfd_bench.methods import MethodClassError

    if unknown_dataset("leaderboard", [args.dataset]):
        return 2
    options = grid_options(args)
    try:
        check_methods(args.methods)
    except (KeyError, MethodClassError) as exc:
        print(f"clfd-bench leaderboard: error: {exc.args[0]}", file=sys.stderr)
        return 2
    if options.sim:
        from clfd_bench.harness.validate import check_robot_model

        check_robot_model()  # before any training: one line naming MENAGERIE_ROOT
    result = run_leaderboard(
        dataset=args.dataset,
        methods=args.methods,
        profile=args.profile,
        seeds=args.seeds,
        orders=args.orders,
        out=Path(args.out),
        options=options,
        include=[Path(p) for p in args.include],
        configs=dict(args.configs),
    )
    print(
        f"[leaderboard] {result.counts()} ({result.seconds:.0f} s)"
    )
    return finish("leaderboard", Path(args.out) / "leaderboard.md", result.files, result.failed)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``leaderboard`` subcommand."""
    p = subparsers.add_parser(
        "leaderboard",
        help="train a grid of CL methods (skipping finished runs) and write the leaderboard",
        description="Runs the training runs of the grid that are not finished yet (a killed "
        "grid resumes; a crashed run is reported as failed and does not stop the grid), then "
        "writes leaderboard.md/.csv/.json and PNG figures into --out.",
    )
    p.add_argument("--dataset", required=True, help="lasa, helloworld, robotasks, robotasks9")
    p.add_argument("--methods", type=names, default=names(ALL_METHODS),
                   help=f"comma-separated CL methods (default {ALL_METHODS}); plugins by "
                        "name or as package.module:ClassName (docs/methods.md); "
                        f"{entry_help()} (a method with its own --node and settings, "
                        "docs/snode.md)")
    p.add_argument("--profile", default="fast", help=profile_help("fast"))
    p.add_argument("--seeds", type=ints, default=[0], help="comma-separated seeds (default 0)")
    p.add_argument("--orders", type=ints, default=[0], help="task orders (default 0)")
    p.add_argument("--out", default="results", help="output directory (default results/)")
    p.add_argument("--config", dest="configs", type=_config, action="append", default=[],
                   metavar="METHOD=PATH",
                   help="a method's hyperparameter file (repeatable; default baselines/ or a "
                        "plugin's own, docs/methods.md)")
    p.add_argument("--include", action="append", default=[], metavar="RUN_DIR",
                   help="also put this finished run directory in the leaderboard, under its "
                        "method label (repeatable): predictions scored with `clfd-bench "
                        "score`, or a run trained elsewhere")
    add_grid_arguments(p, max(1, os.cpu_count() or 1), "default: CPU count")
    p.set_defaults(func=_run)
