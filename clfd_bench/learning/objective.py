"""The training objective every method shares, as pure functions of a config and a batch.

The one training loop (:func:`clfd_bench.harness.loop.train_task`) draws a batch ``(t, y)``
with the :class:`~clfd_bench.learning.batches.BatchSpec` of the config, integrates the task's
vector field from the batch's first samples with the config's :class:`SolverSpec`, and
minimises :func:`trajectory_loss`. Methods that need the same loss outside the loop (EWC's
Fisher, A-GEM's reference gradient on its memory) use these functions, so they score a batch
exactly as training does; the methods live below the harness and must not import it.
"""

from __future__ import annotations

from torch import Tensor

from clfd_bench.learning.batches import BatchSpec
from clfd_bench.learning.node import VectorField
from clfd_bench.learning.odeint import SolverSpec, integrate
from clfd_bench.learning.part_config import PartConfig

__all__ = ["batch_spec", "row_batch", "solver_spec", "trajectory_loss"]


def batch_spec(cfg: PartConfig) -> BatchSpec:
    """The :class:`BatchSpec` of a part config."""
    return BatchSpec(kind=cfg.batch, tsub=cfg.tsub, points=cfg.points,
                     horizon_start=cfg.horizon_start, horizon_ramp=cfg.horizon_ramp,
                     segments=cfg.segments)


def solver_spec(cfg: PartConfig, evaluation: bool = False) -> SolverSpec:
    """The training (or, with ``evaluation``, prediction) :class:`SolverSpec` of a config."""
    if evaluation:
        cfg = cfg.resolved()
        return SolverSpec(cfg.eval_solver, cfg.eval_rtol, cfg.eval_atol, cfg.eval_substeps,
                          cfg.solver_backend)
    return SolverSpec(cfg.solver, cfg.rtol, cfg.atol, cfg.substeps, cfg.solver_backend)


def trajectory_loss(field: VectorField, t: Tensor, y: Tensor, solver: SolverSpec) -> Tensor:
    """The training loss of one batch: ``mean((y_hat - y)^2)`` over rows, samples and
    dimensions (the original code's MSE), where ``y_hat`` integrates ``field`` from each
    row's first sample ``y[:, 0]`` over ``t``.

    Args:
        t: ``[L]`` times, or ``[B, L]`` per-row times (segments).
        y: ``[B, L, D]`` target states.
    """
    y_hat = integrate(field, y[:, 0], t, solver)
    return (y_hat - y).pow(2).mean()


def row_batch(t: Tensor, y: Tensor, row: int) -> tuple[Tensor, Tensor]:
    """Row ``row`` of a batch as a batch of its own: ``(t [L] or [1, L], y [1, L, D])``;
    :func:`trajectory_loss` of it is that row's own loss (a demo's whole trajectory, window or
    segment)."""
    return (t if t.dim() == 1 else t[row : row + 1]), y[row : row + 1]
