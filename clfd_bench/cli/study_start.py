"""``clfd-bench study start``: robustness of trained runs to the starting position (RoboTasks
with execution in simulation, LASA at trajectory level)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from clfd_bench.cli.common import names

__all__ = ["register"]


def _labelled_runs(run_dirs: list[str]) -> dict[str, Path]:
    """``{label: Path}``; label = the run's method and NODE variant (``sg``, ``hn (sNODE)``;
    ``sg#2`` for a second SG run)."""
    from clfd_bench.studies.start_robustness import run_label

    runs: dict[str, Path] = {}
    for d in run_dirs:
        path = Path(d)
        label = run_label(path)  # raises ValueError saying what is wrong and what to run
        base, n = label, 1
        while label in runs:
            n += 1
            label = f"{base}#{n}"
        runs[label] = path
    return runs


def _train(args: argparse.Namespace, out: Path) -> dict[str, Path]:
    """Train (or resume, or skip when done) the ``--methods`` x ``--nodes`` runs in
    ``out/runs``; ``{label: run_dir}``."""
    from clfd_bench.leaderboard.grid import RunSpec
    from clfd_bench.leaderboard.runner import run_specs
    from clfd_bench.studies.start_robustness import run_label

    specs = [RunSpec(args.dataset, m, args.profile, args.seed, node=node, tasks=args.tasks,
                     sim=False) for node in args.nodes for m in args.methods]
    grid = run_specs(specs, out, desc="train for start study")
    bad = [r for r in grid.records if r.status != "done"]
    if bad:
        raise ValueError("training failed for " + ", ".join(
            f"{r.spec.name} ({r.error or r.status}; log in {r.spec.run_dir(out)})" for r in bad))
    return {run_label(s.run_dir(out)): s.run_dir(out) for s in specs}


def _check_only(only: list[str], dataset: str) -> None:
    """Refuse a ``--only`` name that is not one of ``dataset``'s tasks (the closest named)."""
    from clfd_bench.data import DATASETS
    from clfd_bench.harness.run_config import suggest

    valid = sorted({n for order in DATASETS[dataset].task_names() for n in order})
    for name in only:
        if name not in valid:
            raise ValueError(f"--only {name!r}: not a {dataset} task{suggest(name, valid)}; "
                             f"valid: {', '.join(valid)}")


def _run(args: argparse.Namespace) -> int:
    import time

    from clfd_bench.methods import get_method_class
    from clfd_bench.node_variants import NODE_VARIANTS
    from clfd_bench.studies.start_robustness import (
        SETTLE_M,
        STUDY_DATASETS,
        StudyConfig,
        check_executable,
        run_start_study,
        study_dataset,
        study_tasks,
    )
    from clfd_bench.studies.start_robustness_plots import (
        plot_overview,
        plot_settling,
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
        if args.dataset not in STUDY_DATASETS:
            raise ValueError(f"--dataset {args.dataset!r}: the start study runs on "
                             f"{', '.join(STUDY_DATASETS)}")
        bad = [n for n in args.nodes if n not in NODE_VARIANTS]
        if bad:
            raise ValueError(f"--nodes {bad[0]!r}: valid {', '.join(NODE_VARIANTS)}")
        cfg = StudyConfig(seed=args.seed, starts=args.starts, radius=args.radius,
                          approach_speed=args.approach_speed, execute=not args.no_exec,
                          horizon=args.horizon)
        runs = _labelled_runs(args.run or [])
        # Checked before anything is trained: one dataset, executed only where it means
        # something.
        dataset = study_dataset(runs) if runs else args.dataset
        if args.methods and dataset != args.dataset:
            raise ValueError(f"the --run dirs are {dataset} runs and --dataset is "
                             f"{args.dataset}; study one dataset at a time")
        check_executable(dataset, cfg.execute)
        _check_only(args.only, dataset)
        for label, path in (_train(args, out) if args.methods else {}).items():
            runs[label if label not in runs else f"{label}#trained"] = path
        tasks = study_tasks(runs)
        if not tasks:
            raise ValueError(f"the runs have no learned {dataset} task in common")
        missing = [n for n in args.only if n not in tasks]
        if missing:
            raise ValueError(f"--only {missing[0]!r}: not learned by every run (they have "
                             f"{', '.join(tasks)} in common)")
        if args.only:
            tasks = [n for n in tasks if n in args.only]
    except (KeyError, ValueError) as exc:
        print(exc.args[0], file=sys.stderr)
        return 2
    records = run_start_study(runs, out, cfg, tasks)
    methods = list(runs)
    rows = summarize(records, methods, tasks)
    files = write_records(records, out) + write_summary(rows, out)
    fig = plot_study(records, methods, tasks, out / "start_robustness.png")
    overview = plot_overview(records, methods, tasks, out / "start_overview.png")
    settling = plot_settling(records, methods, tasks, out / "start_settling.png",
                             cfg.horizon)
    files += [f for f in (fig, overview, settling) if f]
    for path in files:
        print(f"[study start] wrote {path}")
    print((out / "summary.md").read_text())
    parts = []
    for r in rows:
        succ = "" if r["success_rate"] is None else f", sim success {r['success_rate']:.0%}"
        slowest = (f"the slowest after {r['max_settle']:.2g}x"
                   if r["max_settle"] != float("inf") else "not all")
        parts.append(f"{r['method']}/{r['task']}: median end Δ {r['median_end_cm']:.1f} cm, "
                     f"Large {r['large_frac']:.0%}, {r['settled_frac']:.0%} settled within "
                     f"{SETTLE_M * 100:g} cm ({slowest}){succ}")
    how = (f"executed in simulation after an approach at {cfg.approach_speed:g} m/s"
           if cfg.execute else "not executed")
    horizon = "" if cfg.horizon == 1.0 else f", predicted over {cfg.horizon:g}x its duration"
    shape = "ball" if dataset == "robotasks" else "disc"
    print(f"[study start] {dataset}: {len(runs)} run(s) x {len(tasks)} task(s) x {cfg.starts} "
          f"starts drawn in a {cfg.radius * 100:g} cm {shape} around a seeded demo's start (seed "
          f"{cfg.seed}){horizon}, {how}; " + "; ".join(parts)
          + f". Done in {time.perf_counter() - t0:.0f} s (finished work is cached in "
          f"{out / 'cache'}).")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``study start`` subcommand."""
    p = subparsers.add_parser(
        "start",
        help="robustness to the starting position (RoboTasks with execution in simulation, "
             "LASA)",
        description="Perturb the start of one seeded demo per task (starts uniform in a ball; "
        "a disc on LASA), predict with each trained run, report end-position error to the goal "
        "and (RoboTasks) simulated execution success; tables and the paper-like figure in "
        "--out. Resumable.",
    )
    p.add_argument("--run", action="append", metavar="DIR",
                   help="a trained RoboTasks or LASA run dir (repeatable; label = its method "
                        "and NODE variant)")
    p.add_argument("--methods", type=names, default=[],
                   help="comma list of methods to train here (--no-sim) and study")
    p.add_argument("--dataset", default="robotasks",
                   help="dataset of the runs trained here: robotasks (default) or lasa")
    p.add_argument("--nodes", type=names, default=["t"],
                   help="NODE variants of the runs trained here, comma list of t, i, s "
                        "(default t)")
    p.add_argument("--profile", default="fast", help="profile of the runs trained here")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the runs trained here, the demo choice and the starts")
    p.add_argument("--tasks", type=int, default=None,
                   help="train only the first K tasks (smoke tests)")
    p.add_argument("--only", type=lambda s: [x.strip() for x in s.split(",") if x.strip()],
                   default=[], metavar="TASKS",
                   help="study only these learned tasks (comma list, names as in the dataset; "
                        "default: every task the runs learned)")
    p.add_argument("--starts", type=int, default=100, help="start positions per task")
    p.add_argument("--radius", type=float, default=0.20, help="ball radius, metres")
    p.add_argument("--approach-speed", type=float, default=0.1,
                   help="mean speed (m/s) of the move from the demo's start to a perturbed start")
    p.add_argument("--horizon", type=float, default=1.0,
                   help="predict over this many times the demo's duration (default 1, the "
                        "paper's; more shows whether predictions settle at the goal)")
    p.add_argument("--no-exec", action="store_true",
                   help="skip the simulated execution (required on LASA)")
    p.add_argument("--out", required=True, help="output directory (runs, cache, tables, figure)")
    p.set_defaults(func=_run)
