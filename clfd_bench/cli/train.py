"""``clfd-bench train``: learn a dataset's tasks in order with one CL method.

    clfd-bench train --method hn --dataset helloworld --profile fast --seed 0 --out runs/hn0

Writes ``OUT/results.json``, ``OUT/checkpoint.pt`` and ``OUT/predictions/after_task_{i}.npz``
(see :mod:`clfd_bench.harness.protocol`). Running the same command again resumes an
interrupted run after its last finished task. Hyperparameters come from
``baselines/<method>.toml``; ``--set key=value`` overrides any of them (``--set lr=1e-3``,
``--set orientation.iterations=500``), and ``--show-config`` prints what a run would use.
"""

from __future__ import annotations

import argparse
import json
import sys

__all__ = ["register"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``train`` subcommand."""
    p = subparsers.add_parser(
        "train",
        help="learn a dataset's tasks sequentially with one CL method",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--method", required=True, help="CL method: sg, ft, rep, si, mas, hn, chn")
    p.add_argument("--dataset", required=True,
                   help="dataset: lasa, helloworld, robotasks, robotasks9")
    p.add_argument("--profile", default="fast",
                   help="hyperparameter profile: paper (the paper's tables), fast, smoke "
                        "(default: fast)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--order", type=int, default=0, help="task order 0, 1 or 2 (default 0)")
    p.add_argument("--node", choices=("t", "i"), default="t",
                   help="t: NODE^T (time input, default), i: NODE^I")
    p.add_argument("--tasks", type=int, default=None, metavar="K",
                   help="stop after the first K tasks of the order")
    p.add_argument("--out", help="run directory (required unless --show-config)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a hyperparameter (repeatable); KEY may be prefixed with "
                        "position. or orientation. for RoboTasks")
    p.add_argument("--threads", type=int, default=None,
                   help="torch CPU threads (default 1 or $CLFD_THREADS: small NODEs train "
                        "fastest on one thread; run several runs side by side instead)")
    p.add_argument("--keep-checkpoints", action="store_true",
                   help="keep a checkpoint after every task (checkpoints/after_task_i.pt)")
    p.add_argument("--show-config", action="store_true",
                   help="print the resolved configuration as JSON and exit")
    p.add_argument("--quiet", action="store_true", help="no per-task summary lines")
    p.add_argument("--no-sim", action="store_true",
                   help="do not execute the predictions in simulation after each task")
    p.add_argument("--sim-workers", type=int, default=1,
                   help="processes executing rollouts in parallel (default 1)")
    p.set_defaults(func=_run)


def _sim_hook(out: str, workers: int, quiet: bool):
    """After each task: execute every saved prediction not executed yet (cached in the run),
    and write ``success`` / ``sim_accuracy`` / ``sim_cl_metrics`` into ``results.json``."""
    from clfd_bench.execution.evaluate import evaluate_run

    def after_task(i: int) -> dict:
        fields = evaluate_run(out, workers=workers)
        if not quiet:
            row = fields["success"][i]
            done = [s for cell in row[: i + 1] if cell for s in cell]
            sim = fields["sim"]
            acc = fields["sim_cl_metrics"].get("ACC")
            print(
                f"  executed in simulation after task {i}: {sum(done)}/{len(done)} rollouts "
                f"succeed, exec ACC so far {acc if acc is None else format(acc, '.2f')} "
                f"({sim['rollouts_executed']} new rollouts, {sim['wall_s']:.1f} s)"
            )
        return fields

    return after_task


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.harness.config import ConfigError, resolve_config
    from clfd_bench.harness.protocol import RunMismatchError, run_training
    from clfd_bench.methods import UnknownMethodError

    try:
        config = resolve_config(
            args.method, args.dataset, args.profile, seed=args.seed, order=args.order,
            node=args.node, tasks=args.tasks, overrides=args.overrides,
        )
    except (ConfigError, UnknownMethodError) as exc:
        print(f"clfd-bench train: error: {exc}", file=sys.stderr)
        return 2
    if args.show_config:
        print(json.dumps(config.to_dict(), indent=1))
        return 0
    if not args.out:
        print("clfd-bench train: error: --out DIR is required", file=sys.stderr)
        return 2
    sim_hook = None if args.no_sim else _sim_hook(args.out, args.sim_workers, args.quiet)
    try:
        results = run_training(
            config, args.out, threads=args.threads,
            log=None if args.quiet else print, keep_checkpoints=args.keep_checkpoints,
            after_task=sim_hook,
        )
    except RunMismatchError as exc:
        print(f"clfd-bench train: error: {exc}", file=sys.stderr)
        return 2
    if sim_hook is not None:
        # run_training rewrites results.json at the end; put the (cached) execution back.
        from clfd_bench.execution.evaluate import evaluate_run

        fields = evaluate_run(args.out, workers=args.sim_workers)
        results.update(fields)
    cl = results["cl_metrics"]
    if cl and not args.quiet:
        shown = ", ".join(f"{k} {'n/a' if v is None else format(v, '.3f')}"
                          for k, v in cl.items())
        print(f"done: {args.out}/results.json ({results['cl_metrics_primary']}: {shown})")
        sim_cl = results.get("sim_cl_metrics")
        if sim_cl:
            shown = ", ".join(f"{k} {'n/a' if v is None else format(v, '.3f')}"
                              for k, v in sim_cl.items())
            print(f"executed in simulation: {shown}")
    return 0
