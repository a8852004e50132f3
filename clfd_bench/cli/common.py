"""What the grid commands (``leaderboard``, ``paper``, ``study ...``) share: list-valued
options, the grid options (one :class:`~clfd_bench.leaderboard.grid.GridOptions` from the
command line), and the way a command ends (the table it wrote, the files,
the runs that failed, the exit code)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path

__all__ = ["add_grid_arguments", "finish", "frame_size", "grid_options", "ints", "names",
           "run_grid", "unknown_dataset"]


def ints(text: str) -> list[int]:
    """Comma-separated integers (``"0,1,2"`` -> ``[0, 1, 2]``), for argparse's ``type=``."""
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        msg = f"expected comma-separated integers, got {text!r}"
        raise argparse.ArgumentTypeError(msg) from None


def frame_size(text: str) -> tuple[int, int]:
    """An argparse type for a frame size "WIDTHxHEIGHT" (e.g. 1280x720) -> (width, height)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT, e.g. 1280x720, got {text!r}"
                                         ) from None
    return w, h


def names(text: str) -> list[str]:
    """Comma-separated names, lower-cased; a plugin's import spec (``module:Class``) keeps
    its case."""
    parts = (x.strip() for x in text.split(","))
    return [x if ":" in x else x.lower() for x in parts if x]


def unknown_dataset(command: str, datasets: Iterable[str]) -> bool:
    """Print ``clfd-bench <command>: error: unknown dataset ...`` (the closest valid name, the
    valid names) for the first of ``datasets`` the registry does not hold; True if one was
    unknown (the caller then exits with 2)."""
    from clfd_bench.data import DATASETS
    from clfd_bench.harness.run_config import suggest

    for name in datasets:
        if name not in DATASETS:
            print(f"clfd-bench {command}: error: unknown dataset {name!r}"
                  f"{suggest(name, list(DATASETS))}; valid: {', '.join(DATASETS)}",
                  file=sys.stderr)
            return True
    return False


def add_grid_arguments(
    p: argparse.ArgumentParser, workers: int = 1, workers_help: str = "default 1", *,
    node: bool = True, sim: bool = True, executor: bool = True,
    sim_help: str = "skip execution in simulation",
) -> None:
    """The grid options (:class:`~clfd_bench.leaderboard.grid.GridOptions`, read back by
    :func:`grid_options`): ``--node`` (unless ``node`` is False: a grid with NODE variants of
    its own), ``--tasks``, ``--no-sim`` (unless ``sim`` is False: a grid that never executes)
    and where the runs run, ``--executor``, ``--workers``, ``--address``, ``--no-lockstep``
    (unless ``executor`` is False: a command that only reads a grid)."""
    from clfd_bench.leaderboard.grid import EXECUTORS
    from clfd_bench.node_variants import NODE_HELP, NODE_VARIANTS

    if node:
        p.add_argument("--node", choices=tuple(NODE_VARIANTS), default="t", help=NODE_HELP)
    p.add_argument("--tasks", type=int, default=None, help="stop each run after K tasks")
    if sim:
        p.add_argument("--no-sim", action="store_true", help=sim_help)
    if executor:
        p.add_argument("--executor", choices=EXECUTORS, default="local",
                       help="local processes (default) or a Ray cluster")
        p.add_argument("--workers", type=int, default=workers,
                       help=f"parallel local training processes ({workers_help})")
        p.add_argument("--address", default=None,
                       help="Ray cluster address (default: start a local Ray instance)")
        p.add_argument("--no-lockstep", action="store_true",
                       help="one process per run (default: the local executor trains runs "
                            "that differ only in seed or order together, in lockstep, where "
                            "their models are fused-RK4 NODEs)")


def grid_options(args: argparse.Namespace, **fixed):
    """The :class:`~clfd_bench.leaderboard.grid.GridOptions` of the options
    :func:`add_grid_arguments` added to ``args``; an option the command does not have takes
    its value from ``fixed`` (e.g. ``sim=False``) or the default.

    Raises:
        InputError: ``--workers`` below 1 (one line; ``clfd-bench`` exits with 2).
    """
    from clfd_bench.leaderboard.grid import GridOptions

    given = {name: getattr(args, name) for name in
             ("node", "tasks", "executor", "workers", "address") if hasattr(args, name)}
    if hasattr(args, "no_sim"):
        given["sim"] = not args.no_sim
    if hasattr(args, "no_lockstep"):
        given["lockstep"] = not args.no_lockstep
    return GridOptions(**{**given, **fixed})


def run_grid(command: str, specs: Sequence, args: argparse.Namespace, desc: str,
             options=None):
    """Train (or reuse) ``specs`` under ``args.out`` where ``options`` say (default: the
    grid options of ``args``, :func:`grid_options`).

    Returns the :class:`clfd_bench.leaderboard.runner.GridRun`, or ``None`` after printing
    ``clfd-bench <command>: error: ...`` when a spec is refused before anything is trained
    (the caller then exits with 2)."""
    from clfd_bench.harness.validate import USER_ERRORS
    from clfd_bench.leaderboard.runner import run_specs

    try:
        return run_specs(specs, Path(args.out), options or grid_options(args), desc=desc)
    except USER_ERRORS as exc:
        print(f"clfd-bench {command}: error: {exc}", file=sys.stderr)
        return None


def finish(tag: str, table: Path, files: Iterable[Path], failed: Iterable = (),
           summary: str | None = None) -> int:
    """End a grid command: print the markdown ``table`` it wrote, one ``[tag] wrote PATH``
    line per file, an optional ``summary`` line, and one ``[tag] FAILED <run>: <error>``
    line (on stderr) per failed run (a :class:`clfd_bench.leaderboard.executors.RunOutcome`:
    ``.spec.name``, ``.error``). Returns the exit code: 1 if a run failed, else 0."""
    print(Path(table).read_text())
    for path in files:
        print(f"[{tag}] wrote {path}")
    if summary:
        print(summary)
    failed = list(failed)
    for outcome in failed:
        print(f"[{tag}] FAILED {outcome.spec.name}: {outcome.error}", file=sys.stderr)
    return 1 if failed else 0
