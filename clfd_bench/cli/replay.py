"""``clfd-bench replay``: replay dataset demonstrations through environments, print success.

Examples::

    clfd-bench replay --env clfd/HelloWorld-h-v0
    clfd-bench replay --env clfd/LASA-Angle-v0 --demos 0,1 --perturb reverse --json
    clfd-bench replay --env writing --perturb all        # every writing env, all perturbations
    clfd-bench replay --env all                          # every registered env
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

__all__ = ["register"]

_GROUPS = ("all", "writing", "robotasks")


def _resolve_envs(names: list[str]) -> list[str]:
    from clfd_bench.envs.registration import ROBOTASKS_ENVS, env_specs

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
        else:
            raise SystemExit(f"unknown env {name!r}; valid: {', '.join(_GROUPS)} or one of "
                             f"{', '.join(specs)}")
    return list(dict.fromkeys(out))


def _parse_demos(text: str) -> list[int] | None:
    if text == "all":
        return None
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise SystemExit(f"--demos must be 'all' or comma-separated integers, got {text!r}"
                         ) from None


def _run(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from clfd_bench.progress import progress
    from clfd_bench.sim.replay import PERTURBATIONS, replay

    env_ids = _resolve_envs(args.env)
    demos = _parse_demos(args.demos)
    perturbs: list[str | None]
    if args.perturb == "all":
        perturbs = [None, *PERTURBATIONS]
    elif args.perturb == "none":
        perturbs = [None]
    else:
        perturbs = [args.perturb]
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
            for perturb in perturbs:
                for rec in replay(env_id, demos, perturb, settle_s=args.settle, env=env):
                    rows.append(rec.to_json())
                    if not args.json:
                        status = "success" if rec.success else "FAIL"
                        extra = {k: v for k, v in rec.to_json()["info"].items()
                                 if k in ("dtw", "ink_fraction", "goal_distance",
                                          "failure_reason", "letter_dtw") and v is not None}
                        print(f"{env_id} demo {rec.demo} [{perturb or 'demo'}]: {status} "
                              f"{extra} ({rec.sim_s:.1f} s sim in {rec.wall_s:.2f} s)")
        finally:
            env.close()
    summary = _summary(rows)
    if args.json:
        print(json.dumps({"results": rows, "summary": summary, "errors": errors}, indent=1))
    else:
        for key, s in summary.items():
            want = "succeed" if key.endswith("[demo]") else "fail"
            print(f"{key}: {s['successes']}/{s['n']} succeeded (should {want})")
    return 1 if errors else 0


def _summary(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for r in rows:
        key = f"{r['env']} [{r['perturb'] or 'demo'}]"
        s = out.setdefault(key, {"n": 0, "successes": 0})
        s["n"] += 1
        s["successes"] += int(r["success"])
    for s in out.values():
        s["success_rate"] = s["successes"] / s["n"]
    return out


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``replay`` subcommand."""
    p = subparsers.add_parser(
        "replay", help="replay dataset demos through simulated envs and print per-demo success",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", action="append", required=True, metavar="ID",
                   help="env id (e.g. clfd/HelloWorld-h-v0), or 'all', 'writing', 'robotasks'; "
                        "repeatable")
    p.add_argument("--demos", default="all", help="'all' (default) or comma-separated indices")
    p.add_argument("--perturb", default="none",
                   choices=["none", "reverse", "other-task", "truncate", "all"],
                   help="replay wrong trajectories (should fail): the time-reversed demo, demo j "
                        "of the next task of the dataset, or the demo cut at 50%%; 'all' runs "
                        "the demos and every perturbation")
    p.add_argument("--settle", type=float, default=1.0, metavar="S",
                   help="seconds the scene settles after the trajectory (default 1.0)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=_run)
