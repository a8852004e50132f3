"""``clfd-bench study order``: the CL methods under task orders 0, 1, 2 of each dataset."""

from __future__ import annotations

import argparse
import sys

from clfd_bench.cli.common import (
    add_grid_arguments,
    finish,
    grid_options,
    ints,
    names,
    unknown_dataset,
)
from clfd_bench.profiles import profile_help

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from clfd_bench.methods import get_method_class
    from clfd_bench.studies.task_order import run_order_study, task_names

    if unknown_dataset("study order", args.datasets):
        return 2
    try:
        for method in args.methods:
            get_method_class(method)
        for dataset in args.datasets:
            for order in args.orders:
                task_names(dataset, order)
    except (KeyError, ValueError) as exc:
        print(exc.args[0], file=sys.stderr)
        return 2
    if not (args.methods and args.orders and args.seeds):
        print("--methods, --orders and --seeds each need at least one value", file=sys.stderr)
        return 2
    result = run_order_study(
        datasets=args.datasets,
        methods=args.methods,
        orders=args.orders,
        seeds=args.seeds,
        profile=args.profile,
        out=Path(args.out),
        options=grid_options(args),
    )
    return finish("study order", Path(args.out) / "order_table.md", result.files,
                  result.failed, result.summary())


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``study order`` subcommand."""
    p = subparsers.add_parser(
        "order",
        help="robustness to task order: train each method on several task orders and compare",
        description="Trains every (dataset, method, order, seed) run that is not finished yet "
        "(through the leaderboard grid: a killed study resumes, a crashed run is reported and "
        "does not stop the others), then writes order_table.md/.csv/.json (ACC, REM, CL_score, "
        "exec ACC per dataset x order x method, and each method's spread across orders) and "
        "one figure per dataset, order_<dataset>.png, with one column per order.",
    )
    p.add_argument("--datasets", type=names, default=names("lasa,helloworld,robotasks"),
                   help="comma-separated datasets (default lasa,helloworld,robotasks)")
    p.add_argument("--methods", type=names, default=names("sg,rep,hn,chn"),
                   help="comma-separated CL methods (default sg,rep,hn,chn, as in the paper)")
    p.add_argument("--orders", type=ints, default=[0, 1, 2],
                   help="comma-separated task orders (default 0,1,2)")
    p.add_argument("--seeds", type=ints, default=[0, 1, 2],
                   help="comma-separated seeds (default 0,1,2)")
    p.add_argument("--profile", default="fast", help=profile_help("fast"))
    p.add_argument("--out", required=True, help="output directory (runs, tables, figures)")
    add_grid_arguments(p)
    p.set_defaults(func=_run)
