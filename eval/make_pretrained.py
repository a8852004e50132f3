"""Builds a pretrained bundle (``clfd-bench pretrained``) from a finished leaderboard folder.

    python eval/make_pretrained.py results/ --out pretrained/helloworld-fast.tar.xz

``results/`` is what the main job (``bash run.sh main``) or ``clfd-bench leaderboard`` wrote;
every run must be done under the installed simulator (run the job again first if not: it
only re-executes). The bundle holds each run's results, checkpoint (tensors only), every
predictions file and execution cache, and the tables and figures written again by the
leaderboard code (no videos: ``clfd-bench video`` makes them). The archive is
deterministic: the same results give the same bytes. Prints its size and sha256; pin both in
``clfd_bench.pretrained.BUNDLES``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from clfd_bench.pretrained import PretrainedError, build_bundle


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", help="a finished leaderboard folder (e.g. results/)")
    parser.add_argument("--out", default="pretrained/helloworld-fast.tar.xz",
                        help="the archive to write (default pretrained/helloworld-fast.tar.xz)")
    args = parser.parse_args()
    start = time.perf_counter()
    try:
        sha = build_bundle(args.results, args.out)
    except PretrainedError as exc:
        print(f"make_pretrained: error: {exc}", file=sys.stderr)
        return 2
    size = Path(args.out).stat().st_size
    print(f"{args.out}: {size} bytes ({size / 1e6:.2f} MB), built in "
          f"{time.perf_counter() - start:.0f} s")
    print(f'pin in clfd_bench/pretrained.py: sha256="{sha}", size={size}')
    return 0


if __name__ == "__main__":
    sys.exit(main())
