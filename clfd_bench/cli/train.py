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
import dataclasses
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
    p.add_argument("--snapshot-every", type=_seconds, default=None, metavar="SECONDS",
                   help="write the task being learned to task_snapshot.pt every SECONDS, so "
                        "that a killed run resumes in the middle of its task (default 600; "
                        "0: only after each finished task)")
    p.add_argument("--show-config", action="store_true",
                   help="print the resolved configuration as JSON and exit")
    p.add_argument("--quiet", action="store_true", help="no per-task summary lines")
    p.add_argument("--no-sim", action="store_true",
                   help="do not execute the predictions in simulation after each task")
    p.add_argument("--sim-workers", type=int, default=1,
                   help="processes executing rollouts in parallel (default 1)")
    p.set_defaults(func=_run)


def _seconds(text: str) -> float:
    """``--snapshot-every``'s value: a finite number of seconds >= 0."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds >= 0")
    return value


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.harness.config import ConfigError
    from clfd_bench.harness.run import Training, TrainSpec, checked_run
    from clfd_bench.harness.validate import check_count, check_env_count, check_thread_invariance
    from clfd_bench.methods import MethodClassError, UnknownMethodError

    # Validation at the edge: every check runs before any folder is created or any training
    # starts; a failure is one line on stderr and exit 2.
    check_count("--threads", args.threads)
    check_count("--sim-workers", args.sim_workers)
    if args.threads is None:
        check_env_count("CLFD_THREADS")
    check_thread_invariance()
    spec = TrainSpec(args.method, args.dataset, args.profile, seed=args.seed, order=args.order,
                     node=args.node, tasks=args.tasks, overrides=tuple(args.overrides),
                     config_file=args.config)
    try:
        config = spec.config()
    except (ConfigError, UnknownMethodError, MethodClassError) as exc:
        print(f"clfd-bench train: error: {exc}", file=sys.stderr)
        return 2
    if args.show_config:
        print(json.dumps(config.to_dict(), indent=1))
        return 0
    if not args.out:
        print("clfd-bench train: error: --out DIR is required", file=sys.stderr)
        return 2
    training = Training(config, args.threads, args.keep_checkpoints)
    if args.snapshot_every is not None:
        training = dataclasses.replace(training, snapshot_every=args.snapshot_every)
    return checked_run(training, args.out,
                       sim=not args.no_sim, sim_workers=args.sim_workers,
                       log=None if args.quiet else print, prog="clfd-bench train")
