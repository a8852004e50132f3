"""L2: an anchor penalty towards the weights of the previous task -- a clfd-bench method
written as a plugin, outside the clfd-bench package (the worked example of docs/methods.md).

Loss while learning task m > 0: ``L_m + lambda * sum_k (theta_k - theta*_k)^2``, with
``theta*`` the NODE weights at the end of task m - 1; every weight counts equally (EWC, SI
and MAS weigh them by an importance). The baseline of Kirkpatrick et al. 2017 ("Overcoming
catastrophic forgetting in neural networks", PNAS, the "L2" curve of their Fig. 2) and of
Continual World (Wolczyk et al. 2021, NeurIPS). Like FT it learns one task-conditioned NODE
with one embedding per task; only the NODE weights are pulled towards the anchor.

Use it with any clfd-bench command::

    clfd-bench train --method clfd_l2:L2Anchor --dataset helloworld --out runs/l2  # importable
    clfd-bench train --method docs/examples/clfd_l2/clfd_l2/__init__.py:L2Anchor ...  # a file
    clfd-bench train --method l2 ...  # once installed: pip install -e docs/examples/clfd_l2

Its hyperparameters are in ``l2.toml`` beside this file (``config_file``); ``--config``
replaces it.
"""

from __future__ import annotations

import torch
from torch import Tensor

from clfd_bench.methods import ConditionedNodeMethod, Rule, StepContext, TaskData

__all__ = ["L2Anchor"]


class L2Anchor(ConditionedNodeMethod):
    """L2 (see the module docstring). Buffers ``anchor_{i}``: the NODE weights after the
    last learned task (counted in the model size, as the importances of SI/MAS are)."""

    name = "l2"
    own_hyperparameters = {
        "l2_lambda": Rule("float", lo=0, what="weight of the anchor penalty"),
    }
    config_file = "l2.toml"

    def __init__(self, node, cfg):
        super().__init__(node, cfg)
        for i, w in enumerate(self.weights):
            self.register_buffer(f"anchor_{i}", w.detach().clone())

    def on_task_end(self, task: int, data: TaskData) -> None:
        with torch.no_grad():
            for i, w in enumerate(self.weights):
                getattr(self, f"anchor_{i}").copy_(w)

    def extra_loss(self, ctx: StepContext) -> Tensor | None:
        strength = self.cfg.extra("l2_lambda")
        if ctx.task == 0 or strength == 0:
            return None  # nothing to protect while the first task is learned
        return strength * sum(
            (w - getattr(self, f"anchor_{i}")).pow(2).sum() for i, w in enumerate(self.weights)
        )

    def num_params(self) -> int:
        return super().num_params() + sum(b.numel() for b in self.buffers())
