"""Per-task normalisation of the learned trajectories (mean/std over all demos of a task)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Normalizer"]


@dataclass(frozen=True)
class Normalizer:
    """``z = (y - mean) / std`` per dimension.

    Attributes:
        mean: ``[D]``.
        std: ``[D]`` (strictly positive).
    """

    mean: np.ndarray
    std: np.ndarray

    @classmethod
    def fit(cls, demos: np.ndarray) -> Normalizer:
        """Statistics over every sample of every demo: ``demos: [N, T, D]``.

        As in the original implementation (``np.std``, population standard deviation).
        A dimension that never varies gets std 1.
        """
        flat = np.asarray(demos, dtype=np.float64).reshape(-1, demos.shape[-1])
        std = flat.std(axis=0)
        return cls(mean=flat.mean(axis=0), std=np.where(std > 0, std, 1.0))

    @classmethod
    def identity(cls, dim: int) -> Normalizer:
        """No normalisation (mean 0, std 1)."""
        return cls(mean=np.zeros(dim), std=np.ones(dim))

    def apply(self, y: np.ndarray) -> np.ndarray:
        """Data units -> normalised: ``[..., D] -> [..., D]``."""
        return (np.asarray(y, dtype=np.float64) - self.mean) / self.std

    def invert(self, z: np.ndarray) -> np.ndarray:
        """Normalised -> data units: ``[..., D] -> [..., D]``."""
        return np.asarray(z, dtype=np.float64) * self.std + self.mean

    def to_list(self) -> dict[str, list[float]]:
        """Plain data for a checkpoint header."""
        return {"mean": self.mean.tolist(), "std": self.std.tolist()}

    @classmethod
    def from_list(cls, d: dict[str, list[float]]) -> Normalizer:
        """Inverse of :meth:`to_list`."""
        return cls(mean=np.asarray(d["mean"], dtype=np.float64),
                   std=np.asarray(d["std"], dtype=np.float64))
