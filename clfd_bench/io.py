"""Atomic file writes and checksums.

Every file the project writes (results, checkpoints, leaderboards, downloads) goes
through these helpers: the content is written to a temporary file in the same folder,
flushed to disk and renamed over the target, and the folder is flushed too, so a killed
process (or a power cut) leaves either the old file or the new one, never half of one.
A killed write can leave its temporary file (``.<name>.<random>.tmp``); the run directory
owner (:mod:`clfd_bench.runs`) removes those when it next takes the run.

Fault injection, for the kill tests: with ``CLFD_KILL_BEFORE_REPLACE=<file name>:<n>`` in
the environment, the process SIGKILLs itself at its n-th write of a file of that name, after
the temporary file is complete and before it replaces the target (the worst moment).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import signal
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

__all__ = [
    "json_safe",
    "atomic_write_bytes",
    "atomic_write_json",
    "atomic_write_text",
    "atomic_open",
    "fsync_dir",
    "sha256_file",
]

_KILL_COUNTS: dict[str, int] = {}


def _maybe_kill(name: str) -> None:
    """The fault-injection hook (module docstring)."""
    spec = os.environ.get("CLFD_KILL_BEFORE_REPLACE")
    if not spec:
        return
    target, _, nth = spec.partition(":")
    if name != target:
        return
    _KILL_COUNTS[name] = _KILL_COUNTS.get(name, 0) + 1
    if _KILL_COUNTS[name] == int(nth or 1):
        os.kill(os.getpid(), signal.SIGKILL)


def fsync_dir(path: str | os.PathLike[str]) -> None:
    """Flushes a folder's entries (a rename in it) to disk; a no-op where folders cannot be
    opened (e.g. Windows)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "wb") -> Iterator[IO[Any]]:
    """Open a temporary sibling of ``path`` for writing; rename it over ``path`` on success.

    On an exception the temporary file is removed and ``path`` is left untouched.
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"atomic_open supports modes 'wb' and 'w', not {mode!r}")
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        os.chmod(tmp, 0o644)  # mkstemp makes 0600; results are meant to be shared
        with os.fdopen(fd, mode, **({} if "b" in mode else {"encoding": "utf-8"})) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        _maybe_kill(target.name)
        os.replace(tmp, target)
        fsync_dir(target.parent)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temp file + rename)."""
    with atomic_open(path, "wb") as fh:
        fh.write(data)


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | os.PathLike[str], obj: Any, *, indent: int | None = 1) -> None:
    """Serialise ``obj`` as JSON and write it to ``path`` atomically.

    NaN/inf are rejected (they are not JSON); store them as ``None``.
    """
    text = json.dumps(obj, indent=indent, allow_nan=False, sort_keys=False)
    atomic_write_text(path, text + "\n")


def json_safe(value: Any) -> Any:
    """``value`` as plain JSON data: NaN/inf -> None (JSON has no NaN; e.g. BWT is undefined
    after one task), numpy scalars and arrays unwrapped, dict keys as strings, anything else
    as its ``str``."""
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        value = float(value)
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    return str(value)


def sha256_file(path: str | os.PathLike[str], chunk_size: int = 1 << 20) -> str:
    """The hex sha256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(chunk_size):
            digest.update(chunk)
    return digest.hexdigest()
