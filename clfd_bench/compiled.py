"""How clfd-bench compiles its few numeric kernels: numba, cached on disk where it can be.

The kernels (`metrics/warping.py`, `learning/adam_kernel.py`, `envs/robotasks/scoop/kernels.py`)
are compiled on first use, about a second each, and numba's on-disk cache makes later
processes (the harness's workers) load them in milliseconds. The cache lives beside the module
(``__pycache__``) or in numba's user cache directory (``NUMBA_CACHE_DIR`` to choose another);
where neither can be written (a read-only install and home), numba refuses ``cache=True`` when
the function is defined, which would make the module fail to import: :func:`njit` then compiles
without the cache (once per process), and says so once.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

import numba

__all__ = ["njit"]

_warned = False


def njit(**options: Any) -> Callable[[Callable], Callable]:
    """``numba.njit(cache=True, **options)``, or without the cache where no cache directory
    can be written (a RuntimeWarning, once per process)."""

    def wrap(fn: Callable) -> Callable:
        global _warned
        try:
            return numba.njit(cache=True, **options)(fn)
        except RuntimeError as exc:  # numba: "cannot cache function ...: no locator available"
            if not _warned:
                warnings.warn(f"numba cannot cache compiled kernels here ({exc}); they are "
                              "compiled in every process (~1 s each). Set NUMBA_CACHE_DIR to a "
                              "writable directory to keep them.", RuntimeWarning, stacklevel=2)
                _warned = True
            return numba.njit(**options)(fn)

    return wrap
