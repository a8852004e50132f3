"""Where the project's non-code folders are: ``assets``, ``tasks``, ``baselines``, ``eval``,
``pretrained`` (the shipped results bundles, :mod:`clfd_bench.pretrained`).

In a source checkout (or an editable install) they are the top-level folders of the
repository; in an installed wheel they ship inside the package as ``clfd_bench/_share/``.
Library code never hard-codes a directory: it asks :func:`resource_path`.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["FOLDERS", "resource_path", "resource_root"]

FOLDERS = ("assets", "tasks", "baselines", "eval", "pretrained")

_PACKAGE_DIR = Path(__file__).resolve().parent


def resource_root(folder: str) -> Path:
    """The directory holding one of :data:`FOLDERS`.

    Raises:
        ValueError: ``folder`` is not one of :data:`FOLDERS`.
        FileNotFoundError: the folder is in neither the wheel nor the checkout.
    """
    if folder not in FOLDERS:
        raise ValueError(f"unknown resource folder {folder!r}; valid: {', '.join(FOLDERS)}")
    candidates = (_PACKAGE_DIR / "_share" / folder, _PACKAGE_DIR.parent / folder)
    for candidate in candidates:
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(
        f"clfd-bench resource folder {folder!r} not found (looked in "
        f"{', '.join(str(c) for c in candidates)}); the installation is incomplete: "
        "reinstall clfd-bench"
    )


def resource_path(folder: str, *parts: str) -> Path:
    """Path of a file or directory inside a resource folder, e.g.
    ``resource_path("tasks", "openbox.toml")``. The path is not required to exist."""
    return resource_root(folder).joinpath(*parts)
