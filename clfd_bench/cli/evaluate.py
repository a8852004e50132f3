"""``clfd-bench evaluate``: score a saved run by executing its predictions in simulation.

    clfd-bench evaluate runs/hn0 [--rerun runs/hn0/rollouts.rrd]

Executes every saved prediction (after task i, task j <= i, demo d) in task j's environment
without training, and writes ``success``, ``sim_accuracy``, ``sim_cl_metrics`` (ACC, REM, BWT of
execution success) and ``sim`` (env ids and versions, mujoco / mink versions) into
``RUN_DIR/results.json``, keeping everything else. Results are cached per simulator version in
``RUN_DIR/sim_cache.json``: a second call, or one after an interruption, only executes what is
missing; a changed simulator re-executes everything.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

__all__ = ["format_summary", "register"]


def _fmt(value: Any) -> str:
    return "  -  " if value is None else f"{value:.2f}"


def format_summary(results: dict[str, Any], fields: dict[str, Any]) -> str:
    """A short text report: execution R matrix and ACC/REM/BWT beside the trajectory ones."""
    names = results.get("tasks") or []
    sim = fields["sim"]
    lines = [
        f"executed {sim['rollouts']} rollouts ({sim['rollouts_executed']} run, "
        f"{sim['rollouts_cached']} from the cache) in {sim['wall_s']:.1f} s",
        "execution success R[i][j] (row: after task i, column: task j):",
    ]
    width = max([4] + [len(str(n)) for n in names])
    lines.append(" " * (width + 2) + " ".join(f"{str(n)[:5]:>5}" for n in names[: len(
        fields["sim_accuracy"])]))
    for i, row in enumerate(fields["sim_accuracy"]):
        lines.append(f"{str(names[i]) if i < len(names) else i:>{width}}  "
                     + " ".join(f"{_fmt(v):>5}" for v in row))
    traj = results.get("cl_metrics") or {}
    simm = fields["sim_cl_metrics"]
    primary = results.get("cl_metrics_primary", "trajectory")
    lines.append(f"{'':>10} {'execution':>10} {primary + ' (traj.)':>16}")
    for key in ("ACC", "REM", "BWT"):
        lines.append(f"{key:>10} {_fmt(simm.get(key)):>10} {_fmt(traj.get(key)):>16}")
    lines.append(format_failures(fields.get("sim") or {}))
    return "\n".join(lines)


def format_failures(sim: dict[str, Any]) -> str:
    """One line: how many executions failed, by kind, and the first reason of each kind."""
    counts = {k: n for k, n in (sim.get("failure_counts") or {}).items() if n}
    if not counts:
        return "execution failures: none"
    first: dict[str, str] = {}
    for row_r, row_k in zip(sim.get("failure_reason") or [], sim.get("failure_kind") or [],
                            strict=False):
        for cell_r, cell_k in zip(row_r, row_k, strict=False):
            for reason, kind in zip(cell_r or [], cell_k or [], strict=False):
                if kind and kind not in first and reason:
                    first[kind] = reason
    parts = [f"{kind} {n}" for kind, n in counts.items()]
    lines = [f"execution failures: {', '.join(parts)}"]
    lines += [f"  e.g. {kind}: {first[kind]}" for kind in counts if kind in first]
    return "\n".join(lines)


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.execution.evaluate import evaluate_run
    from clfd_bench.runs import RunDir, RunLockedError

    run = RunDir(args.run_dir)
    if not run.results_path.is_file():
        print(f"clfd-bench evaluate: error: {run.results_path} not found: RUN_DIR must be a "
              "directory written by `clfd-bench train`", file=sys.stderr)
        return 2
    from clfd_bench.harness.validate import check_robot_model

    check_robot_model()  # one line naming MENAGERIE_ROOT, before the run is locked
    try:
        with run.lock(f"clfd-bench evaluate {args.run_dir}"):
            if args.rerun:
                from clfd_bench.viz.rerun_log import RolloutLogger

                with RolloutLogger(args.rerun,
                                   recording_name=f"evaluate {args.run_dir}") as logger:
                    fields = evaluate_run(args.run_dir, observer=logger, force=args.force)
            else:
                fields = evaluate_run(args.run_dir, force=args.force, workers=args.workers)
    except (FileNotFoundError, ValueError, KeyError, RunLockedError) as exc:
        print(f"clfd-bench evaluate: error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        out = {k: fields[k] for k in ("success", "sim_accuracy", "sim_cl_metrics")}
        out["failure_counts"] = fields["sim"]["failure_counts"]
        print(json.dumps(out))
    else:
        print(format_summary(run.load_results(), fields))
        if args.rerun:
            print(f"rerun log: {args.rerun} (open with `rerun {args.rerun}`)")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``evaluate`` subcommand."""
    p = subparsers.add_parser(
        "evaluate",
        help="execute a saved run's predictions in simulation (no training) and score them",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run_dir", metavar="RUN_DIR", help="a run directory of `clfd-bench train`")
    p.add_argument("--rerun", metavar="FILE.rrd", default=None,
                   help="also log every rollout (paths, prediction, demonstration, objects, "
                        "outcomes) to this rerun file")
    p.add_argument("--force", action="store_true",
                   help="ignore the execution cache and execute every prediction again")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="processes executing rollouts in parallel (default 1; --rerun runs in "
                        "this process)")
    p.add_argument("--json", action="store_true",
                   help="print success, sim_accuracy, sim_cl_metrics and failure_counts as "
                        "JSON")
    p.set_defaults(func=_run)
