"""Checks at the edge, before any work: command-line counts, the output directory, the
dataset's files; and :data:`USER_ERRORS`, the exceptions a user's mistake raises.

Every check raises with a one-line message naming the bad value, where it came from and
the fix; ``clfd-bench`` prints that line and exits with code 2 (:mod:`clfd_bench.cli.main`).
They create nothing: a refused command leaves no folder behind. The resolved configuration
itself is checked by :func:`clfd_bench.harness.config.resolve_config` (every key's type and
range: :data:`~clfd_bench.learning.part_config.PART_RULES`,
:data:`~clfd_bench.harness.run_config.RUN_RULES`).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from clfd_bench.data.sources import DatasetError
from clfd_bench.learning.part_config import ConfigError

__all__ = [
    "USER_ERRORS",
    "InputError",
    "check_count",
    "check_dataset",
    "check_env_count",
    "check_out_dir",
    "check_robot_model",
    "check_run_out_dir",
    "check_thread_invariance",
    "one_line",
]


class InputError(ValueError):
    """A command-line value (a count, an output path) is unusable; the message says why."""


def check_count(flag: str, value: int | None, minimum: int = 1) -> None:
    """``value`` (from option ``flag``) is None or an integer ``>= minimum``.

    Raises:
        InputError: e.g. ``--threads -2: must be an integer >= 1 ...``.
    """
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise InputError(f"{flag} {value}: must be an integer >= {minimum}; "
                         f"pass e.g. {flag} {minimum}")


def check_env_count(name: str, minimum: int = 1) -> None:
    """Environment variable ``name``, if set and not blank, is an integer ``>= minimum``.

    Raises:
        InputError: e.g. ``CLFD_THREADS=abc: must be an integer >= 1 ...``.
    """
    raw = os.environ.get(name, "")
    if not raw.strip():
        return
    try:
        value = int(raw)
    except ValueError:
        value = None
    if value is None or value < minimum:
        raise InputError(f"environment variable {name}={raw}: must be an integer >= "
                         f"{minimum}; set it to e.g. {minimum}, or unset it")


def check_thread_invariance() -> None:
    """``CLFD_THREAD_INVARIANT``, if set, is a yes or a no
    (:func:`clfd_bench.kernels.thread_invariance_wanted`).

    Raises:
        InputError: e.g. ``CLFD_THREAD_INVARIANT='flase' is not understood: set it to 0 ...``.
    """
    from clfd_bench.kernels import thread_invariance_wanted

    try:
        thread_invariance_wanted()
    except ValueError as exc:
        raise InputError(str(exc)) from None


def _writable(path: Path) -> bool:
    """Whether files can be created in directory ``path``: permissions (``os.access``), then
    a real probe (a temporary file, removed at once), which also catches a read-only
    filesystem, ``/proc`` and the like, where ``os.access`` says yes to root."""
    if not os.access(path, os.W_OK | os.X_OK):
        return False
    try:
        fd, probe = tempfile.mkstemp(prefix=".clfd-write-probe-", dir=path)
    except OSError:
        return False
    os.close(fd)
    os.unlink(probe)
    return True


def check_out_dir(path: str | os.PathLike[str], flag: str = "--out") -> None:
    """Refuse, before anything is created, an output directory that cannot be used: an
    existing file, a non-writable existing directory (or sub-directory), or a new path whose
    nearest existing parent is a file or not writable.

    Raises:
        InputError: one line naming the path and the fix.
    """
    if not str(path).strip():
        raise InputError(f"{flag} is empty; pass a directory path")
    out = Path(path)
    if out.exists():
        if not out.is_dir():
            raise InputError(f"{flag} {out} is an existing file, not a directory; choose "
                             "another path (or move the file away)")
        if not _writable(out):
            raise InputError(f"{flag} {out} is a directory you cannot write to (permissions or "
                             "a read-only filesystem); choose another path or make it writable")
        for sub in sorted(out.iterdir()) if os.access(out, os.R_OK) else ():
            if sub.is_dir() and not _writable(sub):
                raise InputError(f"{flag} {out}: its folder {sub.name}/ is not writable; make "
                                 "it writable or choose another path")
        return
    if out.is_symlink():
        raise InputError(f"{flag} {out} is a broken symbolic link (to {os.readlink(out)}); "
                         "remove it or choose another path")
    ancestor = out.absolute().parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise InputError(f"{flag} {out} cannot be created: {ancestor} is a file, not a "
                         "directory; choose another path")
    if not _writable(ancestor):
        raise InputError(f"{flag} {out} cannot be created: {ancestor} is not writable "
                         "(permissions or a read-only filesystem); choose another path")


def check_run_out_dir(path: str | os.PathLike[str], flag: str = "--out") -> None:
    """:func:`check_out_dir`, and the folder is new, empty or a run directory: a run writes
    its files (``results.json``, ``checkpoint.pt``, ...) into ``path``, so a folder that holds
    other things (``--out docs``) is refused rather than written into. Hidden files
    (``.DS_Store``) do not count.

    Raises:
        InputError: one line naming the path, an entry found in it, and the fix.
    """
    from clfd_bench.runs import RUN_FILES

    check_out_dir(path, flag)
    out = Path(path)
    if not out.is_dir():
        return
    entries = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    if entries and not any(name in RUN_FILES for name in entries) \
            and not (out / RUN_FILES[-1]).exists():
        raise InputError(
            f"{flag} {out} holds {len(entries)} other entr{'y' if len(entries) == 1 else 'ies'} "
            f"(e.g. {entries[0]!r}) and is not a run directory; pass a new or empty folder "
            "(a run writes results.json, checkpoint.pt, predictions/ ... into it), or the "
            "folder of an earlier run to resume it")


def check_dataset(name: str, order: int = 0) -> None:
    """Load dataset ``name`` in task ``order`` once (every file checked against its pinned
    sha256 and shape), so that a missing, truncated or corrupt file is reported before any
    folder is created or any training starts.

    Raises:
        DatasetError: one line naming the file and what to do (re-download, CLFD_DATA_DIR).
    """
    from clfd_bench.data import load_dataset

    load_dataset(name, order=order)


def check_robot_model() -> None:
    """The Franka Panda model (MuJoCo Menagerie's ``franka_emika_panda``) can be found, so that
    a command that executes in simulation fails before any training, not after it. Without
    ``MENAGERIE_ROOT`` the model is downloaded on first use (pinned, checksummed, by the
    ``mujoco_menagerie`` package).

    Raises:
        InputError: one line naming ``MENAGERIE_ROOT`` and the fix.
    """
    from clfd_bench.sim.robot import MENAGERIE_NAME, menagerie_dir

    root = os.environ.get("MENAGERIE_ROOT")
    try:
        folder = Path(menagerie_dir())
    except Exception as exc:  # the package's own errors (not found, download failed)
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if root:
            raise InputError(
                f"MENAGERIE_ROOT={root} holds no {MENAGERIE_NAME}/ robot model ({reason}); "
                "point MENAGERIE_ROOT at a MuJoCo Menagerie copy (the folder that holds "
                f"{MENAGERIE_NAME}/), or unset it to download the model") from None
        raise InputError(
            f"the robot model ({MENAGERIE_NAME}, MuJoCo Menagerie) is not available and "
            f"cannot be downloaded ({reason}); set MENAGERIE_ROOT to a local MuJoCo Menagerie "
            "copy (`bash run.sh setup` records ../shared/menagerie when it is beside the "
            "checkout), or pass --no-sim to train without executing") from None
    if not (folder / "scene.xml").is_file():
        raise InputError(f"the robot model folder {folder} has no scene.xml; point "
                         "MENAGERIE_ROOT at a complete MuJoCo Menagerie copy")


def _user_errors() -> tuple[type[BaseException], ...]:
    from clfd_bench.harness.checkpoint import CheckpointError
    from clfd_bench.methods import UnknownMethodError

    return (ConfigError, InputError, DatasetError, UnknownMethodError, CheckpointError)


USER_ERRORS: tuple[type[BaseException], ...] = _user_errors()
"""Exceptions caused by what a user typed or has on disk: printed as one line, exit 2."""


def one_line(exc: BaseException) -> str:
    """``exc``'s message as the one line a user's mistake is printed as: its non-blank lines,
    stripped, joined by ``"; "``."""
    return "; ".join(line.strip() for line in str(exc).splitlines() if line.strip())
