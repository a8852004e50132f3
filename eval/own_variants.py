"""Wrong and right trajectories beyond the replay families, for the RoboTasks(9) scenes.

    python eval/own_variants.py [ENV ...]      # default: every env with variants

Each variant (`clfd_bench.execution.task_variants`) is built from every demo and executed with
the motion-limit checks on; the table says how many of the 9 succeed and why the others failed.
"expect" is what an observer would say. Every scene gets the nine `NEARBY` edits first (5 mm,
3 degrees, another clock; expected to succeed). About 80 s per env on one core.
"""

from __future__ import annotations

import argparse
import sys

from clfd_bench.execution.task_variants import VARIANTS, run_variants


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("envs", nargs="*", default=list(VARIANTS), help=f"of {list(VARIANTS)}")
    args = parser.parse_args(argv)
    unknown = [e for e in args.envs if e not in VARIANTS]
    if unknown:
        parser.error(f"no variants for {unknown}; valid: {list(VARIANTS)}")
    print("| env | variant | expect | succeeded | why the others failed |")
    print("|---|---|---|---|---|")
    for env_id in args.envs:
        for row in run_variants(env_id):
            reasons = ", ".join(f"{k} {v}" for k, v in sorted(row.failures.items())) or "-"
            print(f"| {env_id.split('/')[1]} | {row.name} | {row.expect} | "
                  f"{row.succeeded}/{row.demos} | {reasons} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
