"""Child processes that never outlive their parent.

A grid's training runs and an evaluation's rollout workers are child processes. If the parent
is killed (even by SIGKILL, which it cannot catch), Linux delivers a signal of our choice to
each child that asked for it (``prctl(PR_SET_PDEATHSIG)``): :func:`die_with_parent` asks for
SIGKILL, so no orphan keeps training into a run directory. Elsewhere it is a no-op.

A parent that starts a command (not a forked Python function) puts its pid in the child's
environment as ``CLFD_PARENT_PID``; the command calls :func:`die_with_parent_from_env` first
thing, which also catches a parent that died before the child got there.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import sys

__all__ = ["PARENT_ENV", "die_with_parent", "die_with_parent_from_env"]

PARENT_ENV = "CLFD_PARENT_PID"
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
