"""Re-executes a saved run's predictions of some tasks with the current code, beside the verdicts
the run's own `results.json` holds (the code that evaluated it), to see what a criterion change
does to learned skills.

    python eval/reexecute_tasks.py RUN_DIR --tasks matfolding,scoop [--json OUT.json]

Every evaluation point (after task i, task j <= i in `--tasks`, demo d) is executed as
`clfd-bench evaluate` does (`clfd_bench.execution.execute.execute` in `get_env(env id)`, motion
limits on); identical predictions (SG, HN and CHN keep a task's after later tasks) run once.
The run directory is only read: copy it first if another process may write it. Prints, per
task, the successes after the last task, right after learning the task and over all points,
before -> after, and the verdicts nearest each check's bound (`info["checks"]`, rollouts that
ran to the end); `--json` also writes every point with its checks.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import numpy as np

from clfd_bench.envs.registration import env_id_for
from clfd_bench.execution.cache import prediction_key
from clfd_bench.execution.env_pool import get_env
from clfd_bench.execution.execute import execute
from clfd_bench.execution.saved_run import load_run, load_run_predictions


def reexecute(run_dir: str, tasks: list[str]) -> list[dict[str, Any]]:
    """One row per evaluation point of `tasks`: after, task, demo, before (the run's verdict),
    success, failure_kind, checks (the current code's)."""
    run = load_run(run_dir)
    names, m = run.task_names, run.num_learned
    unknown = [t for t in tasks if t not in names]
    if unknown:
        raise SystemExit(f"{run_dir} has no task {unknown}; its tasks: {names}")
    before = run.results.get("success")
    if before is None:
        raise SystemExit(f"{run_dir} was never executed (no success in results.json); run "
                         "`clfd-bench evaluate` on it first")
    done: dict[str, dict[str, Any]] = {}
    rows = []
    for i in range(m):
        preds = load_run_predictions(run_dir, i)
        for j, name in enumerate(names[: i + 1]):
            if name not in tasks:
                continue
            env_id = env_id_for(run.dataset, name)
            for d, traj in enumerate(preds[j]):
                key = prediction_key(env_id, d, None, traj)
                if key not in done:
                    if not np.isfinite(traj).all():
                        done[key] = {"success": False, "failure_kind": "nonfinite",
                                     "checks": None}
                    else:
                        r = execute(get_env(env_id), traj, d)
                        done[key] = {"success": r.success, "failure_kind": r.failure_kind,
                                     "checks": r.info.get("checks")}
                rows.append({"after": i, "task": name, "demo": d,
                             "before": bool(before[i][j][d]), **done[key]})
    return rows


def _count(rows: list[dict[str, Any]], key: str) -> str:
    return f"{sum(bool(r[key]) for r in rows)}/{len(rows)}"


def report(rows: list[dict[str, Any]], tasks: list[str]) -> str:
    """The text `main` prints."""
    lines = []
    last = max(r["after"] for r in rows)
    for task in tasks:
        rs = [r for r in rows if r["task"] == task]
        first = min(r["after"] for r in rs)
        parts = []
        for label, sel in (("after the last task", [r for r in rs if r["after"] == last]),
                           ("right after learning it", [r for r in rs if r["after"] == first]),
                           ("all points", rs)):
            parts.append(f"{label} {_count(sel, 'before')} -> {_count(sel, 'success')}")
        lines.append(f"{task}: " + "; ".join(parts))
        near: dict[tuple[str, str], tuple[float, dict[str, Any], dict[str, Any]]] = {}
        for r in rs:
            if r["failure_kind"] not in (None, "task"):
                continue  # ended early (reflex, collision, ...): its checks were not decided
            for c in r["checks"] or []:
                flag = c["op"] == ">=" and c["bound"] == 1.0 and c["value"] in (0.0, 1.0)
                if c["value"] is None or flag:  # yes/no checks have no nearness
                    continue
                margin = c["bound"] - c["value"] if c["op"] == "<=" else c["value"] - c["bound"]
                k = (c["name"], "passed" if c["passed"] else "failed")
                if k not in near or abs(margin) < abs(near[k][0]):
                    near[k] = (margin, c, r)
        for (name, side), (_, c, r) in sorted(near.items()):
            lines.append(f"    {name} nearest {side}: {c['value']:.4g} vs {c['bound']:.4g} "
                         f"{c['unit']} (after task {r['after'] + 1}, demo {r['demo']})")
        kinds: dict[str, int] = {}
        for r in rs:
            if not r["success"]:
                failed = ",".join(c["name"] for c in r["checks"] or [] if not c["passed"])
                k = r["failure_kind"] + (f" ({failed})" if r["failure_kind"] == "task" else "")
                kinds[k] = kinds.get(k, 0) + 1
        lines.append(f"    failures now: {kinds or '-'}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", help="a run directory of `clfd-bench train` (executed)")
    parser.add_argument("--tasks", required=True, help="comma-separated task names")
    parser.add_argument("--json", help="also write every point with its checks here")
    args = parser.parse_args(argv)
    tasks = [t for t in args.tasks.split(",") if t]
    rows = reexecute(args.run_dir, tasks)
    print(report(rows, tasks))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"run": args.run_dir, "rows": rows}, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
