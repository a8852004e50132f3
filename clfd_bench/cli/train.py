"""``clfd-bench train``: learn a dataset's tasks in order with one CL method.

    clfd-bench train --method hn --dataset helloworld --profile fast --seed 0 --out runs/hn0

Writes ``OUT/results.json``, ``OUT/checkpoint.pt`` and ``OUT/predictions/after_task_{i}.npz``
(see :mod:`clfd_bench.harness.protocol`). Running the same command again resumes an
interrupted run after its last finished task. Hyperparameters come from
``baselines/<method>.toml``; ``--set key=value`` overrides any of them (``--set lr=1e-3``,
``--set orientation.iterations=500``), and ``--show-config`` prints what a run would use. A
method of your own: ``--method mypackage.module:MyMethod --config my_method.toml``
(docs/methods.md).

Exit codes: 0 done; 2 a bad input (config value, option, dataset file, ``--out``), found
before anything is created or trained, printed as one line; 1 training diverged (one line;
the tasks finished before stay in ``--out``).
"""

from __future__ import annotations

import argparse
import json
import sys

from clfd_bench.node_variants import NODE_HELP, NODE_VARIANTS
from clfd_bench.profiles import PROFILES

__all__ = ["register"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``train`` subcommand."""
    p = subparsers.add_parser(
        "train",
        help="learn a dataset's tasks sequentially with one CL method",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--method", required=True,
                   help="CL method: sg, ft, rep, si, mas, hn, chn, an installed plugin's name, "
                        "or a plugin class as package.module:ClassName or "
                        "path/to/file.py:ClassName (docs/methods.md)")
    p.add_argument("--config", default=None, metavar="TOML",
                   help="the method's hyperparameter file (default baselines/<method>.toml, "
                        "or a plugin class's own config_file); same tables as baselines/")
    p.add_argument("--dataset", required=True,
                   help="dataset: lasa, helloworld, robotasks, robotasks9")
    p.add_argument("--profile", default="fast",
                   help="hyperparameter profile: " + "; ".join(
                       f"{name} ({what})" for name, what in PROFILES.items()) + " (default fast)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--order", type=int, default=0, help="task order 0, 1 or 2 (default 0)")
    p.add_argument("--node", choices=tuple(NODE_VARIANTS), default="t", help=NODE_HELP)
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


def _finish_execution(run, tasks_done: int, workers: int) -> dict:
    """Executes what the per-task step left undone (a run killed while executing its last
    task, or trained before with --no-sim); nothing when every prediction was executed by
    this simulator. Returns the execution fields of ``results.json``."""
    from clfd_bench.execution.evaluate import evaluate_run
    from clfd_bench.execution.fingerprint import sim_fingerprint
    from clfd_bench.runs import SIM_KEYS

    if run.status(tasks_done, sim=True, fingerprint=sim_fingerprint()).state == "done":
        results = run.load_results()
        return {k: results[k] for k in SIM_KEYS if k in results}
    return evaluate_run(run.path, workers=workers)


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.harness.config import ConfigError, resolve_config
    from clfd_bench.harness.loop import TrainingDivergedError
    from clfd_bench.harness.protocol import RunMismatchError, run_training
    from clfd_bench.harness.validate import (
        check_count,
        check_dataset,
        check_env_count,
        check_robot_model,
        check_run_out_dir,
    )
    from clfd_bench.methods import MethodClassError, UnknownMethodError

    # Validation at the edge: the checks up to check_dataset run before any folder is created
    # or any training starts; a failure is one line on stderr and exit 2 (cli/main.py).
    check_count("--threads", args.threads)
    check_count("--sim-workers", args.sim_workers)
    if args.threads is None:
        check_env_count("CLFD_THREADS")
    try:
        config = resolve_config(
            args.method, args.dataset, args.profile, seed=args.seed, order=args.order,
            node=args.node, tasks=args.tasks, overrides=args.overrides,
            config_file=args.config,
        )
    except (ConfigError, UnknownMethodError, MethodClassError) as exc:
        print(f"clfd-bench train: error: {exc}", file=sys.stderr)
        return 2
    if args.show_config:
        print(json.dumps(config.to_dict(), indent=1))
        return 0
    if not args.out:
        print("clfd-bench train: error: --out DIR is required", file=sys.stderr)
        return 2
    check_run_out_dir(args.out)
    check_dataset(config.dataset, config.order)
    if not args.no_sim:
        check_robot_model()
    from clfd_bench.procs import die_with_parent_from_env
    from clfd_bench.runs import RunDir, RunLockedError

    die_with_parent_from_env()  # started by a grid: end with it, even if it is SIGKILLed
    run = RunDir(args.out)
    sim_hook = None if args.no_sim else _sim_hook(args.out, args.sim_workers, args.quiet)
    try:
        with run.lock(f"clfd-bench train --method {args.method} --dataset {args.dataset} "
                      f"--seed {args.seed} --out {args.out}"):
            results = run_training(
                config, args.out, threads=args.threads,
                log=None if args.quiet else print, keep_checkpoints=args.keep_checkpoints,
                after_task=sim_hook,
            )
            if sim_hook is not None:
                results.update(_finish_execution(run, results["tasks_done"], args.sim_workers))
    except (RunMismatchError, RunLockedError) as exc:
        print(f"clfd-bench train: error: {exc}", file=sys.stderr)
        return 2
    except TrainingDivergedError as exc:  # exit 1: the run failed; its finished tasks stay
        kept = (f"tasks 0..{exc.task - 1} stay in {args.out}" if exc.task > 0
                else "no task was finished")
        print(f"clfd-bench train: error: {exc}; {kept} (another lr needs another --out)",
              file=sys.stderr)
        return 1
    cl = results["cl_metrics"]
    if cl and not args.quiet:
        shown = ", ".join(f"{k} {'n/a' if v is None else format(v, '.3f')}"
                          for k, v in cl.items())
        print(f"done: {run.results_path} ({results['cl_metrics_primary']}: {shown})")
        sim_cl = results.get("sim_cl_metrics")
        if sim_cl:
            shown = ", ".join(f"{k} {'n/a' if v is None else format(v, '.3f')}"
                              for k, v in sim_cl.items())
            print(f"executed in simulation: {shown}")
    return 0
