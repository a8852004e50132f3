"""Demonstrations a method keeps from learned tasks (REP's replay data, A-GEM's episodic
memory): buffers ``memory_demos_{k}`` ``[n, T, D]`` and ``memory_times_{k}`` ``[T]``, so they
are part of the checkpoint and count as stored samples (SSS)."""

from __future__ import annotations

from collections.abc import Mapping

import torch
from torch import Tensor, nn

from clfd_bench.methods.base import TaskData

__all__ = ["DemoMemory"]


class DemoMemory(nn.Module):
    """Mixin for a :class:`~clfd_bench.methods.base.Method` that stores demos per task."""

    def store(self, task: int, demos: Tensor, times: Tensor) -> None:
        """Keep ``demos`` ``[n, T, D]`` with their ``times`` ``[T]`` as task ``task``'s."""
        self.register_buffer(f"memory_demos_{task}", demos.detach().clone())
        self.register_buffer(f"memory_times_{task}", times.detach().clone())

    def prepare_tasks(self, num_tasks: int, state: Mapping[str, Tensor]) -> None:
        """Also create empty memory buffers of the sizes ``state`` holds (resume, load)."""
        super().prepare_tasks(num_tasks, state)
        for k in range(num_tasks):
            key = f"memory_demos_{k}"
            if key in state and not hasattr(self, key):
                self.store(k, torch.empty_like(state[key]),
                           torch.empty_like(state[f"memory_times_{k}"]))

    def memory(self, task: int) -> TaskData:
        """The demos of ``task`` kept in memory."""
        return TaskData(getattr(self, f"memory_demos_{task}"),
                        getattr(self, f"memory_times_{task}"))

    def stored_samples(self) -> int:
        """``sum n * T`` over the stored tasks."""
        return sum(int(b.shape[0] * b.shape[1]) for name, b in self.named_buffers()
                   if name.startswith("memory_demos_"))
