"""The training objective every method shares, as pure functions of a config and a batch.

The one training loop (:func:`clfd_bench.harness.loop.train_task`) draws a batch ``(t, y)``
with the :class:`~clfd_bench.learning.batches.BatchSpec` of the config, integrates the task's
vector field from the batch's first samples with the config's :class:`SolverSpec`, and
minimises :func:`trajectory_loss`. Methods that need the same loss outside the loop (EWC's
Fisher, A-GEM's reference gradient on its memory) use these functions, so they score a batch
exactly as training does; the methods live below the harness and must not import it.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

import torch
from torch import Tensor

from clfd_bench.learning.batches import BatchSpec
from clfd_bench.learning.fused_mlp import FUSED_ACTIVATIONS
from clfd_bench.learning.node import VectorField
from clfd_bench.learning.odeint import SolverSpec, integrate
from clfd_bench.learning.part_config import PartConfig
from clfd_bench.learning.rk4_fused import rk4_mlp
from clfd_bench.learning.rk4_stacked import rk4_mlp_stacked

__all__ = [
    "batch_spec",
    "row_batch",
    "solver_spec",
    "stack_key",
    "stacked_trajectory_losses",
    "trajectory_loss",
]


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


def stack_key(field: VectorField, t: Tensor, y: Tensor, solver: SolverSpec) -> Hashable | None:
    """Under which key this batch's loss can be computed in one pass with other runs' batches
    of the same key (:func:`stacked_trajectory_losses`), or None when it cannot: only a NODE
    :class:`~clfd_bench.learning.node.VectorField` through the fused fixed-step RK4 stacks
    (adaptive solvers choose their steps per run; stable NODEs have fields of their own).
    Runs stack when their networks have the same shapes and layouts, their batches the same
    number of samples per row and either per-sample times or the same shared times; their
    numbers of rows may differ (padded)."""
    if not (solver.method == "rk4" and solver.backend == "fused"
            and isinstance(field, VectorField)
            and field.spec.activation in FUSED_ACTIVATIONS and t.shape[-1] >= 2):
        return None
    shared = tuple(t.tolist()) if t.dim() == 1 else None
    return (field.spec.activation, solver.substeps, _layout(field), t.shape[-1], shared,
            y.shape[-1], y.dtype)


def _layout(field: VectorField) -> tuple:
    """Shapes and strides of a field's tensors (what decides the kernels that compute it)."""
    tensors = [field.w0y, field.bias, *field.rest] + (
        [] if field.w0t is None else [field.w0t])
    return tuple((tuple(w.shape), w.stride()) for w in tensors)


_EXACT: dict[Hashable, bool] = {}
"""Per stacking signature, whether the stacked integration equals every run's own, bit for
bit (checked once per process: :func:`_stacks_exactly`)."""


def stacked_trajectory_losses(fields: Sequence[VectorField], ts: Sequence[Tensor],
                              ys: Sequence[Tensor], solver: SolverSpec) -> list[Tensor]:
    """:func:`trajectory_loss` of R runs' batches, bit for bit, in one pass where that is
    exact: their fields' weights stacked and integrated together
    (:func:`~clfd_bench.learning.rk4_stacked.rk4_mlp_stacked`), batches with fewer rows than
    the largest padded with copies of their first row (which no loss reads).

    Whether the stacked pass gives each run exactly its own values (forward and backward:
    batched matrix products against the single ones, which BLAS may sum in another order
    for some shapes) is checked the first time a shape occurs (the network and its tensors'
    layouts, R, the padded rows and each run's rows) by computing both over one step (the
    kernels depend on the shapes, not on the number of steps), and remembered for the
    process; where it does not hold, each run's loss is computed alone. So loss ``r`` and
    its gradient are always those of run ``r``'s :func:`trajectory_loss`.

    Args:
        fields: R fields of one :func:`stack_key`.
        ts: R times, each ``[L]`` (equal) or ``[B_r, L]``.
        ys: R targets, each ``[B_r, L, D]``.
    """
    rows = [y.shape[0] for y in ys]
    batch = max(rows)
    per_sample = ts[0].dim() == 2
    y0s, times = [], []
    for t, y in zip(ts, ys, strict=True):
        pad = batch - y.shape[0]
        y0 = y[:, 0]
        if pad:
            y0 = torch.cat([y0, y0[:1].expand(pad, -1)])
        y0s.append(y0)
        if per_sample:
            tr = t.to(y.dtype)
            times.append(torch.cat([tr, tr[:1].expand(pad, -1)]) if pad else tr)
    stacked_t = torch.stack(times) if per_sample else ts[0]
    y0 = torch.stack(y0s)
    first = fields[0]
    base = (first.spec.activation, solver.substeps, _layout(first), per_sample,
            y0.shape[-1], y0.dtype, len(fields), batch)
    if any((base, n) not in _EXACT for n in rows):
        # the kernels depend on the shapes, not on the number of steps: check one step
        verdicts = _stacks_exactly(fields, y0, stacked_t[..., :2], rows,
                                   [t[..., :2] for t in ts], solver)
        for n, ok in zip(rows, verdicts, strict=True):
            _EXACT[(base, n)] = _EXACT.get((base, n), True) and ok
    if not all(_EXACT[(base, n)] for n in rows):
        return [trajectory_loss(f, t, y, solver) for f, t, y in zip(fields, ts, ys, strict=True)]
    out = _stacked(fields, y0, stacked_t, rows, solver)
    return [(out[r, :n] - y).pow(2).mean() for r, (n, y) in enumerate(zip(rows, ys, strict=True))]


def _field_tensors(field: VectorField) -> list[Tensor | None]:
    return [field.w0y, field.w0t, field.bias, *field.rest]


def _stacked(fields: Sequence[VectorField], y0: Tensor, t: Tensor, rows: Sequence[int],
             solver: SolverSpec, tensors: Sequence[Sequence[Tensor | None]] | None = None
             ) -> Tensor:
    """``[R, B, L, D]``: the fields (or their ``tensors``) integrated in one stacked pass."""
    per_field = tensors if tensors is not None else [_field_tensors(f) for f in fields]
    w0y, w0t, bias, *rest = (None if col[0] is None else torch.stack(col)
                             for col in zip(*per_field, strict=True))
    return rk4_mlp_stacked(y0, t, w0y, w0t, bias, rest, fields[0].spec.activation,
                           solver.substeps, rows=rows)


def _stacks_exactly(fields: Sequence[VectorField], y0: Tensor, t: Tensor, rows: Sequence[int],
                    ts: Sequence[Tensor], solver: SolverSpec) -> list[bool]:
    """Per run, whether the stacked pass gives it its own integration bit for bit: outputs
    and weight gradients of both on these inputs (with the fields' own tensor layouts)
    against a fixed output gradient."""
    leaves = [[None if w is None else w.detach().requires_grad_(True)
               for w in _field_tensors(f)] for f in fields]
    verdicts = []
    with torch.enable_grad():
        out = _stacked(fields, y0, t, rows, solver, leaves)
        probe = torch.randn(out.shape, generator=torch.Generator().manual_seed(0),
                            dtype=out.dtype)
        for r, n in enumerate(rows):
            probe[r, n:] = 0.0
        flat = [w for ws in leaves for w in ws if w is not None]
        together = iter(torch.autograd.grad((out * probe).sum(), flat))
        for r, (n, ws) in enumerate(zip(rows, leaves, strict=True)):
            w0y, w0t, bias, *rest = ws
            own = rk4_mlp(y0[r, :n], ts[r], w0y, w0t, bias, rest, fields[r].spec.activation,
                          solver.substeps)
            mine = [w for w in ws if w is not None]
            alone = torch.autograd.grad((own * probe[r, :n]).sum(), mine)
            same = [torch.equal(a, next(together)) for a in alone]
            verdicts.append(torch.equal(own, out[r, :n]) and all(same))
    return verdicts
