"""Task learners: NODE vector fields, ODE integration, hypernetworks, tangent-space maps.

* :mod:`~clfd_bench.learning.node` -- :class:`NodeSpec`, :class:`VectorField` (NODE^T/NODE^I).
* :mod:`~clfd_bench.learning.stable` -- :class:`StableSpec`, :class:`StableField` (sNODE).
* :mod:`~clfd_bench.learning.fields` -- the interface both kinds share (``FieldSpec``).
* :mod:`~clfd_bench.learning.odeint` -- :func:`integrate` (torchdiffeq adaptive or fixed RK4).
* :mod:`~clfd_bench.learning.objective` -- the training loss of a batch, batch and solver specs.
* :mod:`~clfd_bench.learning.rk4_fused` -- RK4 through an MLP with a hand-written backward.
* :mod:`~clfd_bench.learning.hypernet` -- :class:`HyperNetwork`, :class:`ChunkedHyperNetwork`.
* :mod:`~clfd_bench.learning.hnet_reg` -- the look-ahead step and the output regulariser.
* :mod:`~clfd_bench.learning.tangent` -- quaternion Log/Exp relative to a goal.
* :mod:`~clfd_bench.learning.normalize`, :mod:`~clfd_bench.learning.batches`.
"""

from clfd_bench.learning.batches import BatchSampler, BatchSpec
from clfd_bench.learning.hnet_reg import adam_lookahead, output_regularizer
from clfd_bench.learning.hypernet import ChunkedHyperNetwork, HyperNetwork
from clfd_bench.learning.node import NodeSpec, VectorField
from clfd_bench.learning.normalize import Normalizer
from clfd_bench.learning.objective import batch_spec, solver_spec, trajectory_loss
from clfd_bench.learning.odeint import SolverSpec, integrate
from clfd_bench.learning.stable import StableField, StableSpec
from clfd_bench.learning.tangent import quat_exp_relative, quat_log_relative

__all__ = [
    "BatchSampler",
    "BatchSpec",
    "ChunkedHyperNetwork",
    "HyperNetwork",
    "NodeSpec",
    "Normalizer",
    "SolverSpec",
    "StableField",
    "StableSpec",
    "VectorField",
    "adam_lookahead",
    "batch_spec",
    "integrate",
    "output_regularizer",
    "quat_exp_relative",
    "quat_log_relative",
    "solver_spec",
    "trajectory_loss",
]
