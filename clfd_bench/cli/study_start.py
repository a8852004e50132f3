"""``clfd-bench study start``: robustness of trained RoboTasks runs to the starting position."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from clfd_bench.cli.leaderboard import _names

__all__ = ["register"]


def _labelled_runs(run_dirs: list[str]) -> dict[str, Path]:
    """``{label: Path}``; label = the run's method (``sg``, ``sg#2`` for a second SG run)."""
    from clfd_bench.runs import RunDir
    from clfd_bench.studies.start_robustness import run_tasks

    runs: dict[str, Path] = {}
    for d in run_dirs:
        path = Path(d)
        run_tasks(path)  # raises ValueError saying what is wrong and what to run
        label = RunDir(path).load_results()["config"]["method"]
        base, n = label, 1
        while label in runs:
            n += 1
            label = f"{base}#{n}"
        runs[label] = path
    return runs


def _train(args: argparse.Namespace, out: Path) -> dict[str, Path]:
    """Train (or resume, or skip when done) the ``--methods`` runs in ``out/runs``."""
    from clfd_bench.leaderboard.grid import RunSpec
    from clfd_bench.leaderboard.runner import run_specs
    from clfd_bench.studies.start_robustness import DATASET

    specs = [RunSpec(DATASET, m, args.profile, args.seed, tasks=args.tasks, sim=False)
             for m in args.methods]
    grid = run_specs(specs, out, desc="train for start study")
    bad = [r for r in grid.records if r.status != "done"]
    if bad:
        raise ValueError("training failed for " + ", ".join(
            f"{r.spec.name} ({r.error or r.status}; log in {r.spec.run_dir(out)})" for r in bad))
    return {s.method: s.run_dir(out) for s in specs}


def _run(args: argparse.Namespace) -> int:
    import time

    from clfd_bench.methods import get_method_class
    from clfd_bench.studies.start_robustness import StudyConfig, run_start_study, study_tasks
    from clfd_bench.studies.start_robustness_plots import (
        plot_study,
        summarize,
        write_records,
        write_summary,
    )

    t0 = time.perf_counter()
    out = Path(args.out)
    if not args.run and not args.methods:
        print("give trained runs with --run DIR, or --methods to train them here",
              file=sys.stderr)
        return 2
    try:
        for method in args.methods:
            get_method_class(method)
        cfg = StudyConfig(seed=args.seed, starts=args.starts, radius=args.radius,
                          approach_speed=args.approach_speed, execute=not args.no_exec)
        runs = _labelled_runs(args.run or [])
        for label, path in (_train(args, out) if args.methods else {}).items():
            runs[label if label not in runs else f"{label}#trained"] = path
        tasks = study_tasks(runs)
        if not tasks:
            raise ValueError("the runs have no learned RoboTasks task in common")
    except (KeyError, ValueError) as exc:
        print(exc.args[0], file=sys.stderr)
        return 2
    records = run_start_study(runs, out, cfg, tasks)
    methods = list(runs)
    rows = summarize(records, methods, tasks)
    files = write_records(records, out) + write_summary(rows, out)
    fig = plot_study(records, methods, tasks, out / "start_robustness.png")
    files += [fig] if fig else []
    for path in files:
        print(f"[study start] wrote {path}")
    print((out / "summary.md").read_text())
    parts = []
    for r in rows:
        succ = "" if r["success_rate"] is None else f", sim success {r['success_rate']:.0%}"
        parts.append(f"{r['method']}/{r['task']}: median end Δ {r['median_end_cm']:.1f} cm, "
                     f"Large {r['large_frac']:.0%}{succ}")
    how = (f"executed in simulation after an approach at {cfg.approach_speed:g} m/s"
           if cfg.execute else "not executed")
    print(f"[study start] {len(runs)} run(s) x {len(tasks)} task(s) x {cfg.starts} starts drawn "
          f"in a {cfg.radius * 100:g} cm ball around a seeded demo's start (seed {cfg.seed}), "
          f"{how}; " + "; ".join(parts)
          + f". Done in {time.perf_counter() - t0:.0f} s (finished work is cached in "
          f"{out / 'cache'}).")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``study start`` subcommand."""
    p = subparsers.add_parser(
        "start",
        help="robustness to the starting position (RoboTasks, with execution in simulation)",
        description="Perturb the start of one seeded demo per RoboTasks task (starts uniform in "
        "a ball), predict with each trained run, report end-position error to the goal and "
        "simulated execution success; tables and the paper-like figure in --out. Resumable.",
    )
    p.add_argument("--run", action="append", metavar="DIR",
                   help="a trained RoboTasks run dir (repeatable; label = its method)")
    p.add_argument("--methods", type=_names, default=[],
                   help="comma list of methods to train here (RoboTasks, --no-sim) and study")
    p.add_argument("--profile", default="fast", help="profile of the runs trained here")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the runs trained here, the demo choice and the starts")
    p.add_argument("--tasks", type=int, default=None,
                   help="train only the first K tasks (smoke tests)")
    p.add_argument("--starts", type=int, default=100, help="start positions per task")
    p.add_argument("--radius", type=float, default=0.20, help="ball radius, metres")
    p.add_argument("--approach-speed", type=float, default=0.1,
                   help="mean speed (m/s) of the move from the demo's start to a perturbed start")
    p.add_argument("--no-exec", action="store_true", help="skip the simulated execution")
    p.add_argument("--out", required=True, help="output directory (runs, cache, tables, figure)")
    p.set_defaults(func=_run)
