"""``clfd-bench study loops``: which learned tasks keep their loops with and without a time
input."""

from __future__ import annotations

import argparse
import os
import sys

from clfd_bench.cli.common import add_grid_arguments, finish, grid_options, ints, names, run_grid
from clfd_bench.profiles import profile_help

__all__ = ["register"]

PLANAR = ("helloworld", "lasa")


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from clfd_bench.studies.loops import study_specs, summarize, write_outputs

    if args.dataset not in PLANAR:
        print(f"clfd-bench study loops: error: crossings are counted in the plane; dataset must "
              f"be one of {', '.join(PLANAR)} (got {args.dataset!r})", file=sys.stderr)
        return 2
    if not args.methods or not args.seeds:
        print("clfd-bench study loops: error: --methods and --seeds need at least one value",
              file=sys.stderr)
        return 2
    out = Path(args.out)
    options = grid_options(args)
    specs = study_specs(args.dataset, args.methods, args.profile, args.seeds, options)
    grid = run_grid("study loops", specs, args, desc="loop study", options=options)
    if grid is None:  # refused before anything was trained
        return 2
    study = summarize(grid.records, out, args.dataset, args.methods)
    meta = {"dataset": args.dataset, "profile": args.profile, "methods": args.methods,
            "seeds": args.seeds, "sim": options.sim, "tasks": options.tasks,
            "runs": {s.name: r.status for s, r in zip(specs, grid.records, strict=True)}}
    files = write_outputs(study, out, meta)
    return finish("study loops", out / "loops.md", files, grid.failed)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``study loops`` subcommand."""
    p = subparsers.add_parser(
        "loops",
        help="loops with and without a time input: self-crossings, DTW and execution per task",
        description="Trains (or reuses: the paper grid's run names) each method with NODE^T "
        "and NODE^I, task order 0, then writes loops.md/.csv/.json and loops.png: for every "
        "task whose demos cross themselves, how often the predictions do (NODE^I cannot: a "
        "time-invariant planar field never crosses itself), their DTW against the paper's "
        "threshold and their success in simulation.",
    )
    p.add_argument("--dataset", default="helloworld",
                   help=f"a planar dataset: {', '.join(PLANAR)} (default helloworld)")
    p.add_argument("--methods", type=names, default=names("sg,ft,rep,si,mas,hn,chn"),
                   help="comma-separated CL methods (default all seven)")
    p.add_argument("--profile", default="fast", help=profile_help("fast"))
    p.add_argument("--seeds", type=ints, default=[0], help="comma-separated seeds (default 0)")
    p.add_argument("--out", required=True,
                   help="output directory (runs under OUT/runs, tables, figure)")
    add_grid_arguments(p, max(1, os.cpu_count() or 1), "default: CPU count", node=False)
    p.set_defaults(func=_run)
