"""``clfd-bench video``: render a run's learned skills executed by the simulated Panda.

    clfd-bench video runs/hn0 --task all --out videos/
    clfd-bench video runs/hn0 --task e --demo 2 --out videos/ --rerun videos/e.rrd

Executes the predictions made after the run's last learned task for one demo's start and
renders them offscreen (EGL; set MUJOCO_GL=egl on headless machines) to mp4: one file per task,
with ``--task all`` also one video of all tasks in order and, for HelloWorld, "hello world"
written with the learned letters (only the learned ones when the run stopped early). The
prediction is drawn in orange, the demonstration in green, the tool's path or ink in blue.
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["register"]


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT, e.g. 480x360, got {text!r}"
                                         ) from None
    return w, h


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.viz.video import VideoStyle, render_run_videos

    try:
        style = VideoStyle(width=args.size[0], height=args.size[1], fps=args.fps,
                           shadows=args.shadows)
        paths = render_run_videos(args.run_dir, task=args.task, demo=args.demo,
                                  out_dir=args.out, style=style, rerun_path=args.rerun,
                                  hello_world=not args.no_text)
    except (FileNotFoundError, ValueError, KeyError) as exc:
        print(f"clfd-bench video: error: {exc}", file=sys.stderr)
        return 2
    for path in paths:
        print(path)
    if args.rerun:
        print(f"rerun log: {args.rerun} (open with `rerun {args.rerun}`)")
    return 0 if paths else 1


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``video`` subcommand."""
    p = subparsers.add_parser(
        "video",
        help="render a run's learned tasks executed in simulation to mp4",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run_dir", metavar="RUN_DIR", help="a run directory of `clfd-bench train`")
    p.add_argument("--task", default="all", metavar="T",
                   help="a task's index or name, or 'all' (default)")
    p.add_argument("--demo", type=int, default=0, help="start from this demo's start (default 0)")
    p.add_argument("--out", default="videos", help="output folder (default: videos/)")
    p.add_argument("--rerun", metavar="FILE.rrd", default=None,
                   help="also log the rendered rollouts to this rerun file")
    p.add_argument("--fps", type=float, default=20.0,
                   help="frames per simulated second, played in real time (default 20)")
    p.add_argument("--size", type=_size, default=(480, 360), metavar="WxH",
                   help="frame size (default 480x360)")
    p.add_argument("--shadows", action="store_true",
                   help="render shadows and reflections (much slower without a GPU)")
    p.add_argument("--no-text", action="store_true",
                   help="HelloWorld: do not write the 'hello world' text video")
    p.set_defaults(func=_run)
