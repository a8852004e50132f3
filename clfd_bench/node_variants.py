"""The ``--node`` values: which target network a run trains (no heavy imports, so the
command line can list them without loading torch)."""

from __future__ import annotations

__all__ = ["NODE_HELP", "NODE_VARIANTS", "node_label"]

NODE_VARIANTS: dict[str, str] = {
    "t": "NODE^T (time input)",
    "i": "NODE^I (no time input)",
    "s": "sNODE (stable at the goal by construction)",
}
"""Variant letter -> what it is (:mod:`clfd_bench.learning.fields` has the networks)."""

NODE_HELP = ", ".join(f"{k}: {v}" for k, v in NODE_VARIANTS.items()) + " (default t)"
"""The ``--node`` option's help text."""


def node_label(node: str) -> str:
    """How tables name a variant: ``NODE^T``, ``NODE^I``, ``sNODE``."""
    return "sNODE" if node == "s" else f"NODE^{node.upper()}"
