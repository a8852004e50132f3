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
) -> list[dict]:
    """Time training iterations of ``method`` on ``dataset`` -> one row per timed task.

    Earlier tasks are learned with ``warmup`` iterations only; each timed task runs
    ``warmup`` untimed iterations (separately) and then ``iterations`` timed ones.
    """
    import dataclasses

    import torch

    from clfd_bench.data import load_dataset
    from clfd_bench.harness.config import resolve_config
    from clfd_bench.harness.learner import Learner
    from clfd_bench.harness.loop import train_task, warm_up

    warm_up()
    config = resolve_config(method, dataset, profile, seed=seed, overrides=overrides, node=node)
    ds = load_dataset(dataset)
    torch.manual_seed(seed)
    learner = Learner.from_config(config, ds[0].dim)
    rows = []
    for kind, part in learner.parts.items():
        budget = part.cfg.iterations
        short = dataclasses.replace(part.cfg, iterations=max(1, warmup))
        timed = dataclasses.replace(part.cfg, iterations=iterations)
        for index in range(max(tasks) + 1):
            gen = torch.Generator().manual_seed(seed + index)
            data = part.add_task(ds[index])
            if index not in tasks:
                train_task(part.method, index, data, short, gen)
                continue
            train_task(part.method, index, data, short, gen)  # untimed warm-up
            start = time.perf_counter()
            stats = train_task(part.method, index, data, timed, gen)
            rate = stats.iterations_per_s
            ref = (REFERENCE_IT_PER_S.get((method, dataset))
                   if index == 0 and node == "t" else None)
            rows.append({
                "method": method, "dataset": dataset, "node": node, "part": kind,
                "task": index,
                "it_per_s": rate,
                "s_per_task_paper_budget": budget / rate if rate > 0 else None,
                "paper_iterations": budget,
                "hooks_s": stats.seconds - stats.loop_seconds,
                "reference_it_per_s": ref,
                "speedup_vs_reference": rate / ref if ref else None,
                "wall_s": time.perf_counter() - start,
            })
    return rows


def _run(args: argparse.Namespace) -> int:
    import torch

    from clfd_bench.harness.config import ConfigError
    from clfd_bench.harness.protocol import default_threads
    from clfd_bench.methods import UnknownMethodError

    threads = args.threads or default_threads()
    torch.set_num_threads(threads)
    print(f"training speed, profile {args.profile!r} model sizes, {node_label(args.node)}, "
          f"{threads} torch thread(s); "
          f"{args.iterations} timed iterations per task")
    header = (f"{'method':<6} {'dataset':<11} {'part':<11} {'task':>4} {'it/s':>8} "
              f"{'s/task (paper its)':>19} {'hooks s':>8} {'vs original':>12}")
    print(header)
    print("-" * len(header))
    all_rows = []
    for dataset in args.datasets:
        for method in args.methods:
            try:
                rows = bench_method(
                    method, dataset, profile=args.profile, iterations=args.iterations,
                    warmup=args.warmup, tasks=tuple(args.tasks),
                    overrides=tuple(args.overrides), seed=args.seed, node=args.node,
                )
            except (ConfigError, UnknownMethodError) as exc:
                print(f"clfd-bench bench train: error: {exc}", file=sys.stderr)
                return 2
            for r in rows:
                vs = (f"{r['speedup_vs_reference']:.1f}x of {r['reference_it_per_s']:.0f}"
                      if r["speedup_vs_reference"] else "")
                print(f"{r['method']:<6} {r['dataset']:<11} {r['part']:<11} {r['task']:>4} "
                      f"{r['it_per_s']:>8.1f} {r['s_per_task_paper_budget']:>19.0f} "
                      f"{r['hooks_s']:>8.1f} {vs:>12}", flush=True)
            all_rows += rows
    if args.json_out:
        from clfd_bench.io import atomic_write_json

        atomic_write_json(args.json_out, {"threads": threads, "rows": all_rows})
    return 0
