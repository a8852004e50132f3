"""Learned executions nearest each success bound (issue 38: every threshold signed by an observer).

    python eval/bound_audit.py run GRID OUT.jsonl [TASK ...]   # re-execute a grid's predictions
    python eval/bound_audit.py table OUT.jsonl [OUT.jsonl ...]   # the nearest ones, as markdown

`run` re-executes every saved prediction of the runs under ``GRID/runs/<dataset>/<method>/<run>/``
(``predictions/after_task_<i>.npz``; only the tasks named, default all) in the scene of its task,
with full rollouts (no early stop, so every check is measured at the end), and appends one JSON
line per (run, after task, task, demo): method, success, failure kind and the scene's
``info["checks"]``. It resumes: lines already in OUT are skipped. It only reads the grid (copy a
grid that is still being written first). Identical predictions of a run are executed once.

`table` prints, per task and numeric check, the two distinct executions nearest the bound on
each side (value, bound, method, after which task, demo, whether every other check passed),
then the executions that failed by that check alone: the verdicts an observer must be able to
sign (docs/execution.md, "Where every bound comes from").
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from clfd_bench.envs.registration import env_id_for
from clfd_bench.execution.cache import prediction_key
from clfd_bench.execution.env_pool import get_env
from clfd_bench.execution.execute import execute
from clfd_bench.execution.saved_run import load_run, load_run_predictions

_SCALE = {"m": (100.0, "cm"), "deg": (1.0, "deg"), "": (1.0, "")}


def run_grid(grid: Path, out: Path, tasks: set[str]) -> None:
    done = set()
    if out.exists():
        for line in out.read_text().splitlines():
            r = json.loads(line)
            done.add((r["run"], r["after"], r["task"], r["demo"]))
    with out.open("a") as f:
        for results in sorted(grid.glob("runs/*/*/*/results.json")):
            run_dir = results.parent
            run = load_run(run_dir)
            seen: dict[str, dict] = {}
            for i in range(len(run.task_names)):
                if not (run_dir / "predictions" / f"after_task_{i}.npz").exists():
                    continue
                preds = load_run_predictions(run_dir, i)
                for j in range(i + 1):
                    task = run.task_names[j]
                    if tasks and task not in tasks:
                        continue
                    env_id = env_id_for(run.dataset, task)
                    for d, traj in enumerate(preds[j]):
                        if (str(run_dir), i, task, d) in done:
                            continue
                        key = prediction_key(env_id, d, None, traj)
                        rec = {"method": run_dir.parent.name, "run": str(run_dir), "after": i,
                               "task": task, "demo": d}
                        if key not in seen:
                            if not np.isfinite(traj).all():
                                seen[key] = {"success": False, "kind": "diverged",
                                             "checks": None}
                            else:
                                r = execute(get_env(env_id), traj, d, stop_when_decided=False)
                                seen[key] = {"success": r.success, "kind": r.failure_kind,
                                             "checks": r.info.get("checks")}
                        rec.update(seen[key])
                        f.write(json.dumps(rec) + "\n")
                        f.flush()


def _is_flag(c: dict) -> bool:
    return c["op"] == ">=" and c["bound"] == 1.0 and c["unit"] == "" and \
        c["value"] in (0.0, 1.0) and not c["name"].startswith("beans")


def table(paths: list[Path]) -> str:
    rows, seen = [], set()
    for p in paths:
        for line in p.read_text().splitlines():
            r = json.loads(line)
            key = (r["run"], r["task"], r["demo"], json.dumps(r.get("checks"), sort_keys=True))
            if r.get("checks") and key not in seen:  # one row per distinct execution
                seen.add(key)
                rows.append(r)
    by = defaultdict(list)
    for r in rows:
        for c in r["checks"]:
            if c["value"] is None or _is_flag(c):
                continue
            margin = c["bound"] - c["value"] if c["op"] == "<=" else c["value"] - c["bound"]
            alone = all(o["passed"] for o in r["checks"] if o["name"] != c["name"])
            by[(r["task"], c["name"])].append((margin, c, r, alone))

    def show(c: dict, x: float) -> str:
        k, u = _SCALE[c["unit"]]
        return f"{x * k:.3g} {u}".strip()

    out = ["| task | check | side | value | bound | method | after task | demo | "
           "other checks |", "|---|---|---|---|---|---|---|---|---|"]
    for (task, name), items in sorted(by.items()):
        passing = sorted((x for x in items if x[0] >= 0), key=lambda x: x[0])[:2]
        failing = sorted((x for x in items if x[0] < 0), key=lambda x: -x[0])[:2]
        for side, chosen in (("pass", passing), ("fail", failing)):
            for _, c, r, alone in chosen:
                out.append(f"| {task} | {name} | {side} | {show(c, c['value'])} | {c['op']} "
                           f"{show(c, c['bound'])} | {r['method']} | {r['after']} | {r['demo']} "
                           f"| {'pass' if alone else 'fail'} |")
    out += ["", f"{len(rows)} distinct executions with checks.", "",
            "| task | check | failed by it alone | values (nearest first; method, after task, "
            "demo) |", "|---|---|---|---|"]
    for (task, name), items in sorted(by.items()):
        alone = sorted((x for x in items if x[0] < 0 and x[3]), key=lambda x: -x[0])
        if alone:
            vals = ", ".join(f"{show(c, c['value'])} vs {show(c, c['bound'])} ({r['method']} "
                             f"a{r['after']} d{r['demo']})" for _, c, r, _ in alone[:5])
            out.append(f"| {task} | {name} | {len(alone)} | {vals}"
                       f"{' ...' if len(alone) > 5 else ''} |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    p_run = sub.add_parser("run", help="re-execute a grid's predictions")
    p_run.add_argument("grid", type=Path)
    p_run.add_argument("out", type=Path)
    p_run.add_argument("tasks", nargs="*")
    p_table = sub.add_parser("table", help="the executions nearest each bound")
    p_table.add_argument("files", nargs="+", type=Path)
    args = parser.parse_args(argv)
    if args.cmd == "run":
        if not (args.grid / "runs").is_dir():
            parser.error(f"{args.grid} has no runs/ folder: pass a grid's --out folder")
        run_grid(args.grid, args.out, set(args.tasks))
    else:
        print(table(args.files))
    return 0


if __name__ == "__main__":
    sys.exit(main())
