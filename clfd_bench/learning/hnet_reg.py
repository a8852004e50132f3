"""The hypernetwork's two-step optimisation (von Oswald et al. 2020; the paper's Eq. hn_loss_2).

Step 1: the task loss ``L_m`` is back-propagated; :func:`adam_lookahead` computes the change
``dh`` the Adam optimiser would now apply to the hypernetwork parameters ``h`` (without
changing the optimiser's state). Step 2: with ``dh`` fixed, the output regulariser

    R = 1/|S| sum_{l in S} || f(e_l, h*) - f(e_l, h + dh) ||^2

is back-propagated and added to the gradient before the actual optimiser step. The targets
``f(e_l, h*)`` are the outputs for every earlier task embedding computed with the parameters
``h*`` from before the current task. The original code divides by the number of earlier
tasks (``m``), which is what :func:`output_regularizer` does (the paper writes ``m - 1``).

``S`` depends on the mode:

* ``all``: every earlier task, one hypernetwork pass per task (the original's loop).
* ``batched``: every earlier task in ONE batched pass; the same value and gradient, cheaper.
* ``sampled``: ``samples`` earlier tasks drawn uniformly without replacement each step (von
  Oswald et al.'s stochastic regulariser): an unbiased estimate at constant cost per step,
  so the time per task does not grow with the number of tasks learned. This is the
  follow-up paper's ``calc_fix_target_reg_stochastic`` (clfd-snode,
  ``imitation_cl/model/hypernetwork.py``): with fewer earlier tasks than ``samples`` all are
  used, the sum is divided by the number regularised, and the caller multiplies by β as for
  the other modes (its ``beta_decay`` defaults to 1, i.e. one β for every task). Only the
  random stream differs (``torch.randperm`` with the run's generator, not numpy's).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import Tensor

__all__ = ["REG_MODES", "adam_lookahead", "output_regularizer"]

REG_MODES = ("all", "batched", "sampled")


@torch.no_grad()
def adam_lookahead(
    optimizer: torch.optim.Adam, params: Sequence[Tensor], out: Sequence[Tensor] | None = None
) -> list[Tensor]:
    """The step ``dh`` the Adam optimiser would now take on ``params`` (detached).

    Uses the current ``.grad`` and the optimiser's moment estimates; the optimiser's state is
    not modified. The update of ``torch.optim.Adam.step()``:
    ``m' = b1 m + (1-b1) g``, ``v' = b2 v + (1-b2) g^2``,
    ``dh = -lr / (1-b1^k) * m' / (sqrt(v') / sqrt(1-b2^k) + eps)`` with ``k`` the next step,
    in float32 as torch's kernel, up to its rounding (torch may fuse a multiply-add; the
    difference is a few ulp of ``dh``). (The original code's copy of hypnettorch's
    ``calc_delta_theta`` adds ``eps`` before the bias correction, ``(sqrt(v') + eps) /
    sqrt(1-b2^k)``: its effective ``eps`` is ``eps / sqrt(1-b2^k)``, 31.6x ours at step 1 with
    ``b2 = 0.999``, falling to ~1x after a few thousand steps. With ``eps = 1e-8`` the two steps
    differ by up to ~1e-6 relative (where ``sqrt(v'/(1-b2^k))`` is ~3e-4 or more; more for
    smaller gradients). We follow ``torch.optim.Adam``, whose step the look-ahead predicts.)

    float32 parameters take one compiled pass (:func:`~clfd_bench.learning.adam_kernel.
    adam_delta`: gradient and moments read, ``dh`` written), others the same formula in torch.

    Args:
        optimizer: a plain Adam (no amsgrad, no weight decay).
        params: the parameters (managed by ``optimizer``) to compute the step for.
        out: tensors to write ``dh`` into (one per parameter, its shape and dtype), e.g. kept
            across the iterations of a task; new ones when None.

    Returns:
        One tensor per parameter (``out``'s when given); zeros for parameters without a
        gradient.
    """
    from clfd_bench.learning.adam_kernel import adam_delta

    group_of = {}
    for group in optimizer.param_groups:
        for p in group["params"]:
            group_of[id(p)] = group
    deltas: list[Tensor] = []
    for idx, p in enumerate(params):
        delta = torch.empty_like(p) if out is None else out[idx]
        deltas.append(delta)
        g = p.grad
        if g is None:
            delta.zero_()
            continue
        group = group_of.get(id(p))
        if group is None:
            raise ValueError("adam_lookahead: a parameter is not managed by the optimizer")
        if group.get("amsgrad") or group.get("weight_decay") or group.get("maximize"):
            raise ValueError("adam_lookahead supports plain Adam (no amsgrad, weight decay)")
        state = optimizer.state.get(p, {})
        step = (int(state["step"]) if state else 0) + 1
        lr, (beta1, beta2), eps = float(group["lr"]), group["betas"], group["eps"]
        m = state["exp_avg"] if state else torch.zeros_like(p)
        v = state["exp_avg_sq"] if state else torch.zeros_like(p)
        step_size = lr / (1 - beta1**step)
        bc2_sqrt = math.sqrt(1 - beta2**step)
        tensors = (g, m, v, delta)
        if all(t.dtype == torch.float32 and t.is_contiguous() for t in tensors):
            adam_delta(*(t.view(-1).numpy() for t in tensors), beta1, beta2, step_size,
                       bc2_sqrt, eps)
            continue
        m = m.lerp(g, 1 - beta1)
        denom = (v * beta2).addcmul_(g, g, value=1 - beta2).sqrt_().div_(bc2_sqrt).add_(eps)
        torch.mul(m.div_(denom), -step_size, out=delta)
    return deltas


def output_regularizer(
    hnet: torch.nn.Module,
    embeddings: Tensor,
    targets: Tensor,
    delta: Sequence[Tensor] | None,
    mode: str = "all",
    samples: int = 1,
    generator: torch.Generator | None = None,
) -> Tensor:
    """Mean over regularised tasks of ``|| targets_l - hnet(embeddings_l, h + delta) ||^2``.

    Args:
        hnet: a :class:`~clfd_bench.learning.hypernet.HyperNetwork` or chunked one.
        embeddings: ``[M, E]`` embeddings of the earlier tasks (constants).
        targets: ``[M, P]`` their outputs before the current task (constants).
        delta: the look-ahead step ``dh`` (or None).
        mode: ``all``, ``batched`` or ``sampled`` (module docstring).
        samples: tasks per step for ``sampled``.
        generator: random generator for ``sampled``.

    Returns:
        A scalar tensor (differentiable w.r.t. the hypernetwork parameters).
    """
    if mode not in REG_MODES:
        raise ValueError(f"unknown regulariser mode {mode!r}; valid: {', '.join(REG_MODES)}")
    m = embeddings.shape[0]
    if m == 0 or targets.shape[0] != m:
        raise ValueError(f"need M >= 1 embeddings with M targets, got {m} and {targets.shape[0]}")
    if mode == "all":
        total = sum(
            (hnet(embeddings[i], delta) - targets[i]).pow(2).sum() for i in range(m)
        )
        return total / m
    if mode == "sampled" and samples < m:
        idx = torch.randperm(m, generator=generator)[:samples]
        embeddings, targets = embeddings[idx], targets[idx]
    out = hnet(embeddings, delta)
    return (out - targets).pow(2).sum() / embeddings.shape[0]
