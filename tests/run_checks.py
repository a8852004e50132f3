"""Checks several test files share (a helper module, not a test file): a command refused
with one clear line, and run results compared without what legitimately varies."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from clfd_bench.cli.main import main

RUN_TIMING = frozenset({
    "train_time_s", "train_time_s_by_part", "iterations_per_s_by_part", "wall_s",
    "rollout_wall_s", "evaluated_at", "rollouts_executed", "rollouts_cached", "TE",
    "CL_score", "CL_stability", "rank",
})
"""Varies between an uninterrupted and a resumed run: wall times, what was cached, and what
is computed from times (TE, and CL_score / CL_stability, which average TE in; the rank)."""


def comparable(value: Any, ignore: frozenset[str] = RUN_TIMING) -> Any:
    """``value`` (results.json data) without the keys in ``ignore``, at any depth."""
    if isinstance(value, dict):
        return {k: comparable(v, ignore) for k, v in value.items() if k not in ignore}
    if isinstance(value, list):
        return [comparable(v, ignore) for v in value]
    return value


def refused(capsys, argv: list[str], out: Path, *expected: str) -> str:
    """Run ``argv`` (with ``--out out``): exit 2, exactly one stderr line holding every
    ``expected`` text, no traceback, and ``out`` not created (an existing ``out`` left as it
    was). Returns the line."""
    existed = out.exists()
    try:
        code = main([*argv, "--out", str(out)])
    except SystemExit as exc:  # argparse's own errors (a non-integer, a bad choice)
        code = exc.code
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert code == 2, err
    assert len(lines) == 1, err
    for text in expected:
        assert text in lines[0], (text, lines[0])
    assert "Traceback" not in err
    assert out.exists() == existed, f"{out} was created"
    return lines[0]
