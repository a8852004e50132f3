"""``clfd-bench paper``: the paper's full grid (list, run) and its tables next to ours.

    clfd-bench paper list                                   # 495 runs: counts and cost
    clfd-bench paper list --datasets helloworld --runs --out results   # every run's status
    clfd-bench paper run --datasets helloworld --seeds 0 --orders 0 --out results
    clfd-bench paper run --executor ray --address auto --workers 32 --out results
    clfd-bench paper tables --datasets helloworld --out results
    clfd-bench paper sizes --profile fast                   # FS of the profile's model sizes
    clfd-bench paper profiles fast=results/helloworld full=results/full/helloworld

The grid: LASA and HelloWorld with SG FT REP SI MAS HN CHN and NODE^T / NODE^I, RoboTasks
with SG FT REP HN CHN and NODE^T, seeds 0-4, task orders 0-2, profile ``paper``; every
dimension can be narrowed. ``run`` trains only what is not finished (a killed grid resumes)
and then writes the tables; ``tables`` reads whatever runs are finished under
``--out/runs`` and writes ``paper_tables.md``/``.csv``/``.json`` and ``paper_diff.png``.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from clfd_bench.cli.common import add_grid_arguments, finish, grid_options, ints, names, run_grid
from clfd_bench.profiles import profile_help

__all__ = ["register"]


def _grid(args: argparse.Namespace):
    from clfd_bench.studies.paper_grid import paper_grid

    return paper_grid(
        datasets=args.datasets, methods=args.methods, nodes=args.nodes, seeds=args.seeds,
        orders=args.orders, profile=args.profile, options=grid_options(args),
    )


def _hours(seconds: float | None) -> str:
    return "n/a" if seconds is None else f"{seconds / 3600:.1f} h"


def _list(args: argparse.Namespace) -> int:
    from collections import Counter

    from clfd_bench.leaderboard.grid import run_status
    from clfd_bench.studies.paper_grid import grid_cost, load_bench_rates

    specs = _grid(args)
    rates = load_bench_rates(args.bench_json) if args.bench_json else {}
    rows = grid_cost(specs, rates)
    status = {}
    if args.out:
        status = {s: run_status(s, Path(args.out)) for s in specs}
    print(f"paper grid, profile {args.profile!r}: {len(specs)} runs")
    header = (f"{'dataset':<11} {'method':<6} {'node':<4} {'runs':>5} {'tasks':>5} "
              f"{'its/run':>9} {'GPU/run':>8} {'CPU/run':>8} {'CPU total':>10}"
              + ("  done/partial/failed/missing" if status else ""))
    print(header)
    print("-" * len(header))
    cpu_total = 0.0
    cpu_known = True
    for r in rows:
        total = None if r.cpu_s is None else r.cpu_s * r.runs
        cpu_known &= total is not None
        cpu_total += total or 0.0
        line = (f"{r.dataset:<11} {r.method:<6} {r.node:<4} {r.runs:>5} {r.tasks:>5} "
                f"{r.iterations:>9,} {_hours(r.gpu_s):>8} {_hours(r.cpu_s):>8} "
                f"{_hours(total):>10}")
        if status:
            c = Counter(status[s] for s in specs
                        if (s.dataset, s.method, s.node) == (r.dataset, r.method, r.node))
            line += f"  {c['done']}/{c['partial']}/{c['failed']}/{c['missing']}"
        print(line)
    iters = sum(r.total_iterations for r in rows)
    gpu = [r.gpu_s * r.runs for r in rows if r.gpu_s is not None]
    print(f"total: {len(specs)} runs, {iters:,} training iterations; "
          + (f"paper's GPU time {sum(gpu) / 3600:,.0f} GPU-hours (its wall-clock tables); "
             if len(gpu) == len(rows) else "")
          + (f"this CPU ≈ {cpu_total / 3600:,.0f} core-hours at 1 torch thread (bench train "
             "speeds; HN/CHN slow down as tasks accrue, so a lower bound)" if cpu_known and rates
             else "CPU time: pass --bench-json FILE from `clfd-bench bench train --json FILE`"))
    if args.runs:
        print()
        for s in specs:
            print(f"{status.get(s, '?'):<8} {s.name}")
    if status:
        c = Counter(status.values())
        print(f"\nunder {args.out}: {c['done']} done, {c['partial']} partial, "
              f"{c['failed']} failed, {c['missing']} missing")
    return 0


def _tables(args: argparse.Namespace, specs=None, failed=()) -> int:
    import statistics

    from clfd_bench.studies.paper_tables import build_tables, write_outputs

    out = Path(args.out)
    if not out.is_dir():
        print(f"clfd-bench paper tables: {out} does not exist; train the grid first with "
              f"`clfd-bench paper run [...] --out {out}`", file=sys.stderr)
        return 2
    specs = specs if specs is not None else _grid(args)
    tables, times, records = build_tables(specs, out)
    meta = {
        "profile": args.profile,
        "datasets": sorted({s.dataset for s in specs}),
        "methods": sorted({s.method for s in specs}),
        "nodes": sorted({s.node for s in specs}),
        "seeds": sorted({s.seed for s in specs}),
        "orders": sorted({s.order for s in specs}),
        "tasks": args.tasks,
        "runs": {r.spec.name: r.status for r in records},
    }
    files = write_outputs(tables, times, out, meta)
    done = sum(r.status == "done" for r in records)
    # one-paragraph summary
    diffs = [abs(r.diff(c)) for t in tables for r in t.rows for c in ("ACC", "REM", "CL_score")
             if math.isfinite(r.diff(c))]
    filled = sum(1 for t in tables for r in t.rows if r.runs_done)
    cells = sum(len(t.rows) for t in tables)
    summary = (f"[paper] {done} of {len(records)} selected runs are finished; {len(tables)} "
               f"CL table(s), {filled} of {cells} method rows filled")
    if diffs:
        summary += (f"; |ours − paper| over ACC, REM, CL_score: median "
                    f"{statistics.median(diffs):.2f}, max {max(diffs):.2f}")
    if args.profile != "paper":
        summary += (f". Profile {args.profile!r} is not the paper's training budget, so "
                    "differences are expected")
    if done < len(records):
        summary += (f". {len(records) - done} run(s) missing: `clfd-bench paper run` with the "
                    "same flags trains them")
    finish("paper", out / "paper_tables.md", files, failed, summary=summary + ".")
    if done == 0:
        print(f"clfd-bench paper tables: no finished runs under {out}/runs for this selection; "
              f"run `clfd-bench paper run [same flags] --out {out}`", file=sys.stderr)
        return 1
    return 0


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.harness.config import resolve_config

    specs = _grid(args)
    for key in dict.fromkeys((s.method, s.dataset, s.profile) for s in specs):
        resolve_config(key[0], key[1], key[2])  # a missing profile table fails here, not later
    grid = run_grid("paper run", specs, args, desc="paper grid")
    if grid is None:  # refused before anything was trained
        return 2
    print(f"[paper] {grid.counts()}")
    code = _tables(args, specs, grid.failed)
    return 1 if grid.failed else code


def _sizes(args: argparse.Namespace) -> int:
    from clfd_bench.studies.paper_grid import PAPER_GRID
    from clfd_bench.studies.paper_sizes import size_table

    datasets = args.datasets or list(PAPER_GRID)
    rows = [row for dataset in datasets for row in size_table(dataset, args.profile, args.methods)]
    tolerance = args.tolerance
    worst = 0.0
    print(f"final model sizes, profile {args.profile!r}, and the FS they give vs the paper's")
    header = (f"{'dataset':<11} {'table':<12} {'method':<6} {'params':>12} {'FS':>5} "
              f"{'paper':>6} {'diff':>6}")
    print(header)
    print("-" * len(header))
    for row in rows:
        paper = "" if row.paper_fs is None else f"{row.paper_fs:.2f}"
        diff = "" if row.diff is None else f"{row.diff:+.2f}"
        flag = "" if row.diff is None or abs(row.diff) <= tolerance else "  off"
        if row.diff is not None:
            worst = max(worst, abs(row.diff))
        print(f"{row.dataset:<11} {row.table:<12} {row.method:<6} {row.params:>12,d} "
              f"{row.fs:>5.2f} {paper:>6} {diff:>6}{flag}")
    print(f"largest |FS - paper|: {worst:.2f} (rows marked 'off' exceed {tolerance})")
    return 0


def _profiles(args: argparse.Namespace) -> int:
    from clfd_bench.harness.validate import InputError
    from clfd_bench.studies.profile_compare import compare_profiles, markdown, write_comparison

    folders: dict[str, str] = {}
    for item in args.leaderboards:
        label, sep, folder = item.partition("=")
        if not sep or not label or not folder:
            print(f"clfd-bench paper profiles: error: {item!r} is not LABEL=FOLDER (e.g. "
                  "fast=results/helloworld)", file=sys.stderr)
            return 2
        if label in folders:
            print(f"clfd-bench paper profiles: error: label {label!r} given twice",
                  file=sys.stderr)
            return 2
        folders[label] = folder
    try:
        cmp = compare_profiles(folders)
    except InputError as exc:
        print(f"clfd-bench paper profiles: error: {exc}", file=sys.stderr)
        return 2
    print(markdown(cmp))
    if args.out:
        for path in write_comparison(cmp, args.out):
            print(f"wrote {path}")
    return 0


def _safe(func):
    def wrapped(args: argparse.Namespace) -> int:
        from clfd_bench.harness.config import ConfigError
        from clfd_bench.methods import UnknownMethodError
        from clfd_bench.studies.paper_grid import GridError

        try:
            return func(args)
        except (GridError, ConfigError, UnknownMethodError) as exc:
            print(f"clfd-bench paper {args.paper_command}: error: {exc}", file=sys.stderr)
            return 2

    return wrapped


def _add_grid_flags(p: argparse.ArgumentParser, executor: bool = False) -> None:
    p.add_argument("--datasets", type=names, default=None,
                   help="comma-separated: lasa,helloworld,robotasks (default all)")
    p.add_argument("--methods", type=names, default=None,
                   help="comma-separated: sg,ft,rep,si,mas,hn,chn (default: the paper's for "
                        "each dataset; RoboTasks has no SI/MAS)")
    p.add_argument("--nodes", type=names, default=None,
                   help="comma-separated t,i (default: the paper's; RoboTasks: t only)")
    p.add_argument("--seeds", type=ints, default=None, help="comma-separated (default 0-4)")
    p.add_argument("--orders", type=ints, default=None, help="task orders (default 0,1,2)")
    p.add_argument("--profile", default="paper", help=profile_help("paper"))
    add_grid_arguments(p, node=False, executor=executor,
                       sim_help="train without executing predictions in simulation")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``paper`` command with its ``list``, ``run`` and ``tables`` subcommands."""
    p = subparsers.add_parser(
        "paper", help="the paper's full grid (list, run) and its tables next to ours",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = p.add_subparsers(dest="paper_command", metavar="ACTION", required=True)
    ls = sub.add_parser("list", help="runs of the grid: counts, iterations, cost, status")
    _add_grid_flags(ls)
    ls.add_argument("--out", default=None, help="results directory to read run status from")
    ls.add_argument("--runs", action="store_true", help="print every run (with its status)")
    ls.add_argument("--bench-json", action="append", default=[], metavar="FILE",
                    help="`clfd-bench bench train --json` output(s) for a CPU time estimate")
    ls.set_defaults(func=_safe(_list))
    run = sub.add_parser("run", help="train the grid's unfinished runs, then write the tables")
    _add_grid_flags(run, executor=True)
    run.add_argument("--out", required=True, help="results directory (runs go to OUT/runs)")
    run.set_defaults(func=_safe(_run))
    sz = sub.add_parser("sizes", help="final model sizes and the FS they give, vs the paper's")
    sz.add_argument("--datasets", type=names, default=None,
                    help="comma-separated: lasa,helloworld,robotasks (default all)")
    sz.add_argument("--methods", type=names, default=None,
                    help="comma-separated (default: the paper's for each dataset)")
    sz.add_argument("--profile", default="fast", help=profile_help("fast"))
    sz.add_argument("--tolerance", type=float, default=0.05,
                    help="mark rows whose FS differs from the paper's by more (default 0.05)")
    sz.set_defaults(func=_safe(_sizes))
    pr = sub.add_parser("profiles", help="one dataset's leaderboards at several profiles, "
                        "side by side (is fast faithful in execution?)")
    pr.add_argument("leaderboards", nargs="+", metavar="LABEL=FOLDER",
                    help="leaderboard output folders with a label each, the reference last, "
                         "e.g. fast=results/helloworld full=results/full/helloworld")
    pr.add_argument("--out", default=None,
                    help="also write profile_comparison.md/.json into this folder")
    pr.set_defaults(func=_safe(_profiles))
    tb = sub.add_parser("tables", help="the paper's tables from the finished runs, vs the paper")
    _add_grid_flags(tb)
    tb.add_argument("--out", required=True, help="results directory holding OUT/runs")
    tb.set_defaults(func=_safe(_tables))
