"""FT: one task-conditioned NODE fine-tuned on each new task (the paper's lower baseline)."""

from __future__ import annotations

from clfd_bench.methods.conditioned import ConditionedNodeMethod

__all__ = ["FineTuning"]


class FineTuning(ConditionedNodeMethod):
    """FT: nothing protects earlier tasks; only their embeddings are kept."""

    name = "ft"
