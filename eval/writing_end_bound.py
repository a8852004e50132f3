"""The writing end-point bound on real predictions: exec ACC before and after, the flipped
verdicts, the verdicts nearest the bound, and a picture of the nearest on each side.

    python eval/writing_end_bound.py --before BEFORE_ROOT --after AFTER_ROOT \
        --checks CHECKS_DIR [--figure docs/figures/writing_end_bound.png]
    python eval/writing_end_bound.py --replay TABLE.json

BEFORE_ROOT and AFTER_ROOT are grid folders (`<root>/runs/<dataset>/<method>/<run>/results.json`)
executed under the old and the new criterion (AFTER_ROOT is a copy of BEFORE_ROOT re-executed
by `eval/writing_checks.py`, which wrote CHECKS_DIR). Prints markdown tables.

`--replay` reads a `clfd-bench replay --json` table of writing envs and prints its confusion
table twice: as judged (the derived end bound) and with every `goal` check re-judged against
the former constant bound (1 cm on the board; 3 mm for a letter of the text, judged in letter
units). Nothing else of the criterion changed (the dwell radius is still 1 cm), so the second
table is the verdict the former criterion gives on the same rollouts.
"""

from __future__ import annotations

import argparse
import json
import re
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np


def _runs(root: Path) -> dict[str, Path]:
    return {p.parent.parent.name + "/" + p.parent.name: p.parent
            for p in sorted(root.glob("runs/*/*/*/results.json"))}


def _goal_check(checks: list[dict[str, Any]]) -> dict[str, Any] | None:
    for c in checks or []:
        if c["name"] == "goal":
            return c
    return None


#: The former end bound, metres on the board (the text's letters: 1 cm in letter units).
OLD_GOAL_M = 0.01
OLD_GOAL_TEXT_M = 0.003


def _old_success(info: dict[str, Any], text: bool) -> bool:
    """The former criterion's verdict on a rollout judged by the new one."""
    if info.get("failure"):  # refused or blown up: no ink verdict
        return False
    checks = info.get("checks") or []
    old = OLD_GOAL_TEXT_M if text else OLD_GOAL_M
    for c in checks:
        if c["name"].endswith("goal"):
            if c["value"] is None or c["value"] > old:
                return False
        elif not c["passed"]:
            return False
    return bool(checks)


def replay_tables(path: Path) -> None:
    doc = json.loads(path.read_text())
    families = list(dict.fromkeys(r["family"] for r in doc["results"]))
    envs = list(dict.fromkeys(r["env"] for r in doc["results"]))
    expect = {r["family"]: r["expect"] for r in doc["results"]}
    flips = []
    for label in ("before (end bound 1 cm)", "after (derived end bound)"):
        print(f"\n{label}\n")
        print("| env | " + " | ".join(f"{f} ({expect[f][0].upper()})" for f in families) + " |")
        print("|---" * (len(families) + 1) + "|")
        for env in envs:
            cells = []
            for fam in families:
                recs = [r for r in doc["results"] if r["env"] == env and r["family"] == fam]
                used = [r for r in recs if r.get("applicable", True)]
                text = env.split("/")[-1].startswith("HelloWorld-v")
                ok = [r["success"] if label.startswith("after") else
                      _old_success(r["info"], text) for r in used]
                if label.startswith("after"):
                    flips += [(env, fam, r["demo"]) for r in used
                              if r["success"] != _old_success(r["info"], text)]
                n, k = len(used), sum(ok)
                bad = (k < n) if expect[fam] == "succeed" else (k > 0.05 * n)
                na = f" ({len(recs) - n} n/a)" if len(recs) > n else ""
                cells.append(f"{k}/{n}{na}{' ✗' if bad else ''}")
            print(f"| {env.split('/')[-1]} | " + " | ".join(cells) + " |")
    print(f"\nverdicts that differ (env, family, demo): {flips}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path)
    parser.add_argument("--after", type=Path)
    parser.add_argument("--checks", type=Path)
    parser.add_argument("--figure", type=Path, default=None)
    parser.add_argument("--nearest", type=int, default=5)
    parser.add_argument("--replay", type=Path, default=None)
    parser.add_argument("--case", action="append", default=[],
                        help="method,letter,demo,after_task of a rollout to draw in "
                             "--case-figure (repeatable)")
    parser.add_argument("--case-figure", type=Path, default=None)
    args = parser.parse_args(argv)
    if args.replay is not None:
        replay_tables(args.replay)
        return 0
    if args.before is None or args.after is None or args.checks is None:
        parser.error("--before, --after and --checks are required (or --replay)")

    before, after = _runs(args.before), _runs(args.after)
    print("| method | exec ACC before | exec ACC after | flipped to success | flipped to "
          "failure | failed before only on the end point (its value) |")
    print("|---|---|---|---|---|---|")
    points: list[dict[str, Any]] = []
    for key, run_after in after.items():
        method = key.split("/")[0]
        old = json.loads((before[key] / "results.json").read_text())
        new = json.loads((run_after / "results.json").read_text())
        stem = f"{run_after.parent.name}_{run_after.name}"
        # Runs re-executed by `clfd-bench evaluate` alone (no checks kept) still count in the
        # ACC table; they have no rows among the nearest verdicts.
        checks_file = args.checks / f"{stem}.json"
        records = json.loads(checks_file.read_text()) if checks_file.exists() else []
        by_point = {(r["after_task"], r["task"], r["demo"]): r for r in records}
        tasks = new["tasks"]
        up, down, only_goal = 0, 0, []
        flips: Counter = Counter()
        for i, row in enumerate(old["success"]):
            for j, cell in enumerate(row):
                if cell is None:
                    continue
                for d, ok_old in enumerate(cell):
                    ok_new = bool(new["success"][i][j][d])
                    rec = by_point.get((i, tasks[j], d), {"checks": None})
                    reason = old["sim"]["failure_reason"][i][j][d]
                    goal = _goal_check(rec["checks"])
                    others = [c["name"] for c in rec["checks"] or []
                              if not c["passed"] and c["name"] != "goal"]
                    m = re.search(r"goal_distance=([0-9.e+-]+)", reason or "")
                    if m and not ok_old and not others and rec["checks"]:
                        only_goal.append(float(m.group(1)))
                    if ok_new and not ok_old:
                        up += 1
                        flips[tasks[j]] += 1
                    elif ok_old and not ok_new:
                        down += 1
                    points.append({"method": method, "after": i, "task": tasks[j], "demo": d,
                                   "stem": stem, "ok_old": bool(ok_old), "ok_new": ok_new,
                                   "goal": goal, "others": others})
        acc_old, acc_new = old["sim_cl_metrics"]["ACC"], new["sim_cl_metrics"]["ACC"]
        span = (f"{len(only_goal)} ({min(only_goal) * 100:.2f}-{max(only_goal) * 100:.2f} cm)"
                if only_goal else "0" if records else "n/a (no checks kept)")
        per_task = ", ".join(f"{t} {n}" for t, n in sorted(flips.items()))
        print(f"| {method.upper()} | {acc_old:.3f} | {acc_new:.3f} | {up}"
              f"{f' ({per_task})' if per_task else ''} | {down} | {span} |")

    # Distinct rollouts nearest the bound (SG, HN, CHN repeat a task's prediction after later
    # tasks: keep one row per method, letter, demo and value).
    seen, rows = set(), []
    for p in points:
        g = p["goal"]
        if g is None or g["value"] is None:
            continue
        k = (p["method"], p["task"], p["demo"], round(g["value"], 6))
        if k in seen:
            continue
        seen.add(k)
        rows.append({**p, "value": g["value"], "bound": g["bound"],
                     "margin": g["bound"] - g["value"]})
    print()
    print("| side | method | letter | demo | after task | end distance | bound | other "
          "failed checks | verdict |")
    print("|---|---|---|---|---|---|---|---|---|")
    def nearest_each(side: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """One row per method, letter and demo (its nearest to the bound)."""
        kept, out = set(), []
        for r in side:
            if (r["method"], r["task"], r["demo"]) not in kept:
                kept.add((r["method"], r["task"], r["demo"]))
                out.append(r)
        return out

    passing = nearest_each(sorted((r for r in rows if r["margin"] >= 0),
                                  key=lambda r: r["margin"]))
    failing = nearest_each(sorted((r for r in rows if r["margin"] < 0),
                                  key=lambda r: -r["margin"]))
    for side, chosen in (("pass", passing[: args.nearest]), ("fail", failing[: args.nearest])):
        for r in chosen:
            print(f"| {side} | {r['method'].upper()} | {r['task']} | {r['demo']} | {r['after']} "
                  f"| {r['value'] * 100:.2f} cm | {r['bound'] * 100:.2f} cm | "
                  f"{', '.join(r['others']) or '-'} | "
                  f"{'success' if r['ok_new'] else 'failure'} |")
    if args.figure is not None and passing and failing:
        _figure(args.figure, [(passing[0], "nearest passing"), (failing[0], "nearest failing")],
                args.checks)
    if args.case_figure is not None and args.case:
        cases = []
        for spec in args.case:
            method, letter, demo, after = spec.split(",")
            (r,) = [r for r in rows if (r["method"], r["task"], r["demo"], r["after"])
                    == (method, letter, int(demo), int(after))]
            cases.append((r, "case"))
        _figure(args.case_figure, cases, args.checks)
    return 0


def _figure(path: Path, cases: list[tuple[dict[str, Any], str]], checks_dir: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from clfd_bench.data import load_dataset

    ds = load_dataset("helloworld")
    fig, axes = plt.subplots(1, len(cases), figsize=(4.5 * len(cases), 4.6), squeeze=False)
    for ax, (r, title) in zip(axes[0], cases, strict=True):
        ink = np.load(checks_dir / f"{r['stem']}_ink.npz")[
            f"a{r['after']}_t{r['task']}_d{r['demo']}"]
        task = next(t for t in ds.tasks if t.name == r["task"])
        demos, goal = np.asarray(task.demos), np.asarray(task.goal)
        for k, demo in enumerate(demos):
            ax.plot(demo[:, 0] * 100, demo[:, 1] * 100, color="0.85", lw=0.8,
                    label="other demos" if k == 0 else None)
        tgt = demos[r["demo"]]
        ax.plot(tgt[:, 0] * 100, tgt[:, 1] * 100, color="k", lw=1.2,
                label=f"target demo {r['demo']}")
        ax.plot(ink[:, 0] * 100, ink[:, 1] * 100, color="tab:red", lw=1.2, label="ink")
        ax.plot(*goal * 100, "ko", ms=4)
        ax.plot(*ink[-1] * 100, "x", color="tab:red", ms=8, mew=2, label="last ink point")
        ax.add_patch(plt.Circle(goal * 100, r["bound"] * 100, fill=False, ls="--",
                                color="tab:blue", label=f"end bound {r['bound'] * 100:.2f} cm"))
        ax.add_patch(plt.Circle(goal * 100, 1.0, fill=False, ls=":", color="0.4",
                                label="old bound 1 cm"))
        ax.set_aspect("equal")
        ax.invert_xaxis()  # the writing direction (-x) reads left to right
        ax.invert_yaxis()  # "up" on the page is -y
        ax.set_xlabel("x (cm, reversed)")
        ax.set_ylabel("y (cm, reversed)")
        ax.set_title(f"{title}: {r['method'].upper()} '{r['task']}' demo {r['demo']} "
                     f"(after task {r['after']})\nend {r['value'] * 100:.2f} cm vs bound "
                     f"{r['bound'] * 100:.2f} cm: {'success' if r['ok_new'] else 'failure'}",
                     fontsize=9)
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    print(f"\nwrote {path}")


if __name__ == "__main__":
    raise SystemExit(main())
