"""``clfd-bench study timing``: inference speed of HN and CHN, next to the paper's table.

    clfd-bench study timing --out studies/timing                 # paper sizes, CPU (+ GPU)
    clfd-bench study timing --profile fast --out studies/timing_fast   # fast sizes, RK4
    clfd-bench study timing --run runs/hn_hw --run runs/chn_hw --out studies/timing_runs

For each dataset part (LASA, HelloWorld, RoboTasks position and orientation) and for HN and
CHN it times (1) NODE generation by the hypernetwork for one task embedding, (2) one
evaluation of the generated NODE on one state and (3) a whole trajectory over the task's
1000 output times with the profile's own prediction solver (paper: dopri5, rtol 1e-6, atol
1e-7), each the median of --repeats timed runs after --warmup untimed ones, on the CPU and,
when torch sees one, on the GPU (synchronised). By default the models are built at the
profile's sizes with the paper's number of task embeddings and untrained weights (generation
and a step do not depend on the values; the number of solver evaluations does, and is
reported); --run times trained runs instead. Measured cells are cached in OUT/cells/ and
reused when the command is run again with the same settings (--force re-measures).
Writes OUT/timing.md, .csv, .json and OUT/timing_cpu.png (timing_cuda.png).
"""

from __future__ import annotations

import argparse
import sys

from clfd_bench.cli.common import names

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from clfd_bench.harness.config import ConfigError
    from clfd_bench.harness.protocol import default_threads
    from clfd_bench.studies.inference_timing import default_devices, run_study

    threads = args.threads or default_threads()
    if args.devices is None:
        devices = default_devices()
    else:
        devices = tuple(args.devices)
    try:
        result = run_study(
            Path(args.out), methods=args.methods, datasets=args.datasets, runs=args.runs,
            profile=args.profile, overrides=args.overrides, repeats=args.repeats,
            warmup=args.warmup, threads=threads, devices=devices, seed=args.seed,
            task=args.task, force=args.force,
        )
    except (ValueError, ConfigError, FileNotFoundError, KeyError) as exc:
        print(f"clfd-bench study timing: {exc}", file=sys.stderr)
        return 2
    for device, rows in result.rows.items():
        from clfd_bench.studies.inference_timing_report import to_markdown

        print(to_markdown(rows, device))
    print(f"[timing] {result.measured} cells measured now, {result.cached} reused from "
          f"{Path(args.out) / 'cells'}")
    for path in result.files:
        print(f"[timing] wrote {path}")
    print(result.summary())
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``timing`` (under ``clfd-bench study``)."""
    p = subparsers.add_parser(
        "timing",
        help="inference speed of HN/CHN (NODE generation, one step, 1000-step trajectory)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--out", default="studies/timing", help="output directory")
    p.add_argument("--methods", type=names, default=["hn", "chn"],
                   help="comma-separated: hn, chn (default both)")
    p.add_argument("--datasets", type=names, default=["lasa", "helloworld", "robotasks"],
                   help="comma-separated: lasa, helloworld, robotasks (default all three)")
    p.add_argument("--profile", default="paper",
                   help="profile whose sizes and prediction solver are used (default paper; "
                        "fast: RK4)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="config override for the built models (e.g. solver_backend=autograd)")
    p.add_argument("--run", dest="runs", action="append", default=[], metavar="RUN_DIR",
                   help="time this trained HN/CHN run instead of built models (repeatable)")
    p.add_argument("--repeats", type=int, default=100, help="timed runs per quantity (100)")
    p.add_argument("--warmup", type=int, default=5,
                   help="untimed runs first (integration: at most 2)")
    p.add_argument("--threads", type=int, default=None,
                   help="torch CPU threads (default 1 or $CLFD_THREADS)")
    p.add_argument("--device", dest="devices", action="append", choices=("cpu", "cuda"),
                   default=None, help="cpu and/or cuda (default: cpu, plus cuda if available)")
    p.add_argument("--task", type=int, default=0,
                   help="task whose embedding generates the NODE (default 0)")
    p.add_argument("--seed", type=int, default=0, help="seed of the built models' weights")
    p.add_argument("--force", action="store_true", help="re-measure cached cells")
    p.set_defaults(func=_run)
