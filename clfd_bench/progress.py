"""Progress bars for long work (training, grids, replays).

Bars go to stderr and are disabled when stderr is not a terminal or when the
environment variable ``CLFD_NO_PROGRESS=1`` is set (CI, log files).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable
from typing import Any, TypeVar

from tqdm.auto import tqdm

__all__ = ["progress", "progress_enabled"]

T = TypeVar("T")


def progress_enabled() -> bool:
    """Whether progress bars are shown."""
    if os.environ.get("CLFD_NO_PROGRESS", "") not in ("", "0"):
        return False
    return sys.stderr.isatty()


def progress(
    iterable: Iterable[T] | None = None,
    total: int | None = None,
    desc: str | None = None,
    **kwargs: Any,
) -> tqdm:
    """A tqdm bar that honours :func:`progress_enabled`; use like ``tqdm``."""
    kwargs.setdefault("disable", not progress_enabled())
    kwargs.setdefault("dynamic_ncols", True)
    kwargs.setdefault("leave", False)
    return tqdm(iterable, total=total, desc=desc, **kwargs)
