"""Learned executions nearest each success bound (issue 38: every threshold signed by an observer).

    python eval/bound_audit.py run GRID OUT.jsonl [TASK ...]   # re-execute a grid's predictions
    python eval/bound_audit.py table OUT.jsonl [OUT.jsonl ...]   # the nearest ones, as markdown
    python eval/bound_audit.py whatif OUT.jsonl [...] [--drop [TASK:]CHECK] [--bound
        [TASK:]CHECK=VALUE] [--floor [TASK:]CHECK=VALUE] [--decisions]   # exec ACC if ...

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

`whatif` scores the same executions again under other success rules, without simulating: a
check dropped, its bound replaced, or raised to a floor (values in the check's unit as stored:
m, deg), for every task or for TASK only. An execution succeeds when it failed by no other
cause than its checks (a reflex, tracking loss or divergence still fails) and every remaining
check passes. It prints, per run and per method (median over its runs), exec ACC and REM as
recorded by the rules of today (rescored from the same lines, so equal to the run's own
leaderboard row) and under the rules given, and the ranking by exec ACC both ways.
`--decisions` does this for the open decisions of docs/decisions.md that rescoring can answer
(1a, 1b, 2 and 1b with 2), one table.
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


#: The placing scenes whose `release_offset` decision 1 of docs/decisions.md is about.
PLACING = ("bottle2shelf", "platestandingtolying", "wineglass", "pan2stove", "obstaclerotate")
#: Rule = (how, task or None, check, value): how is "drop", "bound" or "floor".
Rule = tuple[str, str | None, str, float]
#: The open decisions that rescoring answers (docs/decisions.md), as rules.
DECISIONS: dict[str, list[Rule]] = {
    "1a: release floor 3 cm": [("floor", t, "release_offset", 0.03) for t in PLACING],
    "1b: placed on the board (no end point)": [("drop", t, "release_offset", 0.0)
                                               for t in PLACING]
    + [("drop", "pouring", "pour_offset", 0.0)],
    "2: rack shift 5 cm": [("bound", "platestandingtolying", "rack_shift", 0.05)],
}
DECISIONS["1b and 2"] = DECISIONS["1b: placed on the board (no end point)"] + \
    DECISIONS["2: rack shift 5 cm"]


def parse_rule(how: str, text: str) -> Rule:
    """``[TASK:]CHECK`` (drop) or ``[TASK:]CHECK=VALUE`` (bound, floor) as a :data:`Rule`."""
    name, _, value = text.partition("=")
    task, _, check = name.rpartition(":")
    if not check or (how != "drop") != bool(value):
        form = "[TASK:]CHECK" if how == "drop" else "[TASK:]CHECK=VALUE"
        raise ValueError(f"--{how} {text!r}: expected {form}")
    try:
        number = float(value) if value else 0.0
    except ValueError:
        raise ValueError(f"--{how} {text!r}: {value!r} is not a number") from None
    return how, task or None, check, number


def _check_passes(c: dict, task: str, rules: list[Rule]) -> bool:
    bound, dropped = c["bound"], False
    for how, t, name, value in rules:
        if name != c["name"] or (t is not None and t != task):
            continue
        if how == "drop":
            dropped = True
        elif how == "bound":
            bound = value
        else:  # floor: only an upper bound is raised, only a lower bound lowered
            bound = max(bound, value) if c["op"] == "<=" else min(bound, value)
    if dropped or c["value"] is None:
        return dropped or c["passed"]
    return c["value"] <= bound if c["op"] == "<=" else c["value"] >= bound


def rescore(r: dict, rules: list[Rule]) -> bool:
    """Whether execution line ``r`` succeeds under ``rules`` (no rules: as recorded)."""
    if not r.get("checks") or r.get("kind") not in (None, "task"):
        return bool(r["success"])
    return all(_check_passes(c, r["task"], rules) for c in r["checks"])


def _runs(paths: list[Path]) -> dict[str, tuple[str, list[str], float | None, list[dict]]]:
    """The lines of ``paths`` by run, read once: run -> (method, its task order, the exec
    ACC its results.json records or None, its lines; a line written twice counts once)."""
    lines: dict[tuple, dict] = {}
    for p in paths:
        for line in p.read_text().splitlines():
            r = json.loads(line)
            lines[(r["run"], r["after"], r["task"], r["demo"])] = r
    by_run: dict[str, list[dict]] = defaultdict(list)
    for r in lines.values():
        by_run[r["run"]].append(r)
    out = {}
    for run, rs in sorted(by_run.items()):
        saved = load_run(Path(run))
        recorded = (saved.results.get("sim_cl_metrics") or {}).get("ACC")
        out[run] = (rs[0]["method"], list(saved.task_names),
                    None if recorded is None else float(recorded), rs)
    return out


def _rates(run: str, order: list[str], rs: list[dict], rules: list[Rule] | None) -> np.ndarray:
    """R [T, T] of one run's lines ``rs``: the success rate per (after, task) below the
    diagonal, as recorded (``rules`` None) or rescored under ``rules``."""
    n = len(order)
    sums, counts = np.zeros((n, n)), np.zeros((n, n))
    for r in rs:
        i, j = r["after"], order.index(r["task"])
        counts[i, j] += 1
        sums[i, j] += bool(r["success"]) if rules is None else rescore(r, rules)
    low = np.tril(np.ones((n, n), dtype=bool))
    if not counts[low].all():
        raise ValueError(f"{run}: the lines do not cover every (after, task) cell of its "
                         f"{n} tasks ({', '.join(order)}); run `bound_audit.py run` on "
                         "all its tasks first")
    with np.errstate(invalid="ignore"):
        return np.where(low, sums / counts, 0.0)


def _matrices(paths: list[Path], rules: list[Rule]
              ) -> dict[str, tuple[str, np.ndarray, np.ndarray, float | None]]:
    """Per run: (method, R today [T, T], R under ``rules``, the exec ACC its results.json
    records or None), success rates per (after, task)."""
    return {run: (method, _rates(run, order, rs, None), _rates(run, order, rs, rules), rec)
            for run, (method, order, rec, rs) in _runs(paths).items()}


def whatif(paths: list[Path], scenarios: dict[str, list[Rule]]) -> str:
    """The markdown tables of `whatif` (module docstring), one column pair per scenario."""
    from clfd_bench.metrics.cl import acc, rem

    names = list(scenarios)
    runs = _runs(paths)
    head = ("| run | method | recorded | exec ACC today | " + " | ".join(f"{n}" for n in names)
            + " |")
    out = ["Per run, exec ACC (REM); 'recorded': the run's own results.json, made with early-"
           "stopped rollouts (today's rules rescored must equal it under the same simulator):",
           "", head, "|---" * (4 + len(names)) + "|"]
    methods: dict[str, list[list[float]]] = defaultdict(list)
    for run, (method, order, recorded, rs) in runs.items():
        today = _rates(run, order, rs, None)
        cells = ["–" if recorded is None else f"{recorded:.2f}",
                 f"{acc(today):.2f} ({rem(today):.2f})"]
        vals = [acc(today)]
        for n in names:
            then = _rates(run, order, rs, scenarios[n])
            cells.append(f"{acc(then):.2f} ({rem(then):.2f})")
            vals.append(acc(then))
        methods[method].append(vals)
        out.append(f"| {Path(run).name} | {method} | " + " | ".join(cells) + " |")
    out += ["", "Per method, median exec ACC over its runs, and the ranking:", "",
            "| method | runs | today | " + " | ".join(names) + " |",
            "|---" * (3 + len(names)) + "|"]
    med = {m: np.median(np.array(v), axis=0) for m, v in methods.items()}
    for m, v in sorted(med.items(), key=lambda kv: -kv[1][0]):
        cells = [f"{v[0]:.2f}"] + [f"{x:.2f} ({x - v[0]:+.2f})" for x in v[1:]]
        out.append(f"| {m} | {len(methods[m])} | " + " | ".join(cells) + " |")
    for k, label in enumerate(["today", *names]):
        ranked = sorted(med, key=lambda m: -med[m][k])
        out.append(f"\nranking {label}: " + " > ".join(f"{m} {med[m][k]:.2f}" for m in ranked))
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
    p_what = sub.add_parser("whatif", help="exec ACC of the same executions under other rules")
    p_what.add_argument("files", nargs="+", type=Path)
    p_what.add_argument("--drop", action="append", default=[], metavar="[TASK:]CHECK")
    p_what.add_argument("--bound", action="append", default=[], metavar="[TASK:]CHECK=VALUE")
    p_what.add_argument("--floor", action="append", default=[], metavar="[TASK:]CHECK=VALUE")
    p_what.add_argument("--decisions", action="store_true",
                        help="the open decisions of docs/decisions.md, one column each")
    args = parser.parse_args(argv)
    if args.cmd == "whatif":
        try:
            rules = [parse_rule(how, text) for how in ("drop", "bound", "floor")
                     for text in getattr(args, how)]
        except ValueError as e:
            parser.error(str(e))
        scenarios = dict(DECISIONS) if args.decisions else {}
        if rules:
            scenarios["the rules given"] = rules
        if not scenarios:
            parser.error("whatif needs --drop, --bound, --floor or --decisions")
        missing = [str(f) for f in args.files if not f.is_file()]
        if missing:
            parser.error(f"no such file: {', '.join(missing)} (made by `bound_audit.py run`)")
        try:
            print(whatif(args.files, scenarios))
        except ValueError as e:
            print(f"error: {e}", file=sys.stderr)
            return 2
        return 0
    if args.cmd == "run":
        if not (args.grid / "runs").is_dir():
            parser.error(f"{args.grid} has no runs/ folder: pass a grid's --out folder")
        run_grid(args.grid, args.out, set(args.tasks))
    else:
        print(table(args.files))
    return 0


if __name__ == "__main__":
    sys.exit(main())
