"""Entry point of the ``clfd-bench`` console script."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from typing import NoReturn

from clfd_bench.version import __version__

__all__ = ["build_parser", "main"]

COMMANDS: tuple[str, ...] = (
    "data", "train", "evaluate", "score", "leaderboard", "paper", "replay", "video", "site",
    "pretrained", "gallery", "settings",
)  # fmt: skip
"""Modules of :mod:`clfd_bench.cli` that add a top-level subcommand."""

BENCH_COMMANDS: tuple[str, ...] = ("bench_train", "bench_sim")
"""Modules of :mod:`clfd_bench.cli` that add a ``clfd-bench bench <name>`` subcommand."""

STUDY_COMMANDS: tuple[str, ...] = (
    "study_start",
    "study_order",
    "study_sensitivity",
    "study_timing",
    "study_tasktime",
    "study_loops",
)
"""Modules of :mod:`clfd_bench.cli` that add a ``clfd-bench study <name>`` subcommand."""


_RESUME: dict[str, str] = {
    "train": "resumes after the last finished task",
    "leaderboard": "skips the finished runs and resumes the others after their last finished "
                   "task",
    "paper": "skips the finished runs and resumes the others after their last finished task",
    "study": "skips the finished runs and resumes the others after their last finished task",
    "evaluate": "executes only the rollouts not yet cached",
}
"""What running an interrupted command again does (printed on Ctrl-C)."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (``prog: error: ...; see --help``), exit 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (subcommands registered from their modules)."""
    parser = _Parser(
        prog="clfd-bench",
        description="Continual learning from demonstration, scored on a simulated Franka Panda.",
    )
    parser.add_argument("--version", action="version", version=f"clfd-bench {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMANDS:
        importlib.import_module(f"clfd_bench.cli.{name}").register(sub)
    if BENCH_COMMANDS:
        bench = sub.add_parser("bench", help="speed benchmarks (training, simulation)")
        bench_sub = bench.add_subparsers(dest="bench_command", metavar="WHAT", required=True,
                                         parser_class=_Parser)
        for name in BENCH_COMMANDS:
            importlib.import_module(f"clfd_bench.cli.{name}").register(bench_sub)
    study = sub.add_parser(
        "study", help="the paper's studies: start robustness, task order, sensitivity, timing, "
        "time per task, loops without a time input"
    )
    study_sub = study.add_subparsers(dest="study_command", metavar="STUDY", required=True,
                                     parser_class=_Parser)
    for name in STUDY_COMMANDS:
        importlib.import_module(f"clfd_bench.cli.{name}").register(study_sub)
    return parser


def _is_user_error(exc: BaseException) -> bool:
    from clfd_bench.harness.validate import USER_ERRORS

    return isinstance(exc, USER_ERRORS)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``clfd-bench`` with ``argv`` (default: ``sys.argv[1:]``); return the exit code.

    A user's mistake (a bad option or config value, an unusable ``--out``, a missing or
    corrupt dataset file: :data:`clfd_bench.harness.validate.USER_ERRORS`) is printed as one
    line on stderr with exit code 2, before any work; other exceptions are bugs and keep
    their traceback.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    func = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 2
    try:
        return int(func(args) or 0)
    except KeyboardInterrupt:
        hint = _RESUME.get(args.command)
        print(f"clfd-bench {args.command}: interrupted"
              + (f"; finished work is kept: run the same command again, it {hint}" if hint
                 else ""), file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0
    except Exception as exc:
        if not _is_user_error(exc):
            raise
        from clfd_bench.harness.validate import one_line

        command = " ".join(
            c for c in (args.command, getattr(args, "bench_command", None),
                        getattr(args, "study_command", None),
                        getattr(args, "pretrained_command", None)) if c
        )
        print(f"clfd-bench {command}: error: {one_line(exc)}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
