"""The README's main job (``bash run.sh main``): a small execution-scored leaderboard.

HelloWorld (7 letters), the paper's seven CL methods, the ``fast`` profile, seed 0, task order 0,
every prediction also executed on the simulated Panda; then a video of the robot writing
"hello world" with the letters HN learned; last, the static results site (``clfd-bench
site``), whose ``index.html`` path it prints. Writes into ``results/`` (or ``--out``):
``leaderboard.md/.csv/.json``, the PNG figures, ``runs/``, ``videos/`` and ``site/``. Running
it again skips what is finished (a killed job resumes, the site's videos included). About
10–15 minutes on 2 cores (the site's 49 videos ~3 of them; 12 min 37 s on 2026-12-06).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from clfd_bench.leaderboard.grid import GridOptions, RunSpec
from clfd_bench.leaderboard.runner import run_leaderboard
from clfd_bench.runs import RunDir

METHODS = ["sg", "ft", "rep", "si", "mas", "hn", "chn"]


def main() -> int:
    """Runs the main job; a user's mistake (no dataset files and no network, no robot model, an
    unusable --out: :data:`clfd_bench.harness.validate.USER_ERRORS`) is one line and exit 2."""
    from clfd_bench.harness.validate import USER_ERRORS, one_line

    try:
        return _main()
    except USER_ERRORS as exc:
        print(f"[main job] error: {one_line(exc)}", file=sys.stderr)
        return 2


def _main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results", help="output directory (default results/)")
    parser.add_argument("--workers", type=int, default=max(1, os.cpu_count() or 1))
    args = parser.parse_args()
    out = Path(args.out)
    start = time.perf_counter()
    print(f"[main job] leaderboard: helloworld, {', '.join(METHODS)}, fast profile, seed 0, "
          f"with simulation -> {out}/", flush=True)
    result = run_leaderboard(
        dataset="helloworld", methods=METHODS, profile="fast", seeds=[0], orders=[0],
        out=out, options=GridOptions(workers=args.workers),
    )
    print((out / "leaderboard.md").read_text())
    hn = RunSpec("helloworld", "hn", "fast", 0, 0, "t", None, True)
    video = None
    if RunDir(hn.run_dir(out)).results_path.is_file():
        from clfd_bench.viz.video import VideoStyle, render_text_video

        print("[main job] rendering 'hello world' written with HN's learned letters", flush=True)
        # 480x360, not the 1280x720 default: measured here, the 1359-frame text renders in
        # 60 s at 480x360 and 113 s at 1280x720, a minute the 15-minute budget cannot spare.
        # `clfd-bench video RUN_DIR --task all` makes it at 1280x720 afterwards.
        video = render_text_video(hn.run_dir(out), demo=0, out_dir=out / "videos",
                                  style=VideoStyle(width=480, height=360, fps=8.0))
    from clfd_bench.site import build_site

    print("[main job] writing the results site (video wall: every method's last model, every "
          "task)", flush=True)
    site = build_site(out, out / "site", workers=args.workers,
                      log=lambda line: print(line, flush=True))
    print(f"[main job] done in {time.perf_counter() - start:.0f} s: {out / 'leaderboard.md'}, "
          f"figures in {out}/, video {video}, site {site.seconds:.0f} s")
    print(site.index.resolve())
    return 1 if result.failed or site.video_errors else 0


if __name__ == "__main__":
    sys.exit(main())
