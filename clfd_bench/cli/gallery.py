"""``clfd-bench gallery``: the executions nearest each success criterion's bound, drawn.

    clfd-bench gallery RESULTS_DIR [RESULTS_DIR ...] --out DIR [--per-side K]
                       [--sheets DIR] [--workers N]

For every run under the results folders (``runs/<dataset>/<method>/...``), every execution of
its saved predictions is scored with the env's checks (executing what the run's sim cache
lacks, as ``clfd-bench evaluate`` does, which also refreshes the run's execution fields).
Per env and numeric check, the K executions nearest the bound on the passing side and on the
failing side (there, executions failing only this check first) are executed again and drawn:
ink against target for letters and shapes, the closing frame for scenes, each captioned
with method, task, demo, the value against its bound and the verdict. DIR receives the
pictures, ``gallery.md`` and one contact sheet per dataset (``gallery_<dataset>.png``;
``--sheets`` writes those elsewhere, e.g. ``docs/figures``).
Envs that report no checks are listed as such, not drawn.
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.viz.gallery import build_gallery

    if args.per_side < 1:
        print(f"clfd-bench gallery: error: --per-side must be >= 1, got {args.per_side}",
              file=sys.stderr)
        return 2
    try:
        report = build_gallery(args.results_dirs, args.out, per_side=args.per_side,
                               sheets=args.sheets, workers=args.workers)
    except ValueError as exc:
        print(f"clfd-bench gallery: error: {exc}", file=sys.stderr)
        return 2
    print(f"{report.pictures} pictures of {len(report.borderlines)} checks from "
          f"{report.executions} distinct executions ({report.left_out} left out: the episode "
          f"ended early; gathering {report.gather_s:.0f} s, drawing {report.render_s:.0f} s)")
    for env_id, n in sorted(report.no_checks.items()):
        print(f"no checks reported: {env_id} ({n} executions; its env does not fill "
              "info['checks'])")
    for run, why in report.skipped.items():
        print(f"run left out: {run}: {why}")
    for line in report.mismatches:
        print(f"warning: re-execution differs: {line}")
    print(f"gallery: {report.markdown}")
    for dataset, path in report.sheets.items():
        print(f"contact sheet {dataset}: {path}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``gallery`` subcommand."""
    p = subparsers.add_parser(
        "gallery",
        help="draw the executions nearest each success criterion's bound (both sides)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("results_dirs", nargs="+", metavar="RESULTS_DIR",
                   help="results folders (of `clfd-bench leaderboard`) or run directories")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--per-side", type=int, default=2, metavar="K",
                   help="executions per check and side (default 2)")
    p.add_argument("--sheets", default=None, metavar="DIR",
                   help="write the per-dataset contact sheets here (default: --out)")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="processes executing what the runs' caches lack (default 1)")
    p.set_defaults(func=_run)
