"""``clfd-bench bench sim``: simulated seconds per wall second of each env, IK included.

Runs demo 0 of each env through `clfd_bench.execution.rollout` in this process (one core; MuJoCo and
mink are single-threaded, torch is not involved) and reports x real time against the targets
(>= 50x, >= 30x for Pouring, MatFolding and Scoop), plus the IK and bare-physics cost per
60 Hz step.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.execution.bench import DEFAULT_ENVS, bench_env, machine_note
    from clfd_bench.progress import progress

    if args.env == ["all"]:
        from clfd_bench.envs.registration import env_specs

        env_ids = list(env_specs())
    else:
        env_ids = args.env or list(DEFAULT_ENVS)
    note = machine_note()
    rows: list[dict[str, Any]] = []
    errors: dict[str, str] = {}
    for env_id in progress(env_ids, desc="bench sim"):
        try:
            rows.append(bench_env(env_id, demo=args.demo, repeats=args.repeats))
        except Exception as exc:  # reported per env
            errors[env_id] = f"{type(exc).__name__}: {exc}"
            if not args.json:
                print(f"{env_id}: FAILED: {errors[env_id]}", file=sys.stderr)
            continue
        if not args.json:
            r = rows[-1]
            flag = "ok" if r["meets_target"] else f"BELOW {r['target_x']:.0f}x"
            print(f"{env_id:34s} {r['x_realtime']:7.1f}x real time (CPU time: "
                  f"{r['x_realtime_cpu']:.1f}x) ({r['sim_s']:.1f} s sim in "
                  f"{r['wall_s']:.2f} s; IK {r['ik_us_per_step']:.0f} us/step, physics "
                  f"{r['physics_us_per_step']:.0f} us/step [{r['physics_substeps']} substeps]) "
                  f"{flag}")
    if args.json:
        print(json.dumps({"machine": note, "results": rows, "errors": errors}, indent=1))
    else:
        print(f"machine: {note}")
    return 1 if errors else 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``sim`` benchmark (under ``clfd-bench bench``)."""
    p = subparsers.add_parser("sim", help="simulation speed of each env (x real time, IK included)",
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", action="append", metavar="ID",
                   help="env id (repeatable) or 'all'; default: one env per scene kind")
    p.add_argument("--demo", type=int, default=0, help="demo to roll out (default 0)")
    p.add_argument("--repeats", type=int, default=3,
                   help="rollouts per env; the fastest counts (default 3)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=_run)
