"""``clfd-bench replay``: replay dataset demonstrations (as they are, or perturbed by families
that must succeed or must fail) through environments and print the env × family confusion
table. Exits 1 when a cell disagrees with its family's expectation.

Examples::

    clfd-bench replay --env clfd/HelloWorld-h-v3
    clfd-bench replay --env clfd/LASA-Angle-v3 --demos 0,1 --perturb reverse,mirror
    clfd-bench replay --env robotasks --perturb all --json table.json   # env x family table
    clfd-bench replay --env all                          # every registered env
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

__all__ = ["register"]

_GROUPS = ("all", "writing", "robotasks")


def _resolve_envs(names: list[str]) -> list[str]:
    from clfd_bench.envs.registration import NAMESPACE, ROBOTASKS_ENVS, env_specs

    specs = env_specs()
    out: list[str] = []
    for name in names:
        if name == "all":
            out += list(specs)
        elif name == "writing":
            out += [i for i in specs if "HelloWorld" in i or "LASA" in i]
        elif name == "robotasks":
            out += [i for i in specs if i.split("/")[1].rsplit("-", 1)[0] in ROBOTASKS_ENVS]
        elif name in specs:
            out.append(name)
        elif f"{NAMESPACE}/{name}" in specs:  # "PlateStacking-v3", as dm.load takes it
            out.append(f"{NAMESPACE}/{name}")
        elif current := [i for i in specs if i.split("/", 1)[1].rsplit("-v", 1)[0]
                         == name.split("/")[-1]]:  # no version: the current one
            out.append(current[-1])
        else:
            from clfd_bench.harness.run_config import suggest
            from clfd_bench.harness.validate import InputError

            bare = [i.split("/", 1)[1] for i in specs]
            raise InputError(f"unknown --env {name!r}{suggest(name.split('/')[-1], bare)}; "
                             f"valid: {', '.join(_GROUPS)} or an env id (with or without "
                             f"'{NAMESPACE}/'): {', '.join(bare)}")
    return list(dict.fromkeys(out))


def _parse_demos(text: str) -> list[int] | None:
    if text == "all":
        return None
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        from clfd_bench.harness.validate import InputError

        raise InputError(f"--demos must be 'all' or comma-separated integers, got {text!r}"
                         ) from None


def _families(text: str) -> list[str] | None:
    """--perturb value -> family names (None: every family that applies to each env)."""
    from clfd_bench.execution.perturb import FAMILIES

    if text == "all":
        return None
    names = [x.strip() for x in text.split(",") if x.strip()]
    bad = [n for n in names if n not in FAMILIES]
    if bad or not names:
        from clfd_bench.harness.run_config import suggest
        from clfd_bench.harness.validate import InputError

        hint = suggest(bad[0], list(FAMILIES)) if bad else ""
        raise InputError(f"unknown --perturb {', '.join(bad) or text!r}{hint}; valid: all or "
                         f"comma-separated names of {', '.join(FAMILIES)}")
    return names


def _run(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from clfd_bench.execution.replay import (
        confusion_table,
        families_for,
        format_confusion,
        replay,
    )
    from clfd_bench.harness.validate import check_robot_model
    from clfd_bench.io import atomic_write_json
    from clfd_bench.progress import progress

    env_ids = _resolve_envs(args.env)
    demos = _parse_demos(args.demos)
    check_robot_model()  # one line naming MENAGERIE_ROOT, not one error per env
    wanted = _families(args.perturb)
    rows: list[dict[str, Any]] = []
    errors: dict[str, str] = {}
    for env_id in progress(env_ids, desc="envs"):
        try:
            env = gym.make(env_id)
        except Exception as exc:  # reported per env; one broken env hides nothing
            errors[env_id] = f"{type(exc).__name__}: {exc}"
            print(f"{env_id}: cannot make env: {errors[env_id]}", file=sys.stderr)
            continue
        try:
            applicable = families_for(env.unwrapped)
            families = applicable if wanted is None else [f for f in wanted if f in applicable]
            for family in families:
                for rec in replay(env_id, demos, family, settle_s=args.settle, env=env):
                    rows.append(rec.to_json())
                    if args.verbose:
                        status = "success" if rec.success else "FAIL"
                        reason = rec.info.get("failure_reason")
                        print(f"{env_id} demo {rec.demo} [{family}, should {rec.expect}]: "
                              f"{status}{f' ({reason})' if reason else ''} "
                              f"({rec.sim_s:.1f} s sim in {rec.wall_s:.2f} s)", file=sys.stderr)
        finally:
            env.close()
    table = confusion_table(rows)
    if args.json:
        atomic_write_json(args.json, {"results": rows, "confusion": table, "errors": errors})
    print(format_confusion(table))
    if args.json:
        print(f"wrote {args.json}", file=sys.stderr)
    disagree = sum(not c["ok"] for cells in table.values() for c in cells.values())
    if disagree:
        print(f"{disagree} cell(s) disagree with their family's expectation (marked ✗)",
              file=sys.stderr)
    return 1 if errors or disagree else 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``replay`` subcommand."""
    p = subparsers.add_parser(
        "replay", help="replay dataset demos through simulated envs and print per-demo success",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", action="append", required=True, metavar="ID",
                   help="env id (e.g. clfd/HelloWorld-h-v3), or 'all', 'writing', 'robotasks'; "
                        "repeatable")
    p.add_argument("--demos", default="all", help="'all' (default) or comma-separated indices")
    p.add_argument("--perturb", default="demo", metavar="FAMILIES",
                   help="'all' or comma-separated perturbation families (default 'demo'): "
                        "must succeed: demo, slower, faster, noise, start-offset; must fail: "
                        "reverse, other-task, stop-early, shortcut, rush-wait, mirror, drift, "
                        "teleport, frozen-orientation (poses only); see "
                        "clfd_bench.execution.perturb")
    p.add_argument("--settle", type=float, default=1.0, metavar="S",
                   help="seconds the scene settles after the trajectory (default 1.0)")
    p.add_argument("--json", metavar="FILE", default=None,
                   help="also write every record and the confusion table to FILE (JSON)")
    p.add_argument("-v", "--verbose", action="store_true", help="one line per replayed demo")
    p.set_defaults(func=_run)
