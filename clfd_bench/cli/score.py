"""``clfd-bench score``: score predictions made elsewhere as a run directory.

    clfd-bench score PREDICTIONS --dataset helloworld --out runs/mine [--method-name mine]

PREDICTIONS is a directory of ``after_task_<i>.npz`` files (arrays ``task_<j>``, the format
``clfd-bench train`` saves in ``RUN_DIR/predictions/``; an optional ``meta.json`` gives model
sizes, training times and stored samples) or one ``.npz`` with keys ``after_task_<i>/task_<j>``:
for every learned task i and seen task j <= i, ``[N_demos, T, D]`` trajectories from each
demo's start, in the dataset's units (docs/predictions.md). OUT becomes a normal run directory
(errors, accuracy matrices, CL metrics, execution in simulation unless ``--no-sim``) that
``clfd-bench leaderboard --include OUT`` puts beside the built-in methods.

Exit codes: 0 scored; 2 a bad file or option (one line naming the file, the key and what was
expected; nothing is written).
"""

from __future__ import annotations

import argparse
import sys

from clfd_bench.node_variants import NODE_HELP, NODE_VARIANTS

__all__ = ["register"]


def _fmt(value: float | None) -> str:
    return "—" if value is None else f"{value:.3f}"


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.harness.external import score_predictions
    from clfd_bench.runs import RunLockedError

    if not args.no_sim:
        from clfd_bench.harness.validate import check_robot_model

        check_robot_model()  # one line naming MENAGERIE_ROOT, before anything is written
    try:
        results = score_predictions(
            args.predictions, args.dataset, order=args.order, node=args.node, tasks=args.tasks,
            out=args.out, sim=not args.no_sim, method_name=args.method_name,
            sim_workers=args.sim_workers, log=lambda line: print(line, file=sys.stderr),
        )
    except RunLockedError as exc:
        print(f"clfd-bench score: error: {exc}", file=sys.stderr)
        return 2
    primary = results["cl_metrics_primary"]
    cl = results["cl_metrics"]
    m = results["tasks_done"]
    n = sum(len(cell) for row in results["errors"][primary] for cell in row if cell)
    print(f"scored {n} predictions of {m} tasks ({', '.join(results['tasks'])}) from "
          f"{results['provenance']['external']['source']}")
    print(f"{primary}: " + ", ".join(f"{k} {_fmt(v)}" for k, v in cl.items()))
    missing = results["not_provided"]
    if missing["fields"]:
        print(f"not provided: {', '.join(missing['fields'])} -> "
              f"{', '.join(missing['criteria'])} left empty (—)")
    if "sim_cl_metrics" in results:
        from clfd_bench.cli.evaluate import format_summary

        print(format_summary(results, results))
    print(f"wrote {args.out}/results.json")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``score`` subcommand."""
    p = subparsers.add_parser(
        "score",
        help="score predictions made elsewhere (a run directory, as if trained here)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("predictions", metavar="PREDICTIONS",
                   help="a directory of after_task_<i>.npz files, or one .npz")
    p.add_argument("--dataset", required=True,
                   help="dataset: lasa, helloworld, robotasks, robotasks9")
    p.add_argument("--order", type=int, default=0,
                   help="the task order the predictions follow: 0, 1 or 2 (default 0)")
    p.add_argument("--node", choices=tuple(NODE_VARIANTS), default="t",
                   help="the NODE variant the run is compared with (recorded): " + NODE_HELP)
    p.add_argument("--tasks", type=int, default=None, metavar="K",
                   help="score only the first K learned tasks (default: all given)")
    p.add_argument("--out", required=True, help="the run directory to write")
    p.add_argument("--no-sim", action="store_true",
                   help="do not execute the predictions in simulation")
    p.add_argument("--method-name", default="external", metavar="LABEL",
                   help="the run's method label in leaderboards (default: external)")
    p.add_argument("--sim-workers", type=int, default=1,
                   help="processes executing rollouts in parallel (default 1)")
    p.set_defaults(func=_run)
