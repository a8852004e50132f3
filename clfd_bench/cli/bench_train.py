"""``clfd-bench bench train``: training speed of every CL method with the paper's model sizes.

    clfd-bench bench train                       # all methods, LASA and HelloWorld
    clfd-bench bench train --methods hn sg --iterations 100 --set hnet_reg=batched

For each method and dataset it builds the ``paper`` profile's models (same widths, embedding
sizes, windows of 20 samples, dopri5 with rtol 1e-6 / atol 1e-7, i.e. the same mathematics as
the paper) and times ``--iterations`` training iterations on task 0 and on task 1 (after a
short task 0, so the regularisers of SI, MAS, HN and CHN are active). It prints iterations per
second and the seconds one task of the paper's budget (15 000 iterations on LASA, 40 000 on
HelloWorld) would take at that speed, next to the original implementation's speed measured
once on this machine class (HN on LASA task 0: ~35 it/s; SG: ~27 it/s). The machine's speed
moves by up to 2x within an hour, so compare with the released code in the same run:
``python eval/bench_original.py`` times both, alternately. ``--node`` times another
target network (``--node s``: the stable NODE), ``--set solver_backend=autograd`` the same
mathematics without the fused solvers.

    clfd-bench bench train --methods sg hn --datasets lasa --profile fast --node s

``--runs 1 5`` also times 5 runs (seeds ``--seed`` .. ``--seed + 4``) trained in lockstep in
one process, as a grid trains seeds (:func:`clfd_bench.harness.loop.train_tasks`), and reports
runs x iterations per second: what a grid of seeds gets from one core.

    clfd-bench bench train --methods hn --datasets helloworld --profile fast --runs 1 5
"""

from __future__ import annotations

import argparse
import sys
import time

from clfd_bench.node_variants import NODE_HELP, NODE_VARIANTS, node_label

__all__ = ["REFERENCE_IT_PER_S", "bench_method", "register"]

REFERENCE_IT_PER_S = {("hn", "lasa"): 35.0, ("sg", "lasa"): 27.0}
"""The original implementation's training speed on task 0 (2-core CPU; docs/learning.md,
"Speed")."""

METHODS = ("sg", "ft", "rep", "si", "mas", "hn", "chn")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``train`` benchmark (under ``clfd-bench bench``)."""
    p = subparsers.add_parser(
        "train",
        help="training iterations/s per method with the paper's model sizes",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--methods", nargs="+", default=list(METHODS), help="methods to time")
    p.add_argument("--datasets", nargs="+", default=["lasa", "helloworld"],
                   help="datasets (default: lasa helloworld)")
    p.add_argument("--profile", default="paper", help="profile whose sizes to use (paper)")
    p.add_argument("--iterations", type=int, default=60, help="iterations timed per task")
    p.add_argument("--warmup", type=int, default=5, help="untimed iterations first")
    p.add_argument("--tasks", type=int, nargs="+", default=[0, 1],
                   help="task indices to time (earlier ones get --warmup iterations)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="hyperparameter override (e.g. hnet_reg=batched)")
    p.add_argument("--threads", type=int, default=None,
                   help="torch threads (default 1 or $CLFD_THREADS)")
    p.add_argument("--node", choices=tuple(NODE_VARIANTS), default="t",
                   help=NODE_HELP + "; the original's speeds are for t")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--runs", type=int, nargs="+", default=[1], metavar="R",
                   help="runs trained together in lockstep, one timing per value "
                        "(default 1; e.g. --runs 1 5)")
    p.add_argument("--json", dest="json_out", default=None, help="also write rows to this file")
    p.set_defaults(func=_run)


def bench_method(
    method: str,
    dataset: str,
    *,
    profile: str = "paper",
    iterations: int = 60,
    warmup: int = 5,
    tasks: tuple[int, ...] = (0, 1),
    overrides: tuple[str, ...] = (),
    seed: int = 0,
    node: str = "t",
    runs: int = 1,
) -> list[dict]:
    """Time training iterations of ``method`` on ``dataset`` -> one row per timed task.

    Earlier tasks are learned with ``warmup`` iterations only; each timed task runs
    ``warmup`` untimed iterations (separately) and then ``iterations`` timed ones. With
    ``runs > 1``, that many runs (seeds ``seed, seed + 1, ...``) train in lockstep
    (:func:`~clfd_bench.harness.loop.train_tasks`); ``it_per_s`` is then each run's and
    ``runs_it_per_s`` all runs' iterations per second.
    """
    import dataclasses

    import torch

    from clfd_bench.data import load_dataset
    from clfd_bench.harness.config import resolve_config
    from clfd_bench.harness.learner import Learner
    from clfd_bench.harness.loop import TaskRun, train_tasks, warm_up
    from clfd_bench.harness.validate import check_count, check_thread_invariance

    check_count("--runs", runs)
    check_thread_invariance()
    warm_up()
    config = resolve_config(method, dataset, profile, seed=seed, overrides=overrides, node=node)
    ds = load_dataset(dataset)
    learners = []
    for r in range(runs):
        torch.manual_seed(seed + r)
        learners.append(Learner.from_config(config, ds[0].dim))
    rows = []
    for kind, part in learners[0].parts.items():
        budget = part.cfg.iterations
        # the speed of an iteration at the config's steps: refine_gap's refinement is off
        short = dataclasses.replace(part.cfg, iterations=max(1, warmup), refine_gap=0.0)
        timed = dataclasses.replace(part.cfg, iterations=iterations, refine_gap=0.0)
        for index in range(max(tasks) + 1):
            units = []
            for r, learner in enumerate(learners):
                own = learner.parts[kind]
                torch.manual_seed(seed + r + 7919 * index)
                units.append(TaskRun(own.method, index, own.add_task(ds[index]), short,
                                     torch.Generator().manual_seed(seed + r + index),
                                     rng_state=torch.get_rng_state()))
            train_tasks(units)  # a short task before a timed one: untimed warm-up
            if index not in tasks:
                continue
            for unit in units:
                unit.cfg = timed
            start = time.perf_counter()
            stats = train_tasks(units)
            wall = time.perf_counter() - start
            loop_s = max(st.loop_seconds for st in stats)
            rate = stats[0].iterations / loop_s
            ref = (REFERENCE_IT_PER_S.get((method, dataset))
                   if index == 0 and node == "t" and runs == 1 else None)
            rows.append({
                "method": method, "dataset": dataset, "node": node, "part": kind,
                "task": index, "runs": runs,
                "it_per_s": rate,
                "runs_it_per_s": rate * runs,
                "s_per_task_paper_budget": budget / rate if rate > 0 else None,
                "paper_iterations": budget,
                "hooks_s": max(st.seconds - st.loop_seconds for st in stats),
                "reference_it_per_s": ref,
                "speedup_vs_reference": rate / ref if ref else None,
                "wall_s": wall,
            })
    return rows


def _run(args: argparse.Namespace) -> int:
    from clfd_bench.harness.config import ConfigError
    from clfd_bench.harness.protocol import default_threads
    from clfd_bench.harness.validate import InputError
    from clfd_bench.kernels import set_threads
    from clfd_bench.methods import UnknownMethodError

    threads = args.threads or default_threads()
    set_threads(threads)
    print(f"training speed, profile {args.profile!r} model sizes, {node_label(args.node)}, "
          f"{threads} torch thread(s); "
          f"{args.iterations} timed iterations per task")
    header = (f"{'method':<6} {'dataset':<11} {'part':<11} {'task':>4} {'runs':>4} "
              f"{'it/s':>8} {'runs*it/s':>9} {'s/task (paper its)':>19} {'hooks s':>8} "
              f"{'vs original':>12}")
    print(header)
    print("-" * len(header))
    all_rows = []
    for dataset in args.datasets:
        for method in args.methods:
            for runs in args.runs:
                try:
                    rows = bench_method(
                        method, dataset, profile=args.profile, iterations=args.iterations,
                        warmup=args.warmup, tasks=tuple(args.tasks),
                        overrides=tuple(args.overrides), seed=args.seed, node=args.node,
                        runs=runs,
                    )
                except (ConfigError, UnknownMethodError, InputError) as exc:
                    print(f"clfd-bench bench train: error: {exc}", file=sys.stderr)
                    return 2
                for r in rows:
                    vs = (f"{r['speedup_vs_reference']:.1f}x of {r['reference_it_per_s']:.0f}"
                          if r["speedup_vs_reference"] else "")
                    print(f"{r['method']:<6} {r['dataset']:<11} {r['part']:<11} "
                          f"{r['task']:>4} {r['runs']:>4} {r['it_per_s']:>8.1f} "
                          f"{r['runs_it_per_s']:>9.1f} {r['s_per_task_paper_budget']:>19.0f} "
                          f"{r['hooks_s']:>8.1f} {vs:>12}", flush=True)
                all_rows += rows
    if args.json_out:
        from clfd_bench.io import atomic_write_json

        atomic_write_json(args.json_out, {"threads": threads, "rows": all_rows})
    return 0
