"""``clfd-bench bench sim``: where a control step's time goes, per env.

Runs demo 0 of each env through `clfd_bench.execution.rollout` (its lean path, as the harness
does) in this process (one core; MuJoCo and mink are single-threaded, torch is not involved)
and reports per 60 Hz control step: the physics (MuJoCo's steps inside the rollout, contacts
included), the IK, the rest (our own Python), and the ratio step / (physics + IK) against the
target (<= 1.4); x real time too, for reference.
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
        _check_ids(env_ids)
    note = machine_note()
    rows: list[dict[str, Any]] = []
    errors: dict[str, str] = {}
    if not args.json:
        print(f"{'env':28s} {'step':>6s} {'physics':>8s} {'IK':>5s} {'rest':>6s} {'ratio':>6s} "
              f"{'x real':>7s}   (us per control step; ratio = step / (physics + IK))")
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
            flag = "ok" if r["meets_target"] else f"OVER {r['ratio_target']:g}"
            print(f"{env_id:28s} {r['step_us']:6.0f} {r['physics_us']:8.0f} {r['ik_us']:5.0f} "
                  f"{r['rest_us']:6.0f} {r['ratio']:6.2f} {r['x_realtime']:6.1f}x  {flag}")
    if args.json:
        print(json.dumps({"machine": note, "results": rows, "errors": errors}, indent=1))
    else:
        print(f"machine: {note}")
    return 1 if errors else 0


def _check_ids(env_ids: list[str]) -> None:
    """SystemExit naming every unknown id, the closest valid one and all valid ids, before
    anything runs."""
    import clfd_bench.envs  # noqa: F401 - registers the ids
    from clfd_bench.envs.registration import registered_env_ids
    from clfd_bench.harness.run_config import suggest

    valid = registered_env_ids()
    unknown = [i for i in env_ids if i not in valid]
    if unknown:
        named = "; ".join(f"{i!r}{suggest(i, valid)}" for i in unknown)
        raise SystemExit(f"clfd-bench bench sim: unknown env id {named}. Valid ids "
                         f"(or --env all): {', '.join(valid)}")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``sim`` benchmark (under ``clfd-bench bench``)."""
    p = subparsers.add_parser("sim", help="where a control step's time goes: physics, IK, rest",
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", action="append", metavar="ID",
                   help="env id (repeatable) or 'all'; default: one env per scene kind")
    p.add_argument("--demo", type=int, default=0, help="demo to roll out (default 0)")
    p.add_argument("--repeats", type=int, default=3,
                   help="rollouts per env; the fastest counts (default 3)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=_run)
