"""REP: replay. Stores every learned task's data; each iteration trains on one seen task.

As in the paper: a task selector draws one of the tasks seen so far (the current one
included) uniformly per iteration and trains the shared NODE with that task's embedding on
that task's data; the number of iterations per task stays fixed.
"""

from __future__ import annotations

import torch
from torch import nn

from clfd_bench.methods.base import TaskData
from clfd_bench.methods.conditioned import ConditionedNodeMethod
from clfd_bench.methods.memory import DemoMemory

__all__ = ["Replay"]


class Replay(DemoMemory, ConditionedNodeMethod):
    """REP: the stored demos are buffers (``memory_demos_k``, ``memory_times_k``), so they
    are part of the checkpoint and count as stored samples."""

    name = "rep"

    def on_task_start(self, task: int, data: TaskData) -> None:
        self.store(task, data.demos, data.times)

    def pick_task(self, task: int, generator: torch.Generator) -> int:
        return int(torch.randint(0, task + 1, (1,), generator=generator))

    def replay_data(self, task: int) -> TaskData:
        return self.memory(task)

    def trainable(self, task: int) -> list[nn.Parameter]:
        return [*self.weights, *self.embeddings[: task + 1]]
