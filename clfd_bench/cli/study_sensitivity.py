"""``clfd-bench study sensitivity``: CL metrics under randomly drawn regularisation strengths."""

from __future__ import annotations

import argparse
import sys

from clfd_bench.cli.common import (
    add_grid_arguments,
    finish,
    grid_options,
    names,
    unknown_dataset,
)
from clfd_bench.profiles import profile_help

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from clfd_bench.harness.config import ConfigError
    from clfd_bench.methods import get_method_class
    from clfd_bench.studies.sensitivity import (
        apply_ranges,
        default_ranges,
        plan_sensitivity,
        run_sensitivity_study,
    )

    if unknown_dataset("study sensitivity", [args.dataset]):
        return 2
    if not args.methods:
        print("--methods needs at least one method", file=sys.stderr)
        return 2
    try:
        for method in args.methods:
            get_method_class(method)
    except KeyError as exc:
        print(exc.args[0], file=sys.stderr)
        return 2
    options = grid_options(args)
    try:
        ranges = apply_ranges(default_ranges(), args.methods, args.range)
        plan_sensitivity(args.dataset, args.methods, args.configs, args.seed, args.profile,
                         ranges, options)
    except (ValueError, ConfigError) as exc:
        print(f"study sensitivity: {exc}", file=sys.stderr)
        return 2
    result = run_sensitivity_study(
        dataset=args.dataset,
        methods=args.methods,
        configs=args.configs,
        seed=args.seed,
        profile=args.profile,
        out=Path(args.out),
        ranges=ranges,
        options=options,
    )
    return finish("study sensitivity", Path(args.out) / "sensitivity.md", result.files,
                  result.failed, result.text())


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``study sensitivity`` subcommand."""
    p = subparsers.add_parser(
        "sensitivity",
        help="robustness to the regularisation hyperparameters (SI c/xi, MAS lambda, HN/CHN beta)",
        description="Draws --configs configurations per method, each hyperparameter uniform in "
        "its range (the paper's by default: SI si_c, si_xi in [0.1, 0.5]; MAS mas_lambda in "
        "[0.1, 0.5]; HN and CHN beta in [1e-3, 1e-2]) from a generator seeded by --seed, "
        "trains each configuration (finished runs are skipped; the draw is recorded in "
        "configs.json and in the run names), and writes sensitivity.md/.csv/.json (median and "
        "IQR of CL_score and CL_stability without SSS, next to the paper's) and "
        "sensitivity.png.",
    )
    p.add_argument("--dataset", default="lasa", help="dataset (default lasa, as in the paper)")
    p.add_argument("--methods", type=names, default=names("si,mas,hn,chn"),
                   help="comma-separated CL methods (default si,mas,hn,chn)")
    p.add_argument("--configs", type=int, default=5,
                   help="configurations drawn per method (default 5)")
    p.add_argument("--seed", type=int, default=0,
                   help="seeds the draw and every training run (default 0)")
    p.add_argument("--profile", default="fast", help=profile_help("fast"))
    p.add_argument("--range", action="append", default=[], metavar="[METHOD.]KEY=LOW,HIGH",
                   help="replace a sampling range, e.g. beta=1e-3,1e-2 (every method that "
                   "samples beta) or hn.beta=0.01,1 (one method; also adds a key); repeatable")
    p.add_argument("--out", required=True, help="output directory (runs, tables, figure)")
    add_grid_arguments(p, sim_help="skip execution in simulation (the study's scores are "
                       "trajectory-based; execution adds exec ACC per configuration)")
    p.set_defaults(func=_run)
