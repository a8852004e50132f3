"""Checks several test files share (a helper module, not a test file): a command refused
with one clear line, run results compared without what legitimately varies, and the CLI run
in its own process group so that a test can kill it for real (SIGKILL)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from clfd_bench.cli.main import main

RUN_TIMING = frozenset({
    "train_time_s", "train_time_s_by_part", "train_cpu_s", "iterations_per_s_by_part", "wall_s",
    "rollout_wall_s", "evaluated_at", "rollouts_executed", "rollouts_cached", "TE",
    "CL_score", "CL_stability", "rank", "lockstep_by_task",
})
"""Varies between an uninterrupted and a resumed run: wall times, what was cached, what is
computed from times (TE, and CL_score / CL_stability, which average TE in; the rank), and how
many runs learned each task together (a run resumed alone learns its next task alone)."""


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


def cli(*args: str, env: dict[str, str] | None = None) -> subprocess.Popen:
    """``clfd-bench ARGS`` in a subprocess of its own session (so :func:`kill_when` kills its
    workers too), progress bars off; ``env`` entries are added to this process's environment."""
    return subprocess.Popen([sys.executable, "-m", "clfd_bench.cli.main", *args],
                            env={**os.environ, "CLFD_NO_PROGRESS": "1", **(env or {})},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def finish(proc: subprocess.Popen, timeout: float = 900.0) -> str:
    """Wait for ``proc`` and assert it exited 0 (its stderr's end is the message if not);
    returns its stdout."""
    out, err = proc.communicate(timeout=timeout)
    assert proc.returncode == 0, err[-3000:]
    return out


def kill_when(proc: subprocess.Popen, ready: Callable[[], bool], timeout: float = 600.0,
              then: float = 0.0) -> None:
    """SIGKILL the process group of ``proc`` ``then`` seconds after ``ready()`` first holds
    (polled every 20 ms); fails if ``proc`` ends before or ``ready()`` never holds."""
    t0 = time.monotonic()
    while not ready():
        assert proc.poll() is None, f"finished before the kill point: {proc.stderr.read()}"
        assert time.monotonic() - t0 < timeout, "kill point never reached"
        time.sleep(0.02)
    time.sleep(then)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
