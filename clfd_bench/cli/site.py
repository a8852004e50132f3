"""``clfd-bench site``: a static results site for a leaderboard's output folder.

    clfd-bench site results --out results/site
    clfd-bench site results --out site --no-videos     # tables, figures and pages only

Writes ``index.html`` (the leaderboard, sortable, with the paper's numbers beside ours; the
figures; a video wall: the last learned model of each method executing every task, failed
tiles marked with their reason) and one page per run (R matrices as heat maps, config,
provenance). Plain files with relative links: open ``index.html`` from disk or put the
folder on any static host. Videos already rendered by an earlier build are reused, so an
interrupted build resumes; rendering is the long part (~4 s per tile on 2 CPU cores).
"""

from __future__ import annotations

import argparse
import sys

from clfd_bench.cli.common import frame_size

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.harness.validate import check_count
    from clfd_bench.site import build_site

    check_count("--workers", args.workers)
    out = args.out or f"{args.results_dir.rstrip('/')}/site"
    style = {"width": args.size[0], "height": args.size[1], "fps": args.fps}
    try:
        from clfd_bench.viz.video import VideoStyle

        VideoStyle(width=style["width"], height=style["height"], fps=style["fps"])
    except ValueError as exc:
        print(f"clfd-bench site: error: {exc}", file=sys.stderr)
        return 2
    from clfd_bench.runs import RunLockedError

    try:
        result = build_site(args.results_dir, out, videos=not args.no_videos, demo=args.demo,
                            style=style, workers=args.workers,
                            log=None if args.quiet else (lambda line: print(line, flush=True)))
    except RunLockedError as exc:
        print(f"clfd-bench site: error: {exc}", file=sys.stderr)
        return 2
    for run, task, note in result.video_errors:
        print(f"clfd-bench site: warning: {run} task {task}: {note}", file=sys.stderr)
    print(result.index)
    return 1 if result.video_errors else 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``site`` subcommand."""
    from clfd_bench.site.wall import WALL_STYLE

    p = subparsers.add_parser(
        "site",
        help="write a static results site (leaderboard, figures, video wall, run pages)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("results_dir", metavar="RESULTS_DIR",
                   help="a leaderboard's output folder (e.g. results/ of `bash run.sh main`)")
    p.add_argument("--out", metavar="SITE_DIR", default=None,
                   help="the site's folder (default: RESULTS_DIR/site)")
    p.add_argument("--no-videos", action="store_true",
                   help="do not render the video wall (outcomes are still shown)")
    p.add_argument("--demo", type=int, default=0,
                   help="the wall's executions start from this demo's start (default 0)")
    p.add_argument("--size", type=frame_size, metavar="WxH",
                   default=(WALL_STYLE["width"], WALL_STYLE["height"]),
                   help=f"tile size (default {WALL_STYLE['width']}x{WALL_STYLE['height']})")
    p.add_argument("--fps", type=float, default=WALL_STYLE["fps"],
                   help=f"tile frames per simulated second (default {WALL_STYLE['fps']:g})")
    p.add_argument("--workers", type=int, default=1,
                   help="processes rendering videos (default 1)")
    p.add_argument("--quiet", action="store_true", help="print only the path of index.html")
    p.set_defaults(func=_run)
