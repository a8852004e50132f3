"""REP: replay. Stores every learned task's data; each iteration trains on one seen task.

As in the paper: a task selector draws one of the tasks seen so far (the current one
included) uniformly per iteration and trains the shared NODE with that task's embedding on
that task's data; the number of iterations per task stays fixed.
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
from torch import Tensor, nn

from clfd_bench.methods.base import TaskData
from clfd_bench.methods.conditioned import ConditionedNodeMethod

__all__ = ["Replay"]


class Replay(ConditionedNodeMethod):
    """REP: the stored demos are buffers (``memory_demos_k``, ``memory_times_k``), so they
    are part of the checkpoint and count as stored samples."""

    name = "rep"

    def _store(self, task: int, demos: Tensor, times: Tensor) -> None:
        self.register_buffer(f"memory_demos_{task}", demos.detach().clone())
        self.register_buffer(f"memory_times_{task}", times.detach().clone())

    def prepare_tasks(self, num_tasks: int, state: Mapping[str, Tensor]) -> None:
        super().prepare_tasks(num_tasks, state)
        for k in range(num_tasks):
            key = f"memory_demos_{k}"
            if key in state and not hasattr(self, key):
                self._store(k, torch.empty_like(state[key]),
                            torch.empty_like(state[f"memory_times_{k}"]))

    def on_task_start(self, task: int, data: TaskData) -> None:
        self._store(task, data.demos, data.times)

    def pick_task(self, task: int, generator: torch.Generator) -> int:
        return int(torch.randint(0, task + 1, (1,), generator=generator))

    def replay_data(self, task: int) -> TaskData:
        return TaskData(
            getattr(self, f"memory_demos_{task}"), getattr(self, f"memory_times_{task}")
        )

    def trainable(self, task: int) -> list[nn.Parameter]:
        return [*self.weights, *self.embeddings[: task + 1]]

    def stored_samples(self) -> int:
        return sum(
            int(b.shape[0] * b.shape[1])
            for name, b in self.named_buffers()
            if name.startswith("memory_demos_")
        )
