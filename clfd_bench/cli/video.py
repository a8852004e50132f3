"""``clfd-bench video``: render a run's learned skills executed by the simulated Panda.

    clfd-bench video runs/hn0 --task all --out videos/
    clfd-bench video runs/hn0 --task e --demo 2 --out videos/ --rerun videos/e.rrd
    clfd-bench video --compare results/runs/helloworld/*/fast_nodet_o0_s0 --task l --out videos/

Executes the predictions made after the run's last learned task for one demo's start and
renders them offscreen (EGL; set MUJOCO_GL=egl on headless machines) to mp4: one file per task,
with ``--task all`` also one video of all tasks in order and, for HelloWorld, "hello world"
written with the learned letters (only the learned ones when the run stopped early). The
prediction is drawn in orange, the demonstration in green, the tool's path or ink in blue.
A caption names the run's method, the task and the demo; the closing frames add the outcome
("success", or "failed (kind)" and the env's reason) and a green or red border.

``--compare RUN_DIR ...`` makes one video of one task (``--task``) executed by every given run
after its last learned task, side by side (a grid of tiles, each rendered at its own size and
captioned with its method and outcome): e.g. every method of a leaderboard on one letter.
Frames are 1280x720 by default (``--size``).
"""

from __future__ import annotations

import argparse
import sys

from clfd_bench.cli.common import frame_size

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.viz.video import (
        VideoStyle,
        comparison_path,
        render_comparison_video,
        render_run_videos,
    )

    if (args.run_dir is None) == (args.compare is None):
        print("clfd-bench video: error: give one RUN_DIR, or --compare RUN_DIR [RUN_DIR ...] "
              "(not both)", file=sys.stderr)
        return 2
    if args.compare is not None and str(args.task).lower() == "all":
        print("clfd-bench video: error: --compare shows one task: give --task (an index or a "
              "name)", file=sys.stderr)
        return 2
    from clfd_bench.harness.validate import check_robot_model

    check_robot_model()  # one line naming MENAGERIE_ROOT
    try:
        style = VideoStyle(width=args.size[0], height=args.size[1], fps=args.fps,
                           shadows=args.shadows)
        if args.compare is not None:
            paths = [render_comparison_video(args.compare, task=args.task, demo=args.demo,
                                             out_path=comparison_path(args.compare[0], args.task,
                                                                      args.demo, args.out),
                                             style=style)]
        else:
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
    from clfd_bench.viz.video import VideoStyle

    p = subparsers.add_parser(
        "video",
        help="render a run's learned tasks executed in simulation to mp4",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run_dir", metavar="RUN_DIR", nargs="?", default=None,
                   help="a run directory of `clfd-bench train`")
    p.add_argument("--compare", nargs="+", metavar="RUN_DIR", default=None,
                   help="instead of RUN_DIR: several runs (e.g. every method of a "
                        "leaderboard), one task (--task) side by side in one video")
    p.add_argument("--task", default="all", metavar="T",
                   help="a task's index or name, or 'all' (default)")
    p.add_argument("--demo", type=int, default=0, help="start from this demo's start (default 0)")
    p.add_argument("--out", default="videos", help="output folder (default: videos/)")
    p.add_argument("--rerun", metavar="FILE.rrd", default=None,
                   help="also log the rendered rollouts to this rerun file")
    p.add_argument("--fps", type=float, default=20.0,
                   help="frames per simulated second, played in real time (default 20)")
    p.add_argument("--size", type=frame_size, default=(VideoStyle.width, VideoStyle.height),
                   metavar="WxH", help=f"frame size (default {VideoStyle.width}x"
                                       f"{VideoStyle.height}; with --compare the whole grid's)")
    p.add_argument("--shadows", action="store_true",
                   help="render shadows and reflections (much slower without a GPU)")
    p.add_argument("--no-text", action="store_true",
                   help="HelloWorld: do not write the 'hello world' text video")
    p.set_defaults(func=_run)
