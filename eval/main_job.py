"""The README's main job (``bash run.sh main``).

Today it runs the stages that exist: the data check. The execution-scored leaderboard
replaces this body when it lands (issue 5); until then this script says so instead of
pretending.
"""

from __future__ import annotations

import sys

from clfd_bench.cli.main import main

if __name__ == "__main__":
    print("[main job] stage 1/1: data check (clfd-bench data)")
    code = main(["data", *sys.argv[1:]])
    print(
        "[main job] the execution-scored leaderboard is not built yet (issues 3-5); "
        "only the data check ran."
    )
    sys.exit(code)
