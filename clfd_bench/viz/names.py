"""Tasks named by index or name, and the file names of a run's videos."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any


def _resolve_tasks(task: int | str | None, names: Sequence[str]) -> list[int]:
    if task is None or (isinstance(task, str) and task.lower() == "all"):
        return list(range(len(names)))
    if isinstance(task, str) and task.lstrip("-").isdigit():
        task = int(task)
    if isinstance(task, int):
        if not 0 <= task < len(names):
            raise ValueError(f"task index {task} out of range: the run learned tasks 0.."
                             f"{len(names) - 1} ({', '.join(names)})")
        return [task]
    if task in names:
        return [list(names).index(task)]
    raise ValueError(f"the run learned no task {task!r}; valid: an index 0..{len(names) - 1}, "
                     f"a name ({', '.join(names)}) or 'all'")


def _video_stem(run: Any) -> str:
    """A run's videos' file-name stem: its directory's name, prefixed by its method when the
    name does not start with it, so the runs of a leaderboard (one name per method folder)
    do not overwrite each other's videos in one folder."""
    name = _safe(run.path.resolve().name)
    method = _safe(run.method.rsplit(":", 1)[-1]) if run.method else ""
    return name if not method or name.startswith(method) else f"{method}_{name}"


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)
