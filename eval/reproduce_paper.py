"""Thin script: reproduce the paper's experiment grid and tables (same as ``clfd-bench paper``).

    python eval/reproduce_paper.py list                      # the 495 runs: counts, iterations,
                                                             # GPU/CPU time references
    python eval/reproduce_paper.py list --out results --runs # every run's status there
    python eval/reproduce_paper.py run --out results         # train what is missing (resumes),
                                                             # then write the tables
    python eval/reproduce_paper.py run --executor ray --address auto --workers 64 --out results
    python eval/reproduce_paper.py tables --out results      # tables from the finished runs

Every dimension narrows with ``--datasets``, ``--methods``, ``--nodes``, ``--seeds``,
``--orders``, ``--profile`` (default ``paper``), ``--tasks``, ``--no-sim``; e.g.
``run --datasets helloworld --seeds 0 --orders 0 --profile fast --out results``.
The tables (``paper_tables.md``/``.csv``/``.json``, ``paper_diff.png``) put ours, the paper's
value and ours − paper in every cell. Run ``python eval/reproduce_paper.py ACTION --help``.
"""

from __future__ import annotations

import sys

from clfd_bench.cli.main import main

if __name__ == "__main__":
    sys.exit(main(["paper", *sys.argv[1:]]))
