"""Thin script: the same as ``clfd-bench leaderboard`` (run ``--help`` for the options).

    python eval/leaderboard.py --dataset helloworld --methods sg,ft,hn --profile fast --out results/
"""

from __future__ import annotations

import sys

from clfd_bench.cli.main import main

if __name__ == "__main__":
    sys.exit(main(["leaderboard", *sys.argv[1:]]))
