"""R matrices as heat maps (PNG, matplotlib's Agg backend)."""

from __future__ import annotations

import os
import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

__all__ = ["plot_r_matrices"]


def _title(key: str, thresholds: Mapping[str, float]) -> str:
    if key == "execution":
        return "execution (success rate)"
    thr = thresholds.get(key)
    return f"trajectory ({key.upper()}" + (f" ≤ {thr:g})" if thr is not None else ")")


def _cell(value: float) -> str:
    """0, 1, or two decimals without the leading zero (.62): fits a small cell."""
    text = f"{value:.2f}"
    return {"0.00": "0", "1.00": "1"}.get(text, text.lstrip("0"))


def plot_r_matrices(matrices: Mapping[str, Sequence[Sequence[float | None]]],
                    task_names: Sequence[str], path: str | os.PathLike[str], *,
                    thresholds: Mapping[str, float] | None = None, title: str = "") -> Path:
    """Draws each matrix ``R[i][j]`` (accuracy on task j after learning task i; None where
    j > i) side by side, values written in the cells, and writes the PNG atomically.

    Args:
        matrices: name -> R (``m × m``); ``execution`` is titled as such, other names as
            trajectory metrics with their threshold from ``thresholds``.
        task_names: the tasks' names, at least ``m``.
        path: the PNG to write.
        title: the figure's title.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not matrices:
        raise ValueError("no R matrix to draw")
    path = Path(path)
    n = len(matrices)
    m = max(len(r) for r in matrices.values())
    size = max(3.0, 0.45 * m + 1.6)
    fig, axes = plt.subplots(1, n, figsize=(size * n + 0.8, size + 0.4), squeeze=False,
                             layout="constrained")
    cmap = matplotlib.colormaps["RdYlGn"].with_extremes(bad="#f0f0f0")
    image = None
    for ax, (key, rows) in zip(axes[0], matrices.items(), strict=True):
        grid = np.full((m, m), np.nan)
        for i, row in enumerate(rows):
            for j, value in enumerate(row or []):
                if value is not None and j <= i:
                    grid[i, j] = float(value)
        image = ax.imshow(np.ma.masked_invalid(grid), cmap=cmap, vmin=0.0, vmax=1.0)
        for i in range(m):
            for j in range(m):
                if np.isfinite(grid[i, j]):
                    ax.text(j, i, _cell(grid[i, j]), ha="center", va="center", fontsize=7)
        names = [str(t) for t in task_names[:m]]
        ax.set_xticks(range(m), names, fontsize=7, rotation=90 if max(map(len, names)) > 3
                      else 0)
        ax.set_yticks(range(m), names, fontsize=7)
        ax.set_xlabel("task evaluated (j)", fontsize=8)
        ax.set_ylabel("after learning task (i)", fontsize=8)
        ax.set_title(_title(key, thresholds or {}), fontsize=9)
    if image is not None:
        fig.colorbar(image, ax=list(axes[0]), shrink=0.8, label="accuracy R[i][j]")
    if title:
        fig.suptitle(title, fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{uuid.uuid4().hex[:8]}.tmp.png")
    try:
        fig.savefig(tmp, dpi=110, bbox_inches="tight")
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        tmp.unlink(missing_ok=True)
    return path
