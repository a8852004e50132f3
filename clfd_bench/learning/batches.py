"""Training batches drawn from one task's (normalised) demonstrations.

Two kinds, both using all demos of the task in every batch:

* ``windows`` (the paper): a random window of ``tsub`` consecutive samples, the same window
  for all demos; the NODE starts from each demo's first window sample. The paper used
  ``tsub = 20``.
* ``trajectories`` (the fast profiles): whole trajectories subsampled to ``points`` samples
  on a fixed grid, starting at each demo's start, over a horizon that grows linearly from
  ``horizon_start`` of the trajectory to all of it during the first ``horizon_ramp`` of the
  iterations (a curriculum: early on the field is fitted near the starts, where errors would
  otherwise compound). With ``segments = true`` a horizon shorter than the trajectory is
  not taken from the start only: the whole subsampled trajectory is cut into consecutive
  segments of that length (at a random offset), each integrated from its first sample, all
  in one batch (multiple shooting). An iteration costs the same (it is as long as one
  segment) but sees the whole trajectory; the batch then has per-sample times ``[B, L]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

__all__ = ["BATCH_KINDS", "BatchSampler", "BatchSpec", "subsample_index"]

BATCH_KINDS = ("windows", "trajectories")


@dataclass(frozen=True)
class BatchSpec:
    """How training batches are drawn (see the module docstring)."""

    kind: str = "windows"
    tsub: int = 20
    points: int = 50
    horizon_start: float = 1.0
    horizon_ramp: float = 0.0
    segments: bool = False

    def __post_init__(self) -> None:
        if self.kind not in BATCH_KINDS:
            raise ValueError(f"unknown batch kind {self.kind!r}; valid: {', '.join(BATCH_KINDS)}")
        if self.tsub < 2 or self.points < 2:
            raise ValueError(f"tsub and points must be >= 2, got {self.tsub}, {self.points}")
        if not 0.0 < self.horizon_start <= 1.0 or not 0.0 <= self.horizon_ramp <= 1.0:
            raise ValueError(
                "horizon_start must be in (0, 1] and horizon_ramp in [0, 1], got "
                f"{self.horizon_start}, {self.horizon_ramp}"
            )


def subsample_index(n_steps: int, points: int) -> np.ndarray:
    """``[P]`` the samples a ``trajectories`` batch keeps of ``n_steps``: ``points`` of them
    evenly spread, the first and the last included (fewer if ``n_steps`` is smaller)."""
    idx = np.unique(np.rint(np.linspace(0, n_steps - 1, min(points, n_steps))))
    return idx.astype(np.int64)


class BatchSampler:
    """Draws ``(t [L], y [N, L, D])`` batches for iteration ``k`` of ``iterations``.

    Args:
        demos: ``[N, T, D]`` normalised demonstrations (float tensor).
        times: ``[T]`` time stamps.
        spec: the batch kind and its settings.
        iterations: the number of training iterations (for the horizon schedule).
    """

    def __init__(self, demos: Tensor, times: Tensor, spec: BatchSpec, iterations: int):
        if demos.dim() != 3 or times.shape != (demos.shape[1],):
            raise ValueError(f"demos [N, T, D] and times [T] expected, got "
                             f"{tuple(demos.shape)} and {tuple(times.shape)}")
        self.demos, self.times, self.spec = demos, times, spec
        self.iterations = max(1, int(iterations))
        n_steps = demos.shape[1]
        if spec.kind == "windows":
            self._tsub = min(spec.tsub, n_steps)
        else:
            idx_t = torch.as_tensor(subsample_index(n_steps, spec.points))
            self._sub_t = times[idx_t]
            self._sub_y = demos[:, idx_t]

    def horizon(self, iteration: int) -> int:
        """Number of subsampled points used at ``iteration`` (``trajectories`` only)."""
        n = self._sub_t.shape[0]
        ramp = self.spec.horizon_ramp * self.iterations
        frac = 1.0 if ramp <= 0 else min(1.0, iteration / ramp)
        share = self.spec.horizon_start + (1.0 - self.spec.horizon_start) * frac
        return max(2, min(n, math.ceil(share * n)))

    def sample(self, iteration: int, generator: torch.Generator) -> tuple[Tensor, Tensor]:
        """The batch for ``iteration``: ``t: [L]`` (or ``[B, L]`` for segments) and
        ``y: [B, L, D]`` (``y[:, 0]`` are the starts; ``B = N`` except for segments)."""
        if self.spec.kind == "windows":
            n_steps = self.demos.shape[1]
            t0 = int(torch.randint(0, n_steps - self._tsub + 1, (1,), generator=generator))
            return self.times[t0 : t0 + self._tsub], self.demos[:, t0 : t0 + self._tsub]
        h = self.horizon(iteration)
        n = self._sub_t.shape[0]
        if not self.spec.segments or h >= n:
            return self._sub_t[:h], self._sub_y[:, :h]
        # segments [s, s + h) with s = offset + k (h - 1), the last one ending at n - 1
        offset = int(torch.randint(0, h - 1, (1,), generator=generator))
        starts = list(range(offset, n - h + 1, h - 1))
        if not starts or starts[-1] != n - h:
            starts.append(n - h)
        if offset > 0:
            starts.insert(0, 0)
        idx = torch.tensor(starts).unsqueeze(1) + torch.arange(h)  # [S, h]
        t = self._sub_t[idx]  # [S, h]
        y = self._sub_y[:, idx]  # [N, S, h, D]
        n_demos = y.shape[0]
        return t.repeat(n_demos, 1), y.reshape(-1, h, y.shape[-1])
