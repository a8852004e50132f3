"""What the grid commands (``leaderboard``, ``paper``, ``study ...``) share: list-valued
options, the executor options, and the way a command ends (the table it wrote, the files,
the runs that failed, the exit code)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path

__all__ = ["add_executor_arguments", "finish", "frame_size", "ints", "names", "run_grid",
           "unknown_dataset"]


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
    from clfd_bench.harness.config import suggest

    for name in datasets:
        if name not in DATASETS:
            print(f"clfd-bench {command}: error: unknown dataset {name!r}"
                  f"{suggest(name, list(DATASETS))}; valid: {', '.join(DATASETS)}",
                  file=sys.stderr)
            return True
    return False


def add_executor_arguments(
    p: argparse.ArgumentParser, workers: int = 1, workers_help: str = "default 1"
) -> None:
    """``--executor``, ``--workers``, ``--address``: where a grid of training runs runs."""
    p.add_argument("--executor", choices=("local", "ray"), default="local",
                   help="local processes (default) or a Ray cluster")
    p.add_argument("--workers", type=int, default=workers,
                   help=f"parallel local training processes ({workers_help})")
    p.add_argument("--address", default=None,
                   help="Ray cluster address (default: start a local Ray instance)")


def run_grid(command: str, specs: Sequence, args: argparse.Namespace, desc: str):
    """Train (or reuse) ``specs`` under ``args.out`` with the executor options of ``args``.

    Returns the :class:`clfd_bench.leaderboard.runner.GridRun`, or ``None`` after printing
    ``clfd-bench <command>: error: ...`` when a spec is refused before anything is trained
    (the caller then exits with 2)."""
    from clfd_bench.harness.validate import USER_ERRORS
    from clfd_bench.leaderboard.runner import run_specs

    try:
        return run_specs(specs, Path(args.out), args.executor, args.workers, args.address,
                         desc=desc)
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
