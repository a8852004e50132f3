"""The two kinds of target network a CL method trains, behind one interface.

* :class:`~clfd_bench.learning.node.NodeSpec` / :class:`~clfd_bench.learning.node.VectorField`:
  the paper's NODE, an MLP ``f(y, t)`` (NODE^T) or ``f(y)`` (NODE^I).
* :class:`~clfd_bench.learning.stable.StableSpec` /
  :class:`~clfd_bench.learning.stable.StableField`: the stable NODE (sNODE) of the follow-up.

Both specs give ``param_shapes()``, ``init_weights(generator)``, ``field(weights, cond)``,
``dim``, ``cond_dim`` and ``time_input``; both fields are called as ``field(t, y)``. Methods
only use this interface, so every method trains either kind.
"""

from __future__ import annotations

from clfd_bench.learning.node import NodeSpec, VectorField
from clfd_bench.learning.stable import StableField, StableSpec

__all__ = ["Field", "FieldSpec"]

FieldSpec = NodeSpec | StableSpec
"""The architecture of a target network."""

Field = VectorField | StableField
"""A target network's vector field with its weights: ``field(t, y: [B, D]) -> [B, D]``."""
