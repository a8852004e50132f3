"""Hyperparameters of one learned model (:class:`PartConfig`) and the error every config
check raises. Lives below the methods and the harness, which both read it."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, fields
from typing import Any

from clfd_bench.learning.batches import BATCH_KINDS
from clfd_bench.learning.hnet_reg import REG_MODES
from clfd_bench.learning.odeint import ADAPTIVE_SOLVERS, BACKENDS, FIXED_SOLVERS

__all__ = ["COMMON_KEYS", "ConfigError", "PART_FIELDS", "PartConfig"]


class ConfigError(ValueError):
    """A baselines file or an override is invalid; the message says what and how to fix it."""


@dataclass(frozen=True)
class PartConfig:
    """Hyperparameters of one learned model (the positions, or the orientations of RoboTasks).

    Training:
        iterations: optimiser steps per task. lr: Adam learning rate (all parameters).
        lr_schedule: ``constant`` or ``cosine`` (decays to ``lr * lr_min_factor``).
    Batches (:mod:`clfd_bench.learning.batches`):
        batch: ``windows`` (paper: ``tsub`` consecutive samples) or ``trajectories`` (whole
        trajectories subsampled to ``points``, horizon growing from ``horizon_start`` over the
        first ``horizon_ramp`` of the iterations; ``segments``: short horizons cover the whole
        trajectory as parallel segments).
    ODE solver (:mod:`clfd_bench.learning.odeint`): ``solver``, ``rtol``, ``atol``,
        ``substeps`` for training; ``eval_*`` for predictions (default: the training ones);
        ``solver_backend``: ``fused`` (hand-written reverse sweep, same values) or
        ``autograd`` (torchdiffeq / autograd, as the original code).
    NODE: ``node_hidden`` widths, ``activation``; ``task_emb_dim`` for task-conditioned
        NODEs and hypernetworks.
    Hypernetworks: ``hnet_hidden``, ``hnet_activation``, ``beta``; ``hnet_reg`` = ``all``
        (the paper's loop over past tasks), ``batched`` (same maths, one pass) or
        ``sampled`` (``hnet_reg_samples`` past tasks per step); CHN: ``chunk_emb_dim``,
        ``chunk_dim``.
    SI: ``si_c``, ``si_xi``. MAS: ``mas_lambda``; ``mas_points`` data points for the
        importance (0: all samples of the task).
    Data: ``normalize`` (per-task mean/std); ``tangent_goal`` (orientation: ``demo`` = Log
        relative to each demo's final quaternion as in the paper, ``task`` = the task goal).
    """

    iterations: int
    lr: float
    node_hidden: tuple[int, ...]
    lr_schedule: str = "constant"
    lr_min_factor: float = 0.0
    activation: str = "elu"
    task_emb_dim: int = 0
    hnet_hidden: tuple[int, ...] = ()
    hnet_activation: str = "relu"
    chunk_emb_dim: int = 0
    chunk_dim: int = 0
    beta: float = 0.0
    hnet_reg: str = "all"
    hnet_reg_samples: int = 1
    si_c: float = 0.0
    si_xi: float = 0.0
    mas_lambda: float = 0.0
    mas_points: int = 0
    batch: str = "windows"
    tsub: int = 20
    points: int = 50
    horizon_start: float = 1.0
    horizon_ramp: float = 0.0
    segments: bool = False
    solver: str = "dopri5"
    rtol: float = 1e-6
    atol: float = 1e-7
    substeps: int = 1
    solver_backend: str = "fused"
    eval_solver: str | None = None
    eval_rtol: float | None = None
    eval_atol: float | None = None
    eval_substeps: int | None = None
    normalize: bool = True
    tangent_goal: str = "demo"

    def __post_init__(self) -> None:
        checks = [
            (self.iterations >= 1, "iterations must be >= 1"),
            (self.lr > 0, "lr must be > 0"),
            (self.lr_schedule in ("constant", "cosine"), "lr_schedule must be constant|cosine"),
            (0.0 <= self.lr_min_factor <= 1.0, "lr_min_factor must be in [0, 1]"),
            (all(h >= 1 for h in self.node_hidden) and self.node_hidden, "node_hidden invalid"),
            (self.hnet_reg in REG_MODES, f"hnet_reg must be one of {', '.join(REG_MODES)}"),
            (self.hnet_reg_samples >= 1, "hnet_reg_samples must be >= 1"),
            (self.batch in BATCH_KINDS, f"batch must be one of {', '.join(BATCH_KINDS)}"),
            (self.tangent_goal in ("demo", "task"), "tangent_goal must be demo|task"),
            (self.solver_backend in BACKENDS, f"solver_backend must be one of {BACKENDS}"),
            (self.mas_points >= 0, "mas_points must be >= 0"),
        ]
        solvers = ADAPTIVE_SOLVERS + FIXED_SOLVERS
        for name in ("solver", "eval_solver"):
            value = getattr(self, name)
            checks.append((value is None or value in solvers,
                           f"{name} must be one of {', '.join(solvers)}"))
        for ok, msg in checks:
            if not ok:
                raise ConfigError(f"{msg} (got {self})")

    def resolved(self) -> PartConfig:
        """A copy with the ``eval_*`` settings filled in from the training ones."""
        return dataclasses.replace(
            self,
            eval_solver=self.eval_solver or self.solver,
            eval_rtol=self.eval_rtol if self.eval_rtol is not None else self.rtol,
            eval_atol=self.eval_atol if self.eval_atol is not None else self.atol,
            eval_substeps=self.eval_substeps if self.eval_substeps is not None else self.substeps,
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain data (lists for tuples) for JSON."""
        out = dataclasses.asdict(self)
        return {k: list(v) if isinstance(v, tuple) else v for k, v in out.items()}


PART_FIELDS: dict[str, dataclasses.Field] = {f.name: f for f in fields(PartConfig)}

COMMON_KEYS = frozenset(PART_FIELDS) - {
    "task_emb_dim", "hnet_hidden", "hnet_activation", "chunk_emb_dim", "chunk_dim", "beta",
    "hnet_reg", "hnet_reg_samples", "si_c", "si_xi", "mas_lambda", "mas_points",
}
"""Keys every method accepts; the rest are method-specific (see ``Method.hyperparameters``)."""
