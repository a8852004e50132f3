"""``clfd-bench study tasktime``: training time per task of the hypernetwork regularisers."""

from __future__ import annotations

import argparse
import sys

from clfd_bench.cli.common import (
    add_grid_arguments,
    finish,
    grid_options,
    ints,
    names,
    run_grid,
    unknown_dataset,
)
from clfd_bench.profiles import profile_help

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from clfd_bench.learning.hnet_reg import REG_MODES
    from clfd_bench.studies.task_time import study_specs, summarize, write_outputs

    if unknown_dataset("study tasktime", [args.dataset]):
        return 2
    bad = [r for r in args.regs if r not in REG_MODES]
    if bad or not args.regs or not args.methods or not args.seeds:
        print(f"--regs takes {', '.join(REG_MODES)} (got {', '.join(args.regs) or 'none'}); "
              "--methods and --seeds need at least one value", file=sys.stderr)
        return 2
    out = Path(args.out)
    options = grid_options(args, sim=False)  # training times are measured without execution
    specs = study_specs(args.dataset, args.methods, args.regs, args.profile, args.seeds,
                        options)
    grid = run_grid("study tasktime", specs, args, desc="task-time study", options=options)
    if grid is None:  # refused before anything was trained
        return 2
    labels = list(dict.fromkeys(s.label for s in specs))
    rows = summarize(grid.records, labels)
    meta = {"dataset": args.dataset, "profile": args.profile, "methods": args.methods,
            "regs": args.regs, "seeds": args.seeds, "node": options.node, "tasks": options.tasks,
            "runs": {s.name: r.status for s, r in zip(specs, grid.records, strict=True)}}
    files = write_outputs(rows, out, meta)
    return finish("study tasktime", out / "task_time.md", files, grid.failed)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``study tasktime`` subcommand."""
    p = subparsers.add_parser(
        "tasktime",
        help="training time per task of HN/CHN with each output-regulariser mode",
        description="Trains each method with each hnet_reg mode (all: the paper's loop over "
        "earlier tasks, batched: the same in one pass, sampled: the follow-up's stochastic "
        "regulariser) through the leaderboard grid (resumable), then writes task_time.md/"
        ".csv/.json and task_time.png: seconds per task and last / first.",
    )
    p.add_argument("--dataset", default="lasa", help="dataset (default lasa, 26 tasks)")
    p.add_argument("--methods", type=names, default=names("hn,chn"),
                   help="comma-separated hypernetwork methods (default hn,chn)")
    p.add_argument("--regs", type=names, default=names("all,batched,sampled"),
                   help="comma-separated hnet_reg modes (default all,batched,sampled)")
    p.add_argument("--profile", default="fast", help=profile_help("fast"))
    p.add_argument("--seeds", type=ints, default=[0], help="comma-separated seeds (default 0)")
    p.add_argument("--out", required=True, help="output directory (runs, tables, figure)")
    add_grid_arguments(p, 1, "default 1: parallel runs would share the cores and change each "
                             "other's times", sim=False)
    p.set_defaults(func=_run)
