"""A contact sheet of rollout videos: a few frames of each video, one row per video.

    python eval/video_sheet.py videos/rt9/*task*.mp4 --out docs/figures/robotasks9_hn_fast.png

Reads the mp4 files `clfd-bench video` writes, takes the frames at `--at` (fractions of each
video's length) and writes one PNG: a row per video (titled with its file name), a column per
moment.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("videos", nargs="+", type=Path, help="mp4 files")
    parser.add_argument("--at", default="0.02,0.45,0.98",
                        help="moments, fractions of each video's length (default 0.02,0.45,0.98)")
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    parser.add_argument("--dpi", type=int, default=80, help="resolution (default 80)")
    args = parser.parse_args(argv)
    missing = [str(v) for v in args.videos if not v.is_file()]
    if missing:
        parser.error(f"no such video: {missing}")
    try:
        moments = [float(a) for a in args.at.split(",")]
    except ValueError:
        parser.error(f"--at takes comma-separated fractions, got {args.at!r}")
    if not all(0.0 <= a <= 1.0 for a in moments):
        parser.error(f"--at fractions must be in [0, 1], got {moments}")

    import imageio.v2 as iio
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = []
    for path in args.videos:
        reader = iio.get_reader(str(path))
        n = reader.count_frames()
        rows.append([reader.get_data(min(n - 1, int(a * (n - 1)))) for a in moments])
        reader.close()
    h, w = rows[0][0].shape[:2]
    fig, axes = plt.subplots(len(rows), len(moments), squeeze=False,
                             figsize=(2.6 * len(moments) * w / h, 2.6 * len(rows)))
    for r, (path, frames) in enumerate(zip(args.videos, rows, strict=True)):
        for c, frame in enumerate(frames):
            ax = axes[r][c]
            ax.imshow(frame)
            ax.set_xticks([])
            ax.set_yticks([])
            if c == 0:
                ax.set_ylabel(path.stem, fontsize=9)
            if r == 0:
                ax.set_title(f"{100 * moments[c]:.0f} % of the video", fontsize=9)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=args.dpi)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
