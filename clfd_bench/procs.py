"""Child processes that never outlive their parent, nor take more of the CPU than it would.

A grid's training runs and an evaluation's rollout workers are child processes. If the parent
is killed (even by SIGKILL, which it cannot catch), Linux delivers a signal of our choice to
each child that asked for it (``prctl(PR_SET_PDEATHSIG)``): :func:`die_with_parent` asks for
SIGKILL, so no orphan keeps training into a run directory. Elsewhere it is a no-op.

A parent that starts a command (not a forked Python function) puts its pid in the child's
environment as ``CLFD_PARENT_PID``; the command calls :func:`die_with_parent_from_env` first
thing, which also catches a parent that died before the child got there.

Such a child leads its own session (so the grid can kill its process group). On Linux with
autogroup scheduling every session is its own scheduling group and the groups share the CPUs
equally whatever their processes' ``nice``: a ``nice -n 10 clfd-bench leaderboard``'s training
workers took 62 % of a core each from a test suite started beside them (2 cores, 2026-12-07).
The parent also puts the nice of its own group in the child's environment
(``CLFD_PARENT_GROUP_NICE``, :func:`child_env`); the child calls :func:`keep_parent_priority`,
which gives its new group the larger of that and its own (inherited) process nice.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import re
import signal
import sys

__all__ = ["PARENT_ENV", "PARENT_GROUP_NICE_ENV", "autogroup_nice", "child_env",
           "die_with_parent", "die_with_parent_from_env", "keep_parent_priority"]

PARENT_ENV = "CLFD_PARENT_PID"
PARENT_GROUP_NICE_ENV = "CLFD_PARENT_GROUP_NICE"
_PR_SET_PDEATHSIG = 1


def die_with_parent(sig: int = signal.SIGKILL, parent: int | None = None) -> bool:
    """Makes the calling process receive ``sig`` when its parent dies; kills it right away if
    the parent is already gone (its parent pid is no longer ``parent``, default: the current
    one). Returns whether the platform supports it (Linux)."""
    if not sys.platform.startswith("linux"):
        return False
    parent = os.getppid() if parent is None else int(parent)
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if os.getppid() != parent:  # the parent died before prctl took effect
        os.kill(os.getpid(), sig)
    return True


def die_with_parent_from_env(sig: int = signal.SIGKILL) -> bool:
    """:func:`die_with_parent` when ``CLFD_PARENT_PID`` names the expected parent (a grid
    started this process); otherwise nothing. Returns whether it was armed."""
    value = os.environ.get(PARENT_ENV, "").strip()
    if not value.isdigit():
        return False
    return die_with_parent(sig, int(value))


def autogroup_nice(pid: int | str = "self") -> int | None:
    """The nice of process ``pid``'s autogroup (``/proc/PID/autogroup``), or None where the
    kernel has none (not Linux, autogroup not built in)."""
    try:
        with open(f"/proc/{pid}/autogroup", encoding="ascii") as f:
            match = re.search(r"nice\s+(-?\d+)", f.read())
    except OSError:
        return None
    return int(match.group(1)) if match else None


def child_env(env: dict[str, str] | None = None) -> dict[str, str]:
    """``env`` (default: this process's) with :data:`PARENT_ENV` and
    :data:`PARENT_GROUP_NICE_ENV` set for a child command this process starts."""
    out = dict(os.environ if env is None else env)
    out[PARENT_ENV] = str(os.getpid())
    group = autogroup_nice()
    if group is not None:
        out[PARENT_GROUP_NICE_ENV] = str(group)
    else:
        out.pop(PARENT_GROUP_NICE_ENV, None)
    return out


def keep_parent_priority() -> int | None:
    """When this process leads its own session, sets its autogroup's nice to the larger of
    :data:`PARENT_GROUP_NICE_ENV` and its own process nice (never lower than it is). Returns
    the nice set, or None when nothing was changed: not a session leader (the group is the
    caller's, which is left alone), no autogroup, nothing to raise, or not permitted."""
    if not hasattr(os, "getsid") or os.getsid(0) != os.getpid():
        return None
    current = autogroup_nice()
    if current is None:
        return None
    value = os.environ.get(PARENT_GROUP_NICE_ENV, "").strip()
    parent = int(value) if re.fullmatch(r"-?\d+", value) else 0
    target = min(19, max(parent, os.nice(0)))
    if target <= current:
        return None
    try:
        with open("/proc/self/autogroup", "w", encoding="ascii") as f:
            f.write(str(target))
    except OSError:
        return None
    return target
