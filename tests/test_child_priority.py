"""A grid's training workers yield the CPU as the grid does (clfd_bench.procs).

Each worker leads its own session, which under Linux autogroup scheduling is its own scheduling
group: without this, ``nice -n 10 clfd-bench leaderboard``'s workers took 62 % of a core each
from a test suite beside them (2026-12-07). Each case runs real processes with real ``nice``."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from clfd_bench.procs import PARENT_GROUP_NICE_ENV, autogroup_nice, child_env

pytestmark = pytest.mark.skipif(autogroup_nice() is None,
                                reason="no /proc/self/autogroup (not Linux autogroup)")

REPORT = ("from clfd_bench.procs import autogroup_nice, keep_parent_priority; "
          "print(keep_parent_priority(), autogroup_nice())")


def _run(cmd: list[str], *, new_session: bool, env: dict[str, str] | None = None) -> str:
    env = {**os.environ, **(env or {})}
    return subprocess.run(cmd, capture_output=True, text=True, check=True, env=env, timeout=60,
                          start_new_session=new_session).stdout.strip()


@pytest.mark.parametrize(("process_nice", "parent_group", "expected"),
                         [(7, 3, 7), (7, 12, 12), (0, 5, 5)])
def test_a_worker_leading_its_session_takes_the_larger_nice(process_nice, parent_group,
                                                            expected):
    out = _run(["nice", "-n", str(process_nice), sys.executable, "-c", REPORT],
               new_session=True, env={PARENT_GROUP_NICE_ENV: str(parent_group)})
    assert out == f"{expected} {expected}"


def test_a_process_in_its_callers_session_leaves_that_group_alone():
    before = autogroup_nice()
    out = _run(["nice", "-n", "9", sys.executable, "-c", REPORT], new_session=False,
               env={PARENT_GROUP_NICE_ENV: "15"})
    assert out == f"None {before}"
    assert autogroup_nice() == before


def test_the_grid_passes_its_groups_nice_and_its_niced_worker_keeps_it():
    env = child_env({"X": "1"})
    assert env["X"] == "1" and env["CLFD_PARENT_PID"] == str(os.getpid())
    assert env[PARENT_GROUP_NICE_ENV] == str(autogroup_nice())
    # End to end through the executor: a grid started with `nice -n 6` starts the worker's
    # entry point in its own session (here with no job: it prints its usage and returns),
    # whose scheduling group ends at nice 6; it stays at 0 without this.
    worker = ("from clfd_bench.harness import worker; from clfd_bench.procs import "
              "autogroup_nice; worker.main([]); print(autogroup_nice())")
    grid = ("import sys; from clfd_bench.leaderboard.executors import _child; "
            f"sys.exit(_child([sys.executable, '-c', {worker!r}], sys.stdout))")
    out = _run(["nice", "-n", "6", sys.executable, "-c", grid], new_session=False)
    assert out.splitlines()[-1] == "6", out
